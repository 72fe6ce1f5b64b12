// Removing objects from a Scene: a hidden instance, a removed light and a
// removed mesh compile to exactly the kernel arrays of a scene built
// without them (so the image cannot tell), and each costs what it should:
// a TLAS update, the light list, a full compile.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

// What a scene with some objects left out is built from: which of the
// three meshes (floor, lamp, box), instances and lights go in.
struct Parts {
  bool floor = true, lamp = true, lamp_b = true, box = true;
  std::vector<int> lights = {0, 1, 2};
};

glm::mat4 at(float x, float y, float z) {
  return glm::translate(glm::mat4(1.0f), glm::vec3(x, y, z));
}

Light point_light(int which) {
  Light l;
  l.name = "light " + std::to_string(which);
  l.position = glm::vec3(float(which) - 1.0f, 3.0f, 0.5f * float(which));
  l.intensity = 5.0f + 10.0f * float(which);
  return l;
}

// Floor (one instance), emissive lamp (two), box (two) and three lights;
// `p` leaves some out, the rest in the same order.
Scene build(const Parts& p) {
  Scene s;
  Material white;
  white.base_color = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  const uint32_t mat = s.add_material(white);
  Material lamp = white;
  lamp.emissive = glm::vec3(4.0f);
  const uint32_t lamp_mat = s.add_material(lamp);
  Mesh floor, quad, box;
  append_quad(floor, {-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, mat, {0, 1, 0});
  append_quad(quad, {-0.5f, 0, -0.5f}, {-0.5f, 0, 0.5f}, {0.5f, 0, 0.5f}, {0.5f, 0, -0.5f},
              lamp_mat, {0, -1, 0});
  append_quad(box, {-0.2f, 0, 0}, {0.2f, 0, 0}, {0.2f, 0.4f, 0}, {-0.2f, 0.4f, 0}, mat, {0, 0, 1});
  if (p.floor) s.add_instance({"floor", s.add_mesh(floor), glm::mat4(1.0f)});
  if (p.lamp) {
    const uint32_t m = s.add_mesh(quad);
    s.add_instance({"lamp a", m, at(-1, 2, 0)});
    if (p.lamp_b) s.add_instance({"lamp b", m, at(1, 2, 0)});
  }
  if (p.box) {
    const uint32_t m = s.add_mesh(box);
    s.add_instance({"box a", m, at(0, 0, 1)});
    s.add_instance({"box b", m, at(1, 0, -1)});
  }
  for (int l : p.lights)
    s.add_light(point_light(l));
  Camera cam;
  cam.position = {0, 1, 6};
  s.set_camera(cam);
  return s;
}

// The arrays the lights and the image depend on, element by element.
void expect_same_lights(const KernelScene& a, const KernelScene& b) {
  EXPECT_EQ(a.lights.size(), b.lights.size());
  EXPECT_TRUE(same_bytes(a.light_alias, b.light_alias));
  EXPECT_EQ(a.constants.total_light_power, b.constants.total_light_power);
  for (size_t i = 0; i < a.lights.size() && i < b.lights.size(); ++i) {
    // Triangle lights name their instance, whose index may differ.
    KLight x = a.lights[i], y = b.lights[i];
    x.instance = y.instance = 0;
    EXPECT_EQ(std::memcmp(&x, &y, sizeof x), 0) << "light " << i;
  }
}

TEST(SceneRemoval, AHiddenInstanceIsNotDrawnLitOrFramedAndCostsATlasUpdate) {
  Scene s = build({});
  Compiled c;
  c.compile(s);
  const uint32_t lamp_b = 2;
  ASSERT_EQ(s.instances()[lamp_b].name, "lamp b");
  s.set_instance_hidden(lamp_b, true);
  const SceneDelta d = c.compile(s);
  EXPECT_FALSE(d.full);
  EXPECT_EQ(d.instances_moved, std::vector<uint32_t>{lamp_b});
  EXPECT_TRUE(c.ks.instances[lamp_b].flags & kInstanceHidden);

  // As if "lamp b" had never been there: the same lights (one lamp's two
  // triangles fewer), and the same bounds.
  Scene without = build({.lamp_b = false});
  Compiled fresh;
  fresh.compile(without);
  expect_same_lights(c.ks, fresh.ks);
  EXPECT_EQ(s.bounds().hi, without.bounds().hi);
  EXPECT_EQ(s.bounds().lo, without.bounds().lo);
  EXPECT_EQ(s.triangle_count_instanced(), without.triangle_count_instanced());

  // Shown again elsewhere (the slot reused for a new object of its mesh).
  s.set_instance_transform(lamp_b, at(2, 2, 1));
  s.set_instance_hidden(lamp_b, false);
  EXPECT_FALSE(c.compile(s).full);
  EXPECT_FALSE(c.ks.instances[lamp_b].flags & kInstanceHidden);
  EXPECT_EQ(s.bounds().hi.y, 2.0f);
}

TEST(SceneRemoval, ARemovedLightRebuildsTheLightListAsIfItNeverWas) {
  Scene s = build({});
  Compiled c;
  c.compile(s);
  s.remove_light(1);
  ASSERT_EQ(s.lights().size(), 2u);
  EXPECT_EQ(s.lights()[1].name, "light 2");
  const SceneDelta d = c.compile(s);
  EXPECT_FALSE(d.full);
  EXPECT_TRUE(d.lights.reallocated);
  Scene without = build({.lights = {0, 2}});
  Compiled fresh;
  fresh.compile(without);
  expect_same_lights(c.ks, fresh.ks);
  // An edit of the light that moved down reaches it under its new index.
  s.edit_light(1).intensity = 99.0f;
  c.compile(s);
  EXPECT_GT(c.ks.constants.total_light_power, fresh.ks.constants.total_light_power);
  // Added again: also the light list only.
  s.add_light(point_light(3));
  EXPECT_FALSE(c.compile(s).full);
  EXPECT_EQ(c.ks.lights.size(), fresh.ks.lights.size() + 1);
}

TEST(SceneRemoval, ARemovedMeshTakesItsInstancesAndTheRestMoveDown) {
  Scene s = build({});
  Compiled c;
  c.compile(s);
  s.edit_light(0).intensity = 7.0f;                      // pending edits elsewhere survive
  const std::vector<uint32_t> remap = s.remove_mesh(1);  // the lamp
  EXPECT_EQ(remap, (std::vector<uint32_t>{0, Scene::kRemovedIndex, Scene::kRemovedIndex, 1, 2}));
  ASSERT_EQ(s.mesh_count(), 2u);
  ASSERT_EQ(s.instances().size(), 3u);
  EXPECT_EQ(s.instances()[1].name, "box a");
  EXPECT_EQ(s.instances()[1].mesh, 1u);
  EXPECT_EQ(s.light_dirty()[0] & kDirtyParams, uint32_t(kDirtyParams));
  EXPECT_TRUE(c.compile(s).full);

  Scene without = build({.lamp = false});
  without.edit_light(0).intensity = 7.0f;
  Compiled fresh;
  fresh.compile(without);
  EXPECT_TRUE(same_bytes(c.ks.instances, fresh.ks.instances));
  EXPECT_TRUE(same_bytes(c.ks.meshes, fresh.ks.meshes));
  EXPECT_TRUE(same_bytes(c.ks.triangles, fresh.ks.triangles));
  expect_same_lights(c.ks, fresh.ks);
  EXPECT_EQ(s.bounds().hi, without.bounds().hi);
  EXPECT_EQ(std::memcmp(&c.ks.constants, &fresh.ks.constants, sizeof c.ks.constants), 0);

  // The last mesh too, then the first: an empty scene compiles.
  s.remove_mesh(1);
  s.remove_mesh(0);
  EXPECT_TRUE(s.instances().empty());
  EXPECT_TRUE(s.bounds().empty);
  c.compile(s);
  EXPECT_TRUE(c.ks.instances.empty());
  EXPECT_THROW(s.remove_mesh(0), std::out_of_range);
  EXPECT_THROW(s.remove_light(5), std::out_of_range);
}

// A game's churn at random: objects spawned (into a hidden slot of their
// mesh when there is one, as the API does), despawned, moved; lights added
// and removed; meshes added and removed. After each step the incremental
// compile gives exactly the arrays of a fresh compile of the same scene,
// and only mesh and new-slot changes cost a full one. (Emissive instances
// are hidden and shown, never moved: a rigid move keeps the light powers
// lazily, tested in world_compiler_test.)
TEST(SceneRemoval, ARandomChurnCompilesAsAFreshCompileOfTheSameScene) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> pos(-3.0f, 3.0f);
  Scene s = build({});
  Compiled c;
  c.compile(s);
  const Scene prototypes = build({});  // meshes to add again: floor, lamp, box
  auto emissive = [&](uint32_t mesh) {
    return s.materials()[s.mesh(mesh).triangle_materials[0]].emissive != glm::vec3(0.0f);
  };
  for (int step = 0; step < 120; ++step) {
    const uint32_t op = rng() % 7;
    bool may_be_full = false;
    std::vector<uint32_t> visible, hidden;
    for (uint32_t i = 0; i < s.instances().size(); ++i)
      (s.instances()[i].hidden ? hidden : visible).push_back(i);
    if (op == 0 && s.mesh_count() > 0) {  // spawn
      const uint32_t mesh = rng() % uint32_t(s.mesh_count());
      const glm::mat4 where = at(pos(rng), 0.5f * (pos(rng) + 3.0f), pos(rng));
      auto slot = std::find_if(hidden.begin(), hidden.end(),
                               [&](uint32_t i) { return s.instances()[i].mesh == mesh; });
      if (slot != hidden.end()) {
        s.set_instance_transform(*slot, where);
        s.set_instance_hidden(*slot, false);
      } else {
        s.add_instance({"spawned", mesh, where});
        may_be_full = true;
      }
    } else if (op == 1 && !visible.empty()) {  // despawn
      s.set_instance_hidden(visible[rng() % visible.size()], true);
    } else if (op == 2 && !visible.empty()) {  // move
      const uint32_t i = visible[rng() % visible.size()];
      if (!emissive(s.instances()[i].mesh))
        s.set_instance_transform(i, at(pos(rng), 0.25f, pos(rng)));
    } else if (op == 3) {
      s.add_light(point_light(int(rng() % 5)));
    } else if (op == 4 && !s.lights().empty()) {
      s.remove_light(uint32_t(rng() % s.lights().size()));
    } else if (op == 5) {
      s.add_mesh(prototypes.mesh(rng() % 3));
      may_be_full = true;
    } else if (op == 6 && s.mesh_count() > 1) {
      s.remove_mesh(uint32_t(rng() % s.mesh_count()));
      may_be_full = true;
    }
    const SceneDelta d = c.compile(s);
    if (!may_be_full) EXPECT_FALSE(d.full) << "step " << step << ", op " << op;
    Scene copy = s;
    Compiled fresh;
    fresh.compile(copy);
    expect_same_scene_arrays(c.ks, fresh.ks, step);
    if (::testing::Test::HasFailure()) return;
  }
}

}  // namespace
}  // namespace tandem
