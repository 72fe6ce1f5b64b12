// tandem-view's camera controllers and adaptive quality: pure logic, no window.
#include <gtest/gtest.h>

#include <cmath>

#include "app/view/adaptive_quality.h"
#include "app/view/camera_controller.h"
#include "app/view/scripted_path.h"

namespace tandem {
namespace {

Camera looking_down_minus_z() {
  Camera c;
  c.position = {0.0f, 1.0f, 5.0f};
  c.forward = {0.0f, 0.0f, -1.0f};
  c.up = {0.0f, 1.0f, 0.0f};
  c.focus_distance = 5.0f;
  return c;
}

TEST(ViewFlyCamera, NoInputDoesNotMove) {
  Camera c = looking_down_minus_z();
  FlyCamera fly(c, 2.0f);
  CameraInput in;
  in.dt = 0.1;
  EXPECT_FALSE(fly.update(in, c));
  EXPECT_NEAR(glm::length(c.position - glm::vec3(0, 1, 5)), 0.0f, 1e-6f);
}

TEST(ViewFlyCamera, WMovesForwardAtSpeedAndShiftIsFaster) {
  Camera c = looking_down_minus_z();
  FlyCamera fly(c, 2.0f);
  CameraInput in;
  in.dt = 0.05;
  in.forward = true;
  EXPECT_TRUE(fly.update(in, c));
  EXPECT_NEAR(c.position.z, 4.9f, 1e-5f);  // 2 units/s for 0.05 s along -z
  in.fast = true;
  fly.update(in, c);
  EXPECT_NEAR(c.position.z, 4.5f, 1e-5f);  // 4x faster
  in = CameraInput{};
  in.dt = 0.1;
  in.up = true;  // E rises along world +y whatever the view
  fly.update(in, c);
  EXPECT_NEAR(c.position.y, 1.2f, 1e-5f);
}

TEST(ViewFlyCamera, MouseLookTurnsAndKeepsAnOrthonormalBasis) {
  Camera c = looking_down_minus_z();
  FlyCamera fly(c, 1.0f);
  CameraInput in;
  in.look = {float(M_PI / 2.0 / FlyCamera::kRadiansPerPixel), 0.0f};  // quarter turn right
  EXPECT_TRUE(fly.update(in, c));
  EXPECT_NEAR(c.forward.x, 1.0f, 1e-4f);
  EXPECT_NEAR(c.forward.z, 0.0f, 1e-4f);
  in.look = {0.0f, -1e6f};  // pitch is clamped short of straight up
  fly.update(in, c);
  EXPECT_LT(c.forward.y, 1.0f);
  EXPECT_GT(c.forward.y, 0.99f);
  EXPECT_NEAR(glm::length(c.forward), 1.0f, 1e-5f);
  EXPECT_NEAR(glm::length(c.up), 1.0f, 1e-5f);
  EXPECT_NEAR(glm::dot(c.forward, c.up), 0.0f, 1e-5f);
}

TEST(ViewOrbitCamera, OrbitKeepsDistanceWheelZoomsPanMovesTarget) {
  Camera c = looking_down_minus_z();
  const glm::vec3 target(0.0f, 1.0f, 0.0f);
  OrbitCamera orbit(c, target);
  EXPECT_NEAR(orbit.distance(), 5.0f, 1e-5f);
  CameraInput in;
  in.orbit = {200.0f, 50.0f};
  EXPECT_TRUE(orbit.update(in, c));
  EXPECT_NEAR(glm::length(c.position - target), 5.0f, 1e-4f);
  EXPECT_GT(glm::dot(glm::normalize(target - c.position), c.forward), 0.9999f);  // looks at target
  in = CameraInput{};
  in.wheel = 2.0f;
  orbit.update(in, c);
  EXPECT_NEAR(orbit.distance(), 5.0f * OrbitCamera::kZoomPerNotch * OrbitCamera::kZoomPerNotch,
              1e-4f);
  in = CameraInput{};
  in.pan = {100.0f, 0.0f};
  orbit.update(in, c);
  EXPECT_GT(glm::length(orbit.target() - target), 1e-3f);
  EXPECT_NEAR(glm::length(c.position - orbit.target()), orbit.distance(), 1e-4f);
  EXPECT_FALSE(orbit.update(CameraInput{}, c));
}

TEST(ViewScriptedPath, StartsAtTheBaseCameraAndMoves) {
  const Camera base = looking_down_minus_z();
  const Camera c0 = scripted_camera(base, 0.0);
  EXPECT_NEAR(glm::length(c0.position - base.position), 0.0f, 1e-4f);
  const Camera c1 = scripted_camera(base, 2.0);
  EXPECT_GT(glm::length(c1.position - base.position), 0.5f);
  // Still aimed at the same point.
  const glm::vec3 target = camera_target(base);
  EXPECT_GT(glm::dot(glm::normalize(target - c1.position), c1.forward), 0.9999f);
}

TEST(ViewAdaptiveQuality, MotionDropsResolutionToHoldTheFrameRate) {
  AdaptiveSettings s;
  s.target_fps = 30.0;
  AdaptiveQuality q(s);
  Quality cur = q.next(true, 0.0);
  EXPECT_EQ(cur.scale, 1.0f);
  EXPECT_EQ(cur.samples_per_frame, 1u);
  // Simulated cost: 0.2 s per frame at full resolution, proportional to pixels.
  for (int i = 0; i < 30; ++i)
    cur = q.next(true, 0.2 * double(cur.scale * cur.scale) * cur.samples_per_frame);
  const double frame = 0.2 * double(cur.scale * cur.scale);
  EXPECT_LT(frame, 1.0 / 30.0 * 1.3) << "scale " << cur.scale;
  EXPECT_GT(frame, 1.0 / 30.0 * 0.5) << "scale " << cur.scale;
  EXPECT_GE(cur.scale, s.min_scale);
}

TEST(ViewAdaptiveQuality, StillRestoresFullResolutionAndRampsSamples) {
  AdaptiveSettings s;
  s.target_fps = 10.0;
  s.max_spp = 8;
  AdaptiveQuality q(s);
  Quality cur = q.next(true, 0.0);
  cur = q.next(true, 1.0);  // slow: scale drops
  EXPECT_LT(cur.scale, 1.0f);
  cur = q.next(false, 0.01);  // first still frame: full resolution, 1 spp
  EXPECT_EQ(cur.scale, 1.0f);
  EXPECT_EQ(cur.samples_per_frame, 1u);
  uint32_t prev = 1;
  for (int i = 0; i < 10; ++i) {
    cur = q.next(false, 0.01 * cur.samples_per_frame);  // 10 ms per sample
    EXPECT_GE(cur.samples_per_frame, prev);
    EXPECT_LE(cur.samples_per_frame, 2 * prev);  // ramps, never jumps
    prev = cur.samples_per_frame;
  }
  EXPECT_EQ(cur.samples_per_frame, 8u);  // 10 fits the 100 ms budget; capped at 8
  cur = q.next(true, 0.08);
  EXPECT_EQ(cur.samples_per_frame, 1u);  // motion: one sample again
}

TEST(ViewAdaptiveQuality, DisabledMeansFixedScaleOneSample) {
  AdaptiveSettings s;
  s.enabled = false;
  s.max_scale = 0.5f;
  AdaptiveQuality q(s);
  EXPECT_EQ(q.next(true, 10.0), (Quality{0.5f, 1}));
  EXPECT_EQ(q.next(false, 0.001), (Quality{0.5f, 1}));
}

}  // namespace
}  // namespace tandem
