// The viewer's adaptive resolution controller, frame-rate readout and
// camera step clamp, fed simulated frame times and inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "app/view/adaptive_quality.h"
#include "app/view/camera_controller.h"
#include "app/view/frame_counter.h"

namespace tandem {
namespace {

// A frame's cost: a fixed part plus a part proportional to the pixels.
struct SimulatedRenderer {
  double overhead = 0.002;  // seconds per frame whatever the resolution
  double full_frame = 0.2;  // seconds per sample at full resolution
  double jitter = 0.0;      // +- fraction, deterministic pattern
  int n = 0;
  double seconds(const Quality& q) {
    const double noise = jitter * std::sin(double(n++) * 2.39996);  // never repeats exactly
    return (overhead + full_frame * double(q.scale) * double(q.scale) * q.samples_per_frame) *
           (1.0 + noise);
  }
};

TEST(ViewAdaptiveQuality, FallsOnSlowFramesThenRisesBackInSteps) {
  AdaptiveSettings s;
  s.target_fps = 30.0;
  AdaptiveQuality q(s);
  const double budget = 1.0 / 30.0;
  // A slow view: even the smallest scale is over budget for a while.
  SimulatedRenderer slow{0.002, 3.0};
  Quality cur = q.next(true, 0.0);
  for (int i = 0; i < 10; ++i)
    cur = q.next(true, slow.seconds(cur));
  EXPECT_FLOAT_EQ(cur.scale, s.min_scale);
  // The view becomes cheap: at the minimum scale a frame takes about 11 ms,
  // a third of the budget. The scale must climb back up, in several steps.
  SimulatedRenderer fast{0.002, 0.4};
  std::set<float> seen;
  float previous = cur.scale;
  for (int i = 0; i < 60; ++i) {
    cur = q.next(true, fast.seconds(cur));
    EXPECT_GE(cur.scale, previous) << "frame " << i << ": fell while frames were fast";
    previous = cur.scale;
    seen.insert(cur.scale);
  }
  EXPECT_GT(cur.scale, 1.5f * s.min_scale);
  EXPECT_GE(seen.size(), 3u) << "rose in one jump";
  const double settled = fast.seconds(cur);
  EXPECT_LT(settled, AdaptiveQuality::kSlowFraction * budget);
  EXPECT_GT(settled, 0.5 * budget) << "scale " << cur.scale << " leaves the budget unused";
}

TEST(ViewAdaptiveQuality, HoldsOneScaleUnderJitterWithoutOscillating) {
  for (double full_frame : {0.05, 0.2, 0.8, 2.5}) {
    AdaptiveSettings s;
    s.target_fps = 30.0;
    AdaptiveQuality q(s);
    SimulatedRenderer r{0.003, full_frame, 0.08};
    Quality cur = q.next(true, 0.0);
    for (int i = 0; i < 100; ++i)
      cur = q.next(true, r.seconds(cur));
    const float settled = cur.scale;
    int changes = 0;
    for (int i = 0; i < 300; ++i) {
      const Quality next = q.next(true, r.seconds(cur));
      changes += next.scale != cur.scale;
      cur = next;
    }
    EXPECT_EQ(changes, 0) << "full frame " << full_frame << " s: settled at " << settled;
  }
}

TEST(ViewAdaptiveQuality, MotionAfterStillStartsFromTheMeasuredCost) {
  AdaptiveSettings s;
  s.target_fps = 30.0;
  AdaptiveQuality q(s);
  SimulatedRenderer r{0.0, 0.3};
  Quality cur = q.next(false, 0.0);
  for (int i = 0; i < 5; ++i)
    cur = q.next(false, r.seconds(cur));
  EXPECT_EQ(cur.scale, 1.0f);
  // The first motion frame already fits: no full-resolution frame of 300 ms.
  cur = q.next(true, r.seconds(cur));
  EXPECT_LT(r.seconds(cur), 1.0 / 30.0);
  EXPECT_GT(cur.scale, s.min_scale);
}

TEST(ViewFrameCounter, FpsAndMsPerFrameComeFromTheSameClock) {
  FrameCounter c(1.0);
  c.presented(0.0, 0.02);
  EXPECT_EQ(c.fps(), 0.0) << "one frame says nothing about a rate";
  // 30 frames per second, each rendered in 20 ms.
  for (int i = 1; i <= 60; ++i)
    c.presented(i / 30.0, 0.02);
  EXPECT_NEAR(c.fps(), 30.0, 0.5);
  EXPECT_NEAR(c.ms_per_rendered_frame(), 20.0, 1e-6);
  // The rate drops to 4 frames per second of 250 ms each: the window forgets
  // the fast frames.
  double t = 2.0;
  for (int i = 0; i < 8; ++i)
    c.presented(t += 0.25, 0.25);
  EXPECT_NEAR(c.fps(), 4.0, 0.1);
  EXPECT_NEAR(c.ms_per_rendered_frame(), 250.0, 1e-6);
  // fps and ms per frame agree when every frame is rendered back to back.
  EXPECT_NEAR(1000.0 / c.fps(), c.ms_per_rendered_frame(), 1.0);
  // A converged image presented again costs no render time.
  for (int i = 0; i < 20; ++i)
    c.presented(t += 0.1, 0.0);
  EXPECT_NEAR(c.fps(), 10.0, 0.2);
  EXPECT_EQ(c.ms_per_rendered_frame(), 0.0);
}

TEST(ViewFlyCamera, ALongFrameDoesNotThrowTheCameraAway) {
  Camera cam;
  cam.position = glm::vec3(0.0f);
  FlyCamera fly(cam, 2.0f);
  CameraInput in;
  in.forward = true;
  in.dt = 5.0;  // the still frame before took five seconds
  ASSERT_TRUE(fly.update(in, cam));
  EXPECT_NEAR(glm::length(cam.position), 2.0f * float(kMaxFrameDeltaSeconds), 1e-5f);
  in.dt = 0.05;  // short frames move by speed * dt
  const glm::vec3 before = cam.position;
  fly.update(in, cam);
  EXPECT_NEAR(glm::length(cam.position - before), 0.1f, 1e-5f);
  EXPECT_EQ(clamp_frame_delta(-1.0), 0.0);
  EXPECT_EQ(clamp_frame_delta(0.02), 0.02);
}

}  // namespace
}  // namespace tandem
