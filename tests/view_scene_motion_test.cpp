// builtin:arena's simulation and glTF node animations: determinism, motion,
// and that moving things dirties only instance transforms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "scenes/arena_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_animation.h"
#include "scenes/gltf_loader.h"
#include "scenes/procedural_rigs.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
const fs::path kGltf = fs::path(TANDEM_SHARED_DIR) / "scenes/gltf";

// Dirty vectors hold one bit mask per object: count the objects marked.
size_t marked(const std::vector<uint32_t>& masks) {
  return size_t(std::count_if(masks.begin(), masks.end(), [](uint32_t m) { return m != 0; }));
}

std::vector<glm::mat4> transforms(const Scene& s) {
  std::vector<glm::mat4> out;
  for (const Instance& i : s.instances())
    out.push_back(i.transform);
  return out;
}

TEST(ViewArena, IsABuiltinSceneWithLightsAndMovingBodies) {
  const auto names = builtin_scene_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "arena"), names.end());
  const Scene s = make_builtin_scene("arena");
  EXPECT_EQ(s.instances().size(), 1 + arena_bodies().size() + arena_walker_paths().size());
  EXPECT_TRUE(s.has_camera());
  bool emissive = false, glossy = false;
  for (const Material& m : s.materials()) {
    emissive |= m.emissive != glm::vec3(0.0f);
    glossy |= m.roughness < 0.2f;
  }
  EXPECT_TRUE(emissive);
  EXPECT_TRUE(glossy);
}

TEST(ViewArena, SameTimeSameTransformsWhateverTheStepPattern) {
  Scene a = make_arena_scene(), b = make_arena_scene();
  ArenaSimulation sa(a), sb(b);
  sa.advance_to(3.7, a);  // one jump
  for (int i = 1; i <= 111; ++i)
    sb.advance_to(i / 30.0, b);  // 30 fps frames ...
  sb.advance_to(3.7, b);         // ... then the same time
  EXPECT_EQ(transforms(a), transforms(b));
  // Going back replays from t = 0.
  sa.advance_to(1.25, a);
  Scene c = make_arena_scene();
  ArenaSimulation sc(c);
  sc.advance_to(1.25, c);
  EXPECT_EQ(transforms(a), transforms(c));
}

TEST(ViewArena, EveryBodyMovesAndOnlyInstanceTransformsAreDirty) {
  Scene s = make_arena_scene();
  ArenaSimulation sim(s);
  sim.advance_to(1.0, s);
  const auto before = transforms(s);
  s.clear_dirty();
  sim.advance_to(1.0 + 1.0 / 30.0, s);
  const auto after = transforms(s);
  EXPECT_EQ(before[0], after[0]) << "the courtyard is static";
  // The bodies follow the courtyard; the walkers after them keep the
  // identity (their skins move them, see scenes_skinning_test.cpp).
  const size_t bodies = arena_bodies().size();
  for (size_t i = 1; i <= bodies; ++i)
    EXPECT_NE(before[i], after[i]) << "body " << i - 1 << " did not move";
  EXPECT_EQ(marked(s.instance_dirty()), bodies);
  for (size_t i = 1; i <= bodies; ++i)
    EXPECT_EQ(s.instance_dirty()[i], uint32_t(kDirtyTransform));
  EXPECT_EQ(marked(s.material_dirty()), 0u);
  EXPECT_EQ(marked(s.mesh_dirty()), 0u);
  EXPECT_EQ(marked(s.light_dirty()), 0u);
  EXPECT_EQ(marked(s.texture_dirty()), 0u);
  EXPECT_FALSE(s.camera_dirty());
  EXPECT_FALSE(s.environment_dirty());
}

TEST(ViewArena, BouncingBallsStayInsideTheCourtyardForAMinute) {
  Scene s = make_arena_scene();
  ArenaSimulation sim(s);
  const auto& bodies = arena_bodies();
  for (int f = 0; f <= 60 * 30; f += 7) {
    sim.advance_to(f / 30.0, s);
    for (size_t i = 0; i < bodies.size(); ++i) {
      const glm::vec3 p(sim.body_transform(i)[3]);
      const float r = bodies[i].radius;
      ASSERT_GE(p.y, r * 0.99f) << "body " << i << " at t=" << f / 30.0;
      ASSERT_LE(std::abs(p.x), kArenaHalfSize - r + 1e-3f) << "body " << i;
      ASSERT_LE(std::abs(p.z), kArenaHalfSize - r + 1e-3f) << "body " << i;
      ASSERT_LT(p.y, 10.0f) << "body " << i << " gains energy";
    }
  }
}

TEST(ViewArena, NotAnArenaIsAnInputError) {
  const Scene s = make_builtin_scene("cornell");
  EXPECT_THROW(ArenaSimulation sim(s), std::runtime_error);
}

