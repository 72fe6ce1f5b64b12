#include "scenes/builtin_scenes.h"

#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "core/util/errors.h"
#include "scenes/arena_scene.h"
#include "scenes/many_lights_scene.h"
#include "scenes/procedural_rigs.h"
#include "scenes/procedural_scenes.h"

namespace tandem {

void append_quad(Mesh& mesh, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                 const glm::vec3& d, uint32_t material, const glm::vec3& facing) {
  const uint32_t base = uint32_t(mesh.positions.size());
  mesh.positions.insert(mesh.positions.end(), {a, b, c, d});
  // Orient the winding (and so the front face) towards `facing`.
  const glm::vec3 n = glm::cross(b - a, c - a);
  const bool flip = glm::dot(n, facing) < 0.0f;
  if (!flip) {
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
  } else {
    mesh.triangles.push_back({base, base + 2, base + 1});
    mesh.triangles.push_back({base, base + 3, base + 2});
  }
  mesh.triangle_materials.push_back(material);
  mesh.triangle_materials.push_back(material);
}

Mesh make_uv_sphere(float radius, uint32_t rings, uint32_t segments, uint32_t material,
                    bool inward) {
  Mesh m;
  m.name = "sphere";
  for (uint32_t r = 0; r <= rings; ++r) {
    const float theta = float(M_PI) * float(r) / float(rings);
    for (uint32_t s = 0; s <= segments; ++s) {
      const float phi = 2.0f * float(M_PI) * float(s) / float(segments);
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta),
                        std::sin(theta) * std::sin(phi));
      m.positions.push_back(n * radius);
      m.normals.push_back(inward ? -n : n);
      m.uv0.push_back({float(s) / float(segments), float(r) / float(rings)});
    }
  }
  const uint32_t stride = segments + 1;
  for (uint32_t r = 0; r < rings; ++r) {
    for (uint32_t s = 0; s < segments; ++s) {
      const uint32_t i0 = r * stride + s, i1 = i0 + 1, i2 = i0 + stride, i3 = i2 + 1;
      // Outward-facing counter-clockwise winding; reversed for inward spheres.
      glm::uvec3 t1(i0, i1, i2), t2(i1, i3, i2);
      if (inward) std::swap(t1.y, t1.z), std::swap(t2.y, t2.z);
      if (r != 0) {
        m.triangles.push_back(t1);
        m.triangle_materials.push_back(material);
      }
      if (r != rings - 1) {
        m.triangles.push_back(t2);
        m.triangle_materials.push_back(material);
      }
    }
  }
  return m;
}

namespace {

Material lambert(const std::string& name, glm::vec3 albedo) {
  Material m;
  m.name = name;
  m.base_color = glm::vec4(albedo, 1.0f);
  m.metallic = 0.0f;
  m.roughness = 1.0f;
  m.specular = 0.0f;  // no specular layer: exactly Lambertian
  return m;
}

}  // namespace

