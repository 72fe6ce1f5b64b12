#include "scenes/many_lights_scene.h"

#include <cmath>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "scenes/builtin_scenes.h"

namespace tandem {

namespace {

// A small linear congruential generator: the scene must be the same on
// every standard library (std:: distributions are not).
struct Lcg {
  uint64_t state;
  float next() {  // [0, 1)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return float(uint32_t(state >> 40)) * (1.0f / 16777216.0f);
  }
  float in(float lo, float hi) { return lo + (hi - lo) * next(); }
};

Material matte(const std::string& name, glm::vec3 albedo) {
  Material m;
  m.name = name;
  m.base_color = glm::vec4(albedo, 1.0f);
  m.metallic = 0.0f;
  m.roughness = 0.8f;
  return m;
}

Material emitter(const std::string& name, glm::vec3 colour, float strength) {
  Material m = matte(name, glm::vec3(0.1f));
  m.emissive = colour;
  m.emissive_strength = strength;
  return m;
}

// An axis-aligned box's faces, facing out (not the bottom: it stands on the floor).
void append_box(Mesh& mesh, glm::vec3 lo, glm::vec3 hi, uint32_t material) {
  auto p = [&](int x, int y, int z) {
    return glm::vec3(x ? hi.x : lo.x, y ? hi.y : lo.y, z ? hi.z : lo.z);
  };
  append_quad(mesh, p(0, 0, 0), p(1, 0, 0), p(1, 1, 0), p(0, 1, 0), material, {0, 0, -1});
  append_quad(mesh, p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1), material, {0, 0, 1});
  append_quad(mesh, p(0, 0, 0), p(0, 1, 0), p(0, 1, 1), p(0, 0, 1), material, {-1, 0, 0});
  append_quad(mesh, p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1), material, {1, 0, 0});
  append_quad(mesh, p(0, 1, 0), p(1, 1, 0), p(1, 1, 1), p(0, 1, 1), material, {0, 1, 0});
}

}  // namespace

