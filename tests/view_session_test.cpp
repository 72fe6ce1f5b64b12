// The viewer session's frame loop, convergence and camera reset, and the
// SceneAnimator every scene's motion goes through.
#include <gtest/gtest.h>

#include <filesystem>

#include "app/view/view_session.h"
#include "scenes/arena_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_loader.h"
#include "scenes/scene_animator.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
const fs::path kGltf = fs::path(TANDEM_SHARED_DIR) / "scenes/gltf";

std::vector<glm::mat4> transforms(const Scene& s) {
  std::vector<glm::mat4> out;
  for (const Instance& i : s.instances())
    out.push_back(i.transform);
  return out;
}

ViewOptions small(const std::string& scene) {
  ViewOptions o;
  o.scene = scene;
  o.width = 32;
  o.height = 24;
  o.backend = BackendKind::kCpu;
  o.max_depth = 2;
  return o;
}

TEST(ViewSceneAnimator, StaticScenesDoNotMove) {
  Scene s = make_builtin_scene("cornell");
  auto a = make_scene_animator(s);
  ASSERT_NE(a, nullptr);
  EXPECT_FALSE(a->animated());
  EXPECT_EQ(a->duration(), 0.0);
  const auto before = transforms(s);
  s.clear_dirty();
  a->pose(2.0, s);
  EXPECT_EQ(transforms(s), before);
  EXPECT_FALSE(s.any_dirty());
}

TEST(ViewSceneAnimator, TheArenaIsFoundByItsBodiesNotItsName) {
  Scene s = make_arena_scene();
  s.source = "renamed";  // the factory must not look at the name
  auto a = make_scene_animator(s);
  EXPECT_TRUE(a->animated());
  EXPECT_EQ(a->duration(), 0.0) << "a simulation has no end";
  Scene ref = make_arena_scene();
  ArenaSimulation sim(ref);
  sim.advance_to(1.5, ref);
  a->pose(3.0, s);
  a->pose(1.5, s);  // pure function of t
  EXPECT_EQ(transforms(s), transforms(ref));
}

TEST(ViewSceneAnimator, GltfNodeAnimationsLoopOverTheirDuration) {
  GltfAnimations anims;
  GltfOptions o;
  o.animations = &anims;
  Scene s = load_gltf(kGltf / "BoxAnimated/glTF/BoxAnimated.gltf", o);
  const double duration = anims.duration();
  auto a = make_scene_animator(s, anims);
  EXPECT_TRUE(a->animated());
  EXPECT_DOUBLE_EQ(a->duration(), duration);
  a->pose(0.3 * duration, s);
  const auto at = transforms(s);
  a->pose(0.6 * duration, s);
  EXPECT_NE(transforms(s), at);
  a->pose(0.3 * duration, s);
  EXPECT_EQ(transforms(s), at);
}

TEST(ViewSession, ResetCameraGoesBackToTheSceneCamera) {
  ViewSession session(small("builtin:cornell"));
  const Camera initial = session.camera();
  Camera moved = initial;
  moved.position += glm::vec3(100.0f, 0.0f, 0.0f);
  session.set_camera(moved);
  EXPECT_NE(session.camera().position, initial.position);
  session.reset_camera();
  EXPECT_EQ(session.camera().position, initial.position);
  EXPECT_EQ(session.camera().forward, initial.forward);
  EXPECT_EQ(session.initial_camera().position, initial.position);
}

TEST(ViewSession, StillFramesConvergeExactlyAtTheTargetAndMotionRestarts) {
  ViewOptions o = small("builtin:cornell");
  o.target_spp = 20;
  o.max_spp_per_frame = 8;
  ViewSession session(o);
  session.render_frame(true, std::nullopt);
  EXPECT_FALSE(session.converged());
  for (int i = 0; i < 40 && !session.converged(); ++i)
    session.render_frame(false, std::nullopt);
  ASSERT_TRUE(session.converged());
  EXPECT_EQ(session.accumulated_spp(), 20u) << "overshot the target";
  // A setting that restarts accumulation un-converges it before the next frame.
  session.set_max_depth(3);
  EXPECT_FALSE(session.converged());
  session.render_frame(false, std::nullopt);
  EXPECT_LT(session.accumulated_spp(), 20u);
  // Motion: never converged.
  session.render_frame(true, std::nullopt);
  EXPECT_FALSE(session.converged());
  EXPECT_TRUE(session.last_frame_moving());
}

TEST(ViewSession, TheNextFrameIsPosedWhileThisOneRenders) {
  ViewSession session(small("builtin:arena"));
  ASSERT_TRUE(session.has_motion());
  session.advance_scene(0.0);
  const auto at0 = transforms(session.scene());
  const FrameMetrics& m0 = session.render_frame(false, 0.5);
  EXPECT_TRUE(m0.accumulation_reset);
  // After the frame the scene stands at the next frame's time ...
  EXPECT_EQ(session.scene_time(), 0.5);
  EXPECT_NE(transforms(session.scene()), at0);
  // ... and the next frame is a motion frame even without camera motion.
  const FrameMetrics& m1 = session.render_frame(false, std::nullopt);
  EXPECT_TRUE(m1.accumulation_reset);
  EXPECT_GT(m1.delta_bytes, 0u);
  EXPECT_TRUE(session.last_frame_moving());
  // Paused: nothing is posed, so the frame after that accumulates.
  session.paused = true;
  session.render_frame(false, 1.0);
  EXPECT_EQ(session.scene_time(), 0.5);
  EXPECT_FALSE(session.last_frame_moving());
}

}  // namespace
}  // namespace tandem
