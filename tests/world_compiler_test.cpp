// SceneCompiler's incremental updates: each kind of edit touches only the
// kernel arrays it has to (what the CUDA backend uploads every frame), and
// the light data stays consistent with the instances.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"

namespace tandem {
namespace {

struct TwoQuads {
  Scene scene;
  uint32_t floor_instance = 0, lamp_instance = 0, lamp_material = 0;
};

// A white floor and a small emissive quad above it, one instance each.
TwoQuads make_two_quads() {
  TwoQuads t;
  Material white;
  white.name = "white";
  white.base_color = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  const uint32_t floor_mat = t.scene.add_material(white);
  Material lamp = white;
  lamp.name = "lamp";
  lamp.emissive = glm::vec3(4.0f);
  t.lamp_material = t.scene.add_material(lamp);
  Mesh floor, quad;
  floor.name = "floor";
  quad.name = "lamp";
  append_quad(floor, {-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, floor_mat, {0, 1, 0});
  append_quad(quad, {-0.5f, 0, -0.5f}, {-0.5f, 0, 0.5f}, {0.5f, 0, 0.5f}, {0.5f, 0, -0.5f},
              t.lamp_material, {0, -1, 0});
  const uint32_t floor_mesh = t.scene.add_mesh(std::move(floor));
  const uint32_t lamp_mesh = t.scene.add_mesh(std::move(quad));
  t.floor_instance = t.scene.add_instance({"floor", floor_mesh, glm::mat4(1.0f)});
  t.lamp_instance = t.scene.add_instance(
      {"lamp", lamp_mesh, glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0))});
  Camera cam;
  cam.position = {0, 1, 6};
  cam.forward = {0, 0, -1};
  cam.up = {0, 1, 0};
  t.scene.set_camera(cam);
  return t;
}

struct Compiled {
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  SceneDelta compile(Scene& s) { return compiler.compile(s, settings, ks); }
};

TEST(SceneCompiler, FirstCompileIsFullAndAnUnchangedSceneGivesAnEmptyDelta) {
  TwoQuads t = make_two_quads();
  Compiled c;
  EXPECT_TRUE(c.compile(t.scene).full);
  const SceneDelta again = c.compile(t.scene);
  EXPECT_FALSE(again.any());
  EXPECT_EQ(again.bytes(c.ks), 0u);
}

TEST(SceneCompiler, MovingAnEmissiveInstanceRigidlyKeepsTheLightArrays) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  const float power_before = c.ks.constants.total_light_power;
  // Rotate and move the lamp: same areas, same powers.
  const glm::mat4 moved = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(1, 2.5f, -1)), 0.7f,
                                      glm::normalize(glm::vec3(1, 1, 0)));
  t.scene.set_instance_transform(t.lamp_instance, moved);
  const SceneDelta d = c.compile(t.scene);
  EXPECT_TRUE(d.instances_changed);
  EXPECT_EQ(d.instances.begin, t.lamp_instance);
  EXPECT_EQ(d.instances.end, t.lamp_instance + 1);
  EXPECT_FALSE(d.lights.any());
  EXPECT_FALSE(d.light_alias.any());
  EXPECT_FALSE(d.full);
  EXPECT_EQ(c.ks.constants.total_light_power, power_before);
  EXPECT_LT(d.bytes(c.ks), 1024u);
}

TEST(SceneCompiler, ScalingAnEmissiveInstanceRecomputesLightPower) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  const float power_before = c.ks.constants.total_light_power;
  t.scene.set_instance_transform(
      t.lamp_instance,
      glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0)), glm::vec3(2.0f)));
  const SceneDelta d = c.compile(t.scene);
  EXPECT_TRUE(d.lights.any() || d.light_alias.any());
  // Twice the size, four times the area and the emitted power.
  EXPECT_NEAR(c.ks.constants.total_light_power, 4.0f * power_before, 1e-3f * power_before);
}

TEST(SceneCompiler, MaterialEditTouchesOnlyThatMaterial) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  t.scene.edit_material(0).base_color = glm::vec4(0.2f, 0.3f, 0.4f, 1.0f);
  const SceneDelta d = c.compile(t.scene);
  EXPECT_EQ(d.materials.begin, 0u);
  EXPECT_EQ(d.materials.end, 1u);
  EXPECT_FALSE(d.instances_changed);
  EXPECT_FALSE(d.lights.any());
  EXPECT_NEAR(c.ks.materials[0].base_color.y, 0.3f, 1e-6f);
}

}  // namespace
}  // namespace tandem