namespace {

// The box itself, with or without its two blocks.
Scene cornell_box(bool blocks) {
  Scene scene;
  scene.source = "builtin:cornell";
  // RGB reflectances commonly derived from the box's measured spectra.
  const uint32_t white = scene.add_material(lambert("white", {0.725f, 0.71f, 0.68f}));
  const uint32_t red = scene.add_material(lambert("red", {0.63f, 0.065f, 0.05f}));
  const uint32_t green = scene.add_material(lambert("green", {0.14f, 0.45f, 0.091f}));
  Material light_mat = lambert("light", {0.0f, 0.0f, 0.0f});
  light_mat.emissive = {17.0f, 12.0f, 4.0f};
  const uint32_t light = scene.add_material(light_mat);

  const float s = 0.001f;  // the published data is in millimetres
  auto P = [s](float x, float y, float z) { return glm::vec3(x, y, z) * s; };
  const glm::vec3 up(0, 1, 0), down(0, -1, 0), toward_camera(0, 0, -1);
  Mesh box;
  box.name = "cornell_box";
  // Floor, back wall, red (left, +x) and green (right, x = 0) walls.
  append_quad(box, P(552.8f, 0, 0), P(0, 0, 0), P(0, 0, 559.2f), P(549.6f, 0, 559.2f), white, up);
  append_quad(box, P(549.6f, 0, 559.2f), P(0, 0, 559.2f), P(0, 548.8f, 559.2f),
              P(556.0f, 548.8f, 559.2f), white, toward_camera);
  append_quad(box, P(552.8f, 0, 0), P(549.6f, 0, 559.2f), P(556.0f, 548.8f, 559.2f),
              P(556.0f, 548.8f, 0), red, glm::vec3(-1, 0, 0));
  append_quad(box, P(0, 0, 559.2f), P(0, 0, 0), P(0, 548.8f, 0), P(0, 548.8f, 559.2f), green,
              glm::vec3(1, 0, 0));
  // Ceiling with a hole where the light sits, so the two never overlap.
  const float cy = 548.8f;
  append_quad(box, P(556, cy, 0), P(556, cy, 227), P(0, cy, 227), P(0, cy, 0), white, down);
  append_quad(box, P(556, cy, 332), P(556, cy, 559.2f), P(0, cy, 559.2f), P(0, cy, 332), white,
              down);
  append_quad(box, P(556, cy, 227), P(556, cy, 332), P(343, cy, 332), P(343, cy, 227), white, down);
  append_quad(box, P(213, cy, 227), P(213, cy, 332), P(0, cy, 332), P(0, cy, 227), white, down);
  // The light: 130 x 105 mm, emitting downwards only.
  append_quad(box, P(343, cy, 227), P(343, cy, 332), P(213, cy, 332), P(213, cy, 227), light, down);

  // Short block.
  const glm::vec3 sb[4] = {P(130, 0, 65), P(82, 0, 225), P(240, 0, 272), P(290, 0, 114)};
  const glm::vec3 tb[4] = {P(423, 0, 247), P(265, 0, 296), P(314, 0, 456), P(472, 0, 406)};
  auto add_block = [&](const glm::vec3(&base)[4], float height) {
    const glm::vec3 h = P(0, height, 0);
    glm::vec3 center(0.0f);
    for (const glm::vec3& p : base)
      center += p * 0.25f;
    append_quad(box, base[0] + h, base[1] + h, base[2] + h, base[3] + h, white, up);
    for (int i = 0; i < 4; ++i) {
      const glm::vec3 a = base[i], b = base[(i + 1) % 4];
      const glm::vec3 mid = (a + b) * 0.5f;
      append_quad(box, a, b, b + h, a + h, white, mid - center);
    }
  };
  if (blocks) {
    add_block(sb, 165.0f);
    add_block(tb, 330.0f);
  }

  const uint32_t mesh = scene.add_mesh(std::move(box));
  scene.add_instance({"cornell_box", mesh, glm::mat4(1.0f)});

  Camera cam;
  cam.position = P(278, 273, -800);
  cam.forward = {0, 0, 1};
  cam.up = {0, 1, 0};
  cam.yfov = 2.0f * std::atan(12.5f / 35.0f);
  cam.focus_distance = 0.8f + 0.2796f;
  cam.aspect_ratio = 1.0f;
  scene.set_camera(cam);
  return scene;
}

}  // namespace

Scene make_cornell_box() {
  return cornell_box(true);
}

