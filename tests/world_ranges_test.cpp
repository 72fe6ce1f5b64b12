// What the tracers can take (core/world/scene_ranges.h): which instances are
// drawn, which cameras and scenes are refused and how the refusal reads.
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "core/util/errors.h"
#include "core/world/scene.h"
#include "core/world/scene_ranges.h"

namespace tandem {
namespace {

SceneBounds unit_box() {
  SceneBounds b;
  b.extend(glm::vec3(-1.0f));
  b.extend(glm::vec3(1.0f));
  return b;
}

glm::mat4 scaled(float s) {
  return glm::scale(glm::mat4(1.0f), glm::vec3(s));
}

TEST(SceneRanges, InstancesAreDrawnOnlyWhereTheTracersCanTakeThem) {
  const SceneBounds box = unit_box();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(classify_instance(glm::mat4(1.0f), box), InstanceState::kVisible);
  EXPECT_EQ(classify_instance(scaled(1e-6f), box), InstanceState::kVisible);
  EXPECT_EQ(classify_instance(scaled(1e8f), box), InstanceState::kVisible);
  // Scaled to 0, flattened, or so small that the inverse leaves 1e18.
  EXPECT_EQ(classify_instance(scaled(0.0f), box), InstanceState::kSingular);
  EXPECT_EQ(classify_instance(glm::scale(glm::mat4(1.0f), glm::vec3(1, 1, 0)), box),
            InstanceState::kSingular);
  EXPECT_EQ(classify_instance(scaled(1e-12f), box), InstanceState::kSingular);
  // A mesh of no triangles anywhere is drawn (as nothing) unless singular.
  EXPECT_EQ(classify_instance(glm::mat4(1.0f), SceneBounds{}), InstanceState::kVisible);
  EXPECT_EQ(classify_instance(scaled(0.0f), SceneBounds{}), InstanceState::kSingular);
  // Far away: the place or the scaled mesh beyond 1e9.
  EXPECT_EQ(classify_instance(glm::translate(glm::mat4(1.0f), glm::vec3(1e20f, 0, 0)), box),
            InstanceState::kOutOfRange);
  EXPECT_EQ(classify_instance(scaled(1e30f), box), InstanceState::kOutOfRange);
  // Far away and tiny: out of range, not singular (its place is checked first).
  EXPECT_EQ(classify_instance(glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, 1e35f)),
                                         glm::vec3(1e-30f)),
                              box),
            InstanceState::kOutOfRange);
  // Not finite: the transform or the mesh.
  glm::mat4 nan_transform(1.0f);
  nan_transform[1][2] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(classify_instance(nan_transform, box), InstanceState::kNonFinite);
  EXPECT_EQ(classify_instance(scaled(inf), box), InstanceState::kNonFinite);
  SceneBounds nan_box = box;
  nan_box.extend(glm::vec3(0, std::numeric_limits<float>::quiet_NaN(), 0));
  EXPECT_FALSE(nan_box.finite);
  EXPECT_EQ(classify_instance(glm::mat4(1.0f), nan_box), InstanceState::kNonFinite);
}

Camera good_camera() {
  Camera c;
  c.position = {0, 0, 5};
  c.forward = {0, 0, -1};
  c.up = {0, 1, 0};
  return c;
}

TEST(SceneRanges, CamerasOutsideTheRangeAreNamedProblems) {
  EXPECT_EQ(camera_problem(good_camera()), "");
  Camera c = good_camera();
  c.position.x = 5e18f;
  EXPECT_NE(camera_problem(c).find("lies beyond 1e+09"), std::string::npos);
  c = good_camera();
  c.position.y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(camera_problem(c), "its position is not finite");
  c = good_camera();
  c.forward = {0, 0, 0};
  EXPECT_EQ(camera_problem(c), "its orientation is not a finite frame");
  c = good_camera();
  c.type = CameraType::kOrthographic;
  c.ortho_half_height = std::numeric_limits<float>::infinity();
  EXPECT_NE(camera_problem(c).find("orthographic half height inf"), std::string::npos);
  c = good_camera();
  c.aperture_radius = 1e20f;
  EXPECT_NE(camera_problem(c).find("aperture radius"), std::string::npos);
}

// A scene with one unit-box mesh at `transform`, a camera and one light.
Scene one_box_scene(const glm::mat4& transform) {
  Scene s;
  s.add_material(Material{});
  Mesh m;
  m.name = "box";
  m.positions = {{-1, -1, -1}, {1, -1, -1}, {1, 1, 1}};
  m.triangles = {{0, 1, 2}};
  m.triangle_materials = {0};
  s.add_instance({"thing", s.add_mesh(std::move(m)), transform});
  s.set_camera(good_camera());
  Light l;
  l.name = "bulb";
  l.position = {0, 2, 0};
  s.add_light(l);
  return s;
}

std::string traceable_error(const Scene& s) {
  try {
    check_scene_traceable(s, "file.gltf");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneRanges, ScenesTheTracersCannotTakeAreRefusedNamingTheObject) {
  EXPECT_EQ(traceable_error(one_box_scene(glm::mat4(1.0f))), "");
  // Singular: not drawn, not an error.
  EXPECT_EQ(traceable_error(one_box_scene(scaled(0.0f))), "");
  EXPECT_EQ(traceable_error(one_box_scene(scaled(1e30f))),
            "file.gltf: node 0 ('thing') with mesh 0 ('box') lies beyond 1e+09 of the origin, "
            "the range Tandem can trace");
  Scene s = one_box_scene(glm::mat4(1.0f));
  s.edit_mesh_vertices(0).positions[1].x = std::numeric_limits<float>::infinity();
  EXPECT_NE(traceable_error(s).find("mesh 0 ('box') has positions that are not finite"),
            std::string::npos);
  s = one_box_scene(glm::mat4(1.0f));
  s.edit_camera().position.z = 1e19f;
  EXPECT_NE(traceable_error(s).find("file.gltf: the camera cannot be rendered: its position"),
            std::string::npos);
  s = one_box_scene(glm::mat4(1.0f));
  s.edit_light(0).intensity = std::numeric_limits<float>::infinity();
  EXPECT_NE(traceable_error(s).find("light 0 ('bulb') has an intensity of inf"), std::string::npos);
  s = one_box_scene(glm::mat4(1.0f));
  s.edit_light(0).color = glm::vec3(1e16f);
  s.edit_light(0).intensity = 1e16f;  // each finite, the product beyond 1e30
  EXPECT_NE(traceable_error(s).find("has an intensity of 1e+32"), std::string::npos);
  s = one_box_scene(glm::mat4(1.0f));
  s.edit_material(0).emissive = glm::vec3(1.0f);
  s.edit_material(0).emissive_strength = 1e31f;
  EXPECT_NE(traceable_error(s).find("material 0 emits 1e+31"), std::string::npos);
}

}  // namespace
}  // namespace tandem