TEST(ViewGltfAnimation, AnimatedCubeRotatesThroughItsKeys) {
  GltfAnimations anims;
  GltfOptions o;
  o.animations = &anims;
  Scene s = load_gltf(kGltf / "AnimatedCube/glTF/AnimatedCube.gltf", o);
  ASSERT_EQ(anims.animations.size(), 1u);
  const GltfAnimation& a = anims.animations[0];
  ASSERT_EQ(a.channels.size(), 1u);
  const GltfAnimationChannel& ch = a.channels[0];
  EXPECT_EQ(ch.path, GltfAnimatedPath::kRotation);
  EXPECT_EQ(ch.interpolation, GltfInterpolation::kLinear);
  EXPECT_GT(a.duration, 0.0);
  // At every key time the sample is the (normalised) key value.
  for (size_t k = 0; k < ch.times.size(); ++k) {
    float v[4];
    sample_gltf_channel(ch, ch.times[k], v);
    const float* key = &ch.values[4 * k];
    const float len =
        std::sqrt(key[0] * key[0] + key[1] * key[1] + key[2] * key[2] + key[3] * key[3]);
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(v[c], key[c] / len, 1e-5f) << "key " << k;
  }
  apply_gltf_animations(anims, 0.0, s);
  const glm::mat4 m0 = s.instances()[0].transform;
  s.clear_dirty();
  EXPECT_EQ(apply_gltf_animations(anims, a.duration * 0.3, s), 1u);
  EXPECT_NE(s.instances()[0].transform, m0);
  EXPECT_EQ(marked(s.instance_dirty()), 1u);
  EXPECT_EQ(marked(s.material_dirty()), 0u);
  // Rotation only: the cube's centre stays put and the matrix stays rigid.
  const glm::mat4 m = s.instances()[0].transform;
  EXPECT_NEAR(glm::length(glm::vec3(m[3]) - glm::vec3(m0[3])), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(glm::vec3(m[0])), glm::length(glm::vec3(m0[0])), 1e-4f);
  // Looping: t and t + duration give the same pose.
  apply_gltf_animations(anims, a.duration * 1.3, s);
  EXPECT_LT(glm::length(glm::vec3(s.instances()[0].transform[0] - m[0])), 1e-4f);
}

TEST(ViewGltfAnimation, BoxAnimatedMovesTheAnimatedSubtreeOnly) {
  GltfAnimations anims;
  GltfOptions o;
  o.animations = &anims;
  Scene s = load_gltf(kGltf / "BoxAnimated/glTF/BoxAnimated.gltf", o);
  ASSERT_EQ(anims.animations.size(), 1u);
  EXPECT_EQ(anims.animations[0].channels.size(), 2u);  // translation + rotation
  ASSERT_EQ(s.instances().size(), 2u);
  // Node 2 (under animated nodes 0 and 1) and node 3 (static).
  size_t animated = 0, fixed = 0;
  for (const GltfInstanceBinding& b : anims.instances)
    (anims.nodes[b.node].animated ? animated : fixed)++;
  EXPECT_EQ(animated, 1u);
  EXPECT_EQ(fixed, 1u);
  const auto rest = transforms(s);
  s.clear_dirty();
  apply_gltf_animations(anims, anims.duration() * 0.4, s);
  EXPECT_EQ(marked(s.instance_dirty()), 1u);
  size_t changed = 0;
  for (size_t i = 0; i < rest.size(); ++i)
    changed += rest[i] != s.instances()[i].transform;
  EXPECT_EQ(changed, 1u);
}

TEST(ViewGltfAnimation, StepAndCubicSplineInterpolation) {
  GltfAnimationChannel ch;
  ch.path = GltfAnimatedPath::kTranslation;
  ch.times = {0.0f, 1.0f};
  ch.values = {0, 0, 0, 2, 4, 6};
  ch.interpolation = GltfInterpolation::kStep;
  float v[3];
  sample_gltf_channel(ch, 0.99, v);
  EXPECT_EQ(v[0], 0.0f);
  sample_gltf_channel(ch, 1.0, v);
  EXPECT_EQ(v[1], 4.0f);
  ch.interpolation = GltfInterpolation::kLinear;
  sample_gltf_channel(ch, 0.25, v);
  EXPECT_NEAR(v[2], 1.5f, 1e-6f);
  sample_gltf_channel(ch, -3.0, v);  // clamped before the first key
  EXPECT_EQ(v[0], 0.0f);
  // Cubic with tangents equal to the secant slope reproduces a straight line.
  ch.interpolation = GltfInterpolation::kCubicSpline;
  ch.values = {2, 4, 6, 0, 0, 0, 2, 4, 6,   // key 0: in-tangent, value, out-tangent
               2, 4, 6, 2, 4, 6, 2, 4, 6};  // key 1
  sample_gltf_channel(ch, 0.5, v);
  EXPECT_NEAR(v[0], 1.0f, 1e-5f);
  EXPECT_NEAR(v[2], 3.0f, 1e-5f);
  // Zero tangents: smoothstep.
  ch.values = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0};
  sample_gltf_channel(ch, 0.25, v);
  EXPECT_NEAR(v[0], 0.25f * 0.25f * (3.0f - 2.0f * 0.25f), 1e-5f);
}

TEST(ViewGltfAnimation, WithoutTheOptionNothingIsLoaded) {
  GltfSummary summary;
  const Scene s = load_gltf(kGltf / "BoxAnimated/glTF/BoxAnimated.gltf", {}, &summary);
  EXPECT_EQ(summary.animations, 1u);
  EXPECT_EQ(s.instances().size(), 2u);
}

}  // namespace
}  // namespace tandem