Scene make_cornell_spheres() {
  Scene scene = cornell_box(false);
  scene.source = "builtin:cornell-spheres";
  Material mirror;
  mirror.name = "mirror";
  mirror.metallic = 1.0f;
  mirror.roughness = 0.0f;
  Material glass;
  glass.name = "glass";
  glass.metallic = 0.0f;
  glass.roughness = 0.0f;
  glass.transmission = 1.0f;
  glass.ior = 1.5f;
  const uint32_t mirror_mat = scene.add_material(mirror);
  const uint32_t glass_mat = scene.add_material(glass);
  // Flat-shaded UV spheres (radius 100 mm): tools/compare/cycles_cornell.py
  // builds the very same triangles, so both renderers see one geometry.
  auto add_sphere = [&](const char* name, uint32_t material, glm::vec3 center_mm) {
    Mesh sphere =
        make_uv_sphere(0.1f, kCornellSphereRings, 2 * kCornellSphereRings, material, false);
    sphere.name = name;
    sphere.normals.clear();
    const uint32_t mesh = scene.add_mesh(std::move(sphere));
    scene.add_instance({name, mesh, glm::translate(glm::mat4(1.0f), center_mm * 0.001f)});
  };
  add_sphere("mirror_sphere", mirror_mat, {185.0f, 100.0f, 351.0f});
  add_sphere("glass_sphere", glass_mat, {370.0f, 100.0f, 169.0f});
  scene.source = "builtin:cornell-spheres";
  return scene;
}

Scene make_furnace_scene(float albedo, float emission) {
  Scene scene;
  scene.source = "builtin:furnace";
  Material m = lambert("furnace", glm::vec3(albedo));
  m.emissive = glm::vec3(emission);
  m.double_sided = true;
  const uint32_t mat = scene.add_material(m);
  // Flat shading: smooth normals on a tessellated sphere make the Lambertian
  // BSDF lose the samples that leave below the true surface (about 0.03% per
  // bounce), which would bias the analytic answer e / (1 - a).
  Mesh sphere = make_uv_sphere(1.0f, 24, 48, mat, true);
  sphere.normals.clear();
  const uint32_t mesh = scene.add_mesh(std::move(sphere));
  scene.add_instance({"sphere", mesh, glm::mat4(1.0f)});
  Camera cam;
  cam.position = {0.0f, 0.0f, 0.0f};
  cam.forward = {0.0f, 0.0f, -1.0f};
  cam.up = {0.0f, 1.0f, 0.0f};
  cam.yfov = 1.2f;
  scene.set_camera(cam);
  return scene;
}

Scene make_sky_plane_scene(float albedo, float sky) {
  Scene scene;
  scene.source = "builtin:sky-plane";
  const uint32_t mat = scene.add_material(lambert("plane", glm::vec3(albedo)));
  Mesh plane;
  plane.name = "plane";
  const float r = 1000.0f;
  append_quad(plane, {-r, 0, -r}, {r, 0, -r}, {r, 0, r}, {-r, 0, r}, mat, {0, 1, 0});
  const uint32_t mesh = scene.add_mesh(std::move(plane));
  scene.add_instance({"plane", mesh, glm::mat4(1.0f)});
  Environment env;
  env.color = glm::vec3(sky);
  scene.set_environment(env);
  Camera cam;
  // Pitched down ~17 degrees: the top fifth of the image sees the sky.
  cam.position = {0.0f, 1.0f, 0.0f};
  cam.forward = glm::normalize(glm::vec3(0.0f, -0.3f, -1.0f));
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  cam.yfov = 1.0f;
  scene.set_camera(cam);
  return scene;
}

std::vector<std::string> builtin_scene_names() {
  return {"cornell",    "cornell-spheres", "furnace",      "sky-plane",
          "procedural", "arena",           "skinned-grid", "many-lights"};
}

Scene make_builtin_scene(const std::string& name) {
  if (name == "cornell") return make_cornell_box();
  if (name == "cornell-spheres") return make_cornell_spheres();
  if (name == "furnace") return make_furnace_scene(0.8f, 0.5f);
  if (name == "sky-plane") return make_sky_plane_scene(0.5f, 1.0f);
  if (name == "procedural") return make_procedural_scene(1000000, 1);
  if (name == "arena") return make_arena_scene();
  if (name == "skinned-grid") return make_skinned_grid_scene();
  if (name == "many-lights") return make_many_lights_scene();
  std::string known;
  for (const std::string& n : builtin_scene_names())
    known += (known.empty() ? "" : ", ") + n;
  throw InputError("builtin:" + name + ": no such built-in scene (known: " + known + ")");
}

}  // namespace tandem