Scene make_many_lights_scene(const ManyLightsCounts& counts) {
  Scene scene;
  scene.source = "builtin:many-lights";
  Lcg rng{12345};
  // The room: 20 m x 20 m, 5 m high, open nowhere; four pillars.
  const float half = 10.0f, height = 5.0f;
  const uint32_t walls = scene.add_material(matte("walls", glm::vec3(0.7f, 0.68f, 0.65f)));
  const uint32_t floor_mat = scene.add_material(matte("floor", glm::vec3(0.45f, 0.4f, 0.35f)));
  const uint32_t pillar_mat = scene.add_material(matte("pillars", glm::vec3(0.3f, 0.35f, 0.5f)));
  Mesh room;
  room.name = "room";
  const glm::vec3 a(-half, 0, -half), b(half, 0, -half), c(half, 0, half), d(-half, 0, half);
  const glm::vec3 up(0, height, 0);
  append_quad(room, a, b, c, d, floor_mat, {0, 1, 0});
  append_quad(room, a + up, b + up, c + up, d + up, walls, {0, -1, 0});
  append_quad(room, a, b, b + up, a + up, walls, {0, 0, 1});
  append_quad(room, d, c, c + up, d + up, walls, {0, 0, -1});
  append_quad(room, a, d, d + up, a + up, walls, {1, 0, 0});
  append_quad(room, b, c, c + up, b + up, walls, {-1, 0, 0});
  for (float x : {-4.0f, 4.0f}) {
    for (float z : {-4.0f, 4.0f})
      append_box(room, {x - 0.6f, 0.0f, z - 0.6f}, {x + 0.6f, height, z + 0.6f}, pillar_mat);
  }
  scene.add_instance({"room", scene.add_mesh(std::move(room)), glm::mat4(1.0f)});

  // Bulbs: one 10 cm quad emitting along -y of its own frame, instanced
  // on the ceiling (facing down), on the walls (facing the room, or the
  // wall: lit for nothing) and on the floor's edges (facing up), each
  // scaled 0.5-2x (a 16x range of power) and of one of four strengths.
  const uint32_t bulb_mats[4] = {
      scene.add_material(emitter("bulb warm", glm::vec3(1.0f, 0.8f, 0.6f), 4.0f)),
      scene.add_material(emitter("bulb cold", glm::vec3(0.6f, 0.8f, 1.0f), 8.0f)),
      scene.add_material(emitter("bulb dim", glm::vec3(1.0f), 1.0f)),
      scene.add_material(emitter("bulb bright", glm::vec3(1.0f, 0.95f, 0.9f), 40.0f))};
  uint32_t bulb_meshes[4];
  for (int k = 0; k < 4; ++k) {
    Mesh bulb;
    bulb.name = "bulb " + std::to_string(k);
    append_quad(bulb, {-0.05f, 0, -0.05f}, {0.05f, 0, -0.05f}, {0.05f, 0, 0.05f},
                {-0.05f, 0, 0.05f}, bulb_mats[k], {0, -1, 0});
    bulb_meshes[k] = scene.add_mesh(std::move(bulb));
  }
  for (uint32_t i = 0; i < counts.bulbs; ++i) {
    const float s = std::exp2(rng.in(-1.0f, 1.0f));
    const uint32_t where = i % 4;
    glm::mat4 t(1.0f);
    if (where <= 1) {  // ceiling, facing down
      // Each draw named, in a fixed order: the order of a call's arguments
      // is the compiler's choice (GCC's -O1 and -O2 built different rooms).
      const float z = rng.in(-9.5f, 9.5f), x = rng.in(-9.5f, 9.5f);
      t = glm::translate(t, glm::vec3(x, height - 0.01f, z));
    } else {  // a wall, facing into the room (or, one in four, the wall)
      const float angle = float(M_PI) * 0.5f * float(uint32_t(rng.next() * 4.0f));
      const bool backwards = rng.next() < 0.25f;
      t = glm::rotate(t, angle, glm::vec3(0, 1, 0));
      const float y = rng.in(0.5f, 4.5f), x = rng.in(-9.5f, 9.5f);
      t = glm::translate(t, glm::vec3(x, y, -half + 0.01f));
      // -y (the emitting side) towards +z (into the room), or -z (the wall).
      t = glm::rotate(t, backwards ? float(M_PI) * 0.5f : -float(M_PI) * 0.5f, glm::vec3(1, 0, 0));
    }
    t = glm::scale(t, glm::vec3(s, 1.0f, s));
    scene.add_instance({"bulb " + std::to_string(i), bulb_meshes[(i / 4) % 4], t});
  }

  // A panel of small cells along the +x wall: one mesh of many emissive
  // triangles in four strengths (the case of an emissive glTF mesh).
  Mesh panel;
  panel.name = "panel";
  const uint32_t cols = 64, rows = (counts.panel_cells + cols - 1) / cols;
  for (uint32_t cell = 0; cell < counts.panel_cells; ++cell) {
    const float z = -8.0f + 16.0f * (float(cell % cols) + 0.1f) / float(cols);
    const float y = 0.5f + 0.6f * (float(cell / cols) + 0.1f) / float(rows);
    const float w = 16.0f * 0.8f / float(cols), h = 0.6f * 0.8f / float(rows);
    const float x = half - 0.01f;
    append_quad(panel, {x, y, z}, {x, y, z + w}, {x, y + h, z + w}, {x, y + h, z},
                bulb_mats[cell % 4], {-1, 0, 0});
  }
  scene.add_instance({"panel", scene.add_mesh(std::move(panel)), glm::mat4(1.0f)});

  // A few punctual lights: points near the pillars, spots down the middle.
  for (uint32_t i = 0; i < counts.punctual; ++i) {
    Light l;
    l.name = "lamp " + std::to_string(i);
    l.type = i % 2 ? LightType::kSpot : LightType::kPoint;
    const float z = rng.in(-8.0f, 8.0f), y = rng.in(2.0f, 4.5f), x = rng.in(-8.0f, 8.0f);
    l.position = glm::vec3(x, y, z);
    const float dz = rng.in(-0.3f, 0.3f), dx = rng.in(-0.3f, 0.3f);
    l.direction = glm::normalize(glm::vec3(dx, -1.0f, dz));
    l.intensity = rng.in(2.0f, 20.0f);
    l.color = glm::vec3(1.0f, 0.9f, 0.8f);
    l.outer_cone_angle = 0.6f;
    l.inner_cone_angle = 0.4f;
    scene.add_light(l);
  }

  Camera cam;
  cam.position = {-8.5f, 1.7f, 8.5f};
  cam.forward = glm::normalize(glm::vec3(1.0f, -0.12f, -1.0f));
  const glm::vec3 right = glm::normalize(glm::cross(cam.forward, glm::vec3(0, 1, 0)));
  cam.up = glm::cross(right, cam.forward);
  cam.yfov = 1.0f;
  scene.set_camera(cam);
  return scene;
}

}  // namespace tandem
