#include "scenes/procedural_scenes.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "scenes/builtin_scenes.h"

namespace tandem {

namespace {

// splitmix64: fully specified, unlike the <random> distributions, so a seed
// means the same scene everywhere.
class SceneRng {
 public:
  explicit SceneRng(uint64_t seed) : state_(seed * 0x9e3779b97f4a7c15ull + 0x632be59bd9b4e019ull) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  float uniform() { return float(next() >> 40) * (1.0f / 16777216.0f); }
  float range(float a, float b) { return a + (b - a) * uniform(); }
  float log_range(float a, float b) { return std::exp(range(std::log(a), std::log(b))); }
  glm::vec3 unit_vector() {
    const float z = range(-1.0f, 1.0f), phi = range(0.0f, 6.2831853f);
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    return {r * std::cos(phi), r * std::sin(phi), z};
  }
  uint32_t below(uint32_t n) { return uint32_t(next() % n); }

 private:
  uint64_t state_;
};

constexpr float kTerrainHalfSize = 100.0f;

float terrain_height(float x, float z) {
  return 4.0f * std::sin(0.05f * x) * std::cos(0.04f * z) + 1.5f * std::sin(0.21f * x + 0.13f * z) +
         0.4f * std::sin(0.9f * x) * std::sin(0.7f * z);
}

Material lambert_material(const std::string& name, glm::vec3 albedo) {
  Material m;
  m.name = name;
  m.base_color = glm::vec4(albedo, 1.0f);
  m.metallic = 0.0f;
  m.roughness = 0.8f;
  m.specular = 0.5f;
  return m;
}

void add_triangle(Mesh& m, glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material) {
  const uint32_t base = uint32_t(m.positions.size());
  m.positions.insert(m.positions.end(), {a, b, c});
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangle_materials.push_back(material);
}

Mesh make_terrain(uint32_t target, uint32_t material) {
  const uint32_t n = std::max<uint32_t>(2, uint32_t(std::sqrt(double(target) / 2.0)));
  Mesh m;
  m.name = "terrain";
  for (uint32_t j = 0; j <= n; ++j) {
    for (uint32_t i = 0; i <= n; ++i) {
      const float x = -kTerrainHalfSize + 2.0f * kTerrainHalfSize * float(i) / float(n);
      const float z = -kTerrainHalfSize + 2.0f * kTerrainHalfSize * float(j) / float(n);
      m.positions.push_back({x, terrain_height(x, z), z});
    }
  }
  for (uint32_t j = 0; j < n; ++j) {
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.push_back({a, c, b});
      m.triangles.push_back({b, c, d});
      m.triangle_materials.insert(m.triangle_materials.end(), {material, material});
    }
  }
  return m;
}

// A sphere with a lumpy radius; radius depends on position only, so the
// duplicated seam vertices stay together and the mesh stays closed.
Mesh make_rock(uint32_t target, uint32_t material, SceneRng& rng) {
  const uint32_t rings = std::max<uint32_t>(3, uint32_t(std::sqrt(double(target) / 4.0)));
  Mesh m = make_uv_sphere(1.0f, rings, 2 * rings, material, false);
  m.name = "rock";
  m.normals.clear();
  const glm::vec3 f = {rng.range(1.0f, 4.0f), rng.range(1.0f, 4.0f), rng.range(1.0f, 4.0f)};
  for (glm::vec3& p : m.positions) {
    const float r = 1.0f + 0.25f * std::sin(f.x * p.x + 1.3f) * std::sin(f.y * p.y + 0.7f) +
                    0.1f * std::sin(f.z * 5.0f * p.z);
    p *= r;
  }
  return m;
}

Mesh make_torus(uint32_t target, uint32_t material, glm::vec3 center) {
  const uint32_t v = std::max<uint32_t>(3, uint32_t(std::sqrt(double(target) / 8.0)));
  const uint32_t u = 4 * v;
  const float big = 6.0f, small = 1.5f;
  Mesh m;
  m.name = "torus";
  for (uint32_t i = 0; i < u; ++i) {
    const float a = 6.2831853f * float(i) / float(u);
    for (uint32_t j = 0; j < v; ++j) {
      const float b = 6.2831853f * float(j) / float(v);
      const float r = big + small * std::cos(b);
      m.positions.push_back(center +
                            glm::vec3(r * std::cos(a), small * std::sin(b), r * std::sin(a)));
    }
  }
  for (uint32_t i = 0; i < u; ++i) {
    for (uint32_t j = 0; j < v; ++j) {
      const uint32_t a = i * v + j, b = ((i + 1) % u) * v + j;
      const uint32_t c = i * v + (j + 1) % v, d = ((i + 1) % u) * v + (j + 1) % v;
      m.triangles.push_back({a, c, b});
      m.triangles.push_back({b, c, d});
      m.triangle_materials.insert(m.triangle_materials.end(), {material, material});
    }
  }
  return m;
}

// Random triangles from 1 cm slivers to 10 m sheets, about 2% degenerate
// (collinear or repeated vertices), crowded into a box above the terrain.
Mesh make_soup(uint32_t target, uint32_t material, SceneRng& rng) {
  Mesh m;
  m.name = "soup";
  for (uint32_t t = 0; t < target; ++t) {
    const glm::vec3 c = {rng.range(-40.0f, 40.0f), rng.range(8.0f, 40.0f),
                         rng.range(-40.0f, 40.0f)};
    const float s = rng.log_range(0.01f, 8.0f);
    glm::vec3 a = c + s * rng.unit_vector(), b = c + s * rng.unit_vector(),
              d = c + s * rng.unit_vector();
    if (rng.uniform() < 0.2f) {
      const glm::vec3 jitter = rng.unit_vector();
      const float along = rng.range(0.0f, 1.0f);
      d = a + (b - a) * along + 0.002f * s * jitter;
    }
    const float kind = rng.uniform();
    if (kind < 0.01f)
      d = a + (b - a) * 0.5f;  // collinear: zero area
    else if (kind < 0.02f)
      b = a;  // repeated vertex
    add_triangle(m, a, b, d, material);
  }
  return m;
}

// Long thin blades rising from a unit disk.
Mesh make_grass_tuft(uint32_t target, uint32_t material, SceneRng& rng) {
  Mesh m;
  m.name = "grass";
  for (uint32_t t = 0; t < target; ++t) {
    const float r = std::sqrt(rng.uniform()), phi = rng.range(0.0f, 6.2831853f);
    const glm::vec3 p = {r * std::cos(phi), 0.0f, r * std::sin(phi)};
    glm::vec3 dir = glm::normalize(glm::vec3(0, 1, 0) + 0.6f * rng.unit_vector());
    if (dir.y < 0.1f) dir = glm::normalize(dir + glm::vec3(0, 1, 0));
    const float len = rng.range(0.5f, 3.0f), width = rng.log_range(0.002f, 0.03f);
    const glm::vec3 side = glm::normalize(glm::cross(dir, rng.unit_vector())) * (0.5f * width);
    add_triangle(m, p - side, p + side, p + dir * len, material);
  }
  return m;
}

// Square cards on a sphere shell, for stochastic alpha.
Mesh make_foliage(uint32_t target, uint32_t material, SceneRng& rng) {
  Mesh m;
  m.name = "foliage";
  for (uint32_t t = 0; t + 1 < target; t += 2) {
    const float radius = rng.range(1.0f, 2.0f);
    const glm::vec3 c = rng.unit_vector() * radius;
    const glm::vec3 n = rng.unit_vector();
    const glm::vec3 u = glm::normalize(glm::cross(n, rng.unit_vector())) * 0.25f;
    const glm::vec3 v = glm::cross(n, u);
    append_quad(m, c - u - v, c + u - v, c + u + v, c - u + v, material, n);
  }
  return m;
}

Mesh make_unit_box(uint32_t material) {
  Mesh m;
  m.name = "box";
  const glm::vec3 p[8] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                          {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  m.positions.assign(p, p + 8);
  const uint32_t f[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                            {3, 7, 6, 2}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  for (const auto& q : f) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
    m.triangle_materials.insert(m.triangle_materials.end(), {material, material});
  }
  return m;
}

// Random placement on the terrain with a random rotation and a
// non-uniform scale, mirrored one time in ten.
glm::mat4 random_placement(SceneRng& rng, float scale_lo, float scale_hi, float stretch,
                           float lift) {
  const float x = rng.range(-0.9f, 0.9f) * kTerrainHalfSize,
              z = rng.range(-0.9f, 0.9f) * kTerrainHalfSize;
  const float s = rng.log_range(scale_lo, scale_hi);
  const float sz = rng.range(1.0f, stretch), sy = rng.range(1.0f, stretch),
              sx = rng.range(1.0f, stretch);
  glm::vec3 scale = glm::vec3(s) * glm::vec3(sx, sy, sz);
  if (rng.uniform() < 0.1f) scale.x = -scale.x;
  glm::mat4 t = glm::translate(glm::mat4(1.0f), {x, terrain_height(x, z) + lift * s, z});
  const glm::vec3 axis = glm::normalize(rng.unit_vector() + glm::vec3(0, 2, 0));
  const float angle = rng.range(0.0f, 6.2831853f);
  t = glm::rotate(t, angle, axis);
  return glm::scale(t, scale);
}

}  // namespace

Scene make_procedural_scene(uint32_t approx_triangles, uint32_t seed) {
  SceneRng rng(seed);
  Scene scene;
  scene.source = "builtin:procedural";
  const uint32_t ground = scene.add_material(lambert_material("ground", {0.35f, 0.3f, 0.22f}));
  const uint32_t stone = scene.add_material(lambert_material("stone", {0.5f, 0.5f, 0.48f}));
  const uint32_t grass = scene.add_material(lambert_material("grass", {0.2f, 0.45f, 0.1f}));
  const uint32_t plastic = scene.add_material(lambert_material("soup", {0.7f, 0.25f, 0.2f}));
  const uint32_t concrete = scene.add_material(lambert_material("concrete", {0.6f, 0.6f, 0.62f}));
  Material leaf_mat = lambert_material("leaves", {0.15f, 0.5f, 0.1f});
  leaf_mat.alpha_mode = AlphaMode::kBlend;
  leaf_mat.base_color.w = 0.5f;
  leaf_mat.double_sided = true;
  const uint32_t leaves = scene.add_material(leaf_mat);

  const double total = std::max<double>(approx_triangles, 1000.0);
  auto budget = [&](double fraction) { return std::max<uint32_t>(8, uint32_t(total * fraction)); };
  auto add_single = [&](Mesh mesh) {
    const std::string name = mesh.name;
    const uint32_t id = scene.add_mesh(std::move(mesh));
    scene.add_instance({name, id, glm::mat4(1.0f)});
  };

  add_single(make_terrain(budget(0.25), ground));
  Mesh plane;
  plane.name = "ground_plane";
  const float r = 2000.0f;
  append_quad(plane, {-r, -8, -r}, {r, -8, -r}, {r, -8, r}, {-r, -8, r}, ground, {0, 1, 0});
  add_single(std::move(plane));
  add_single(make_torus(budget(0.12), concrete, {-30.0f, 25.0f, 10.0f}));

  // Rocks: a dozen meshes from coarse to fine (sizes double), fewer
  // instances of the finer ones.
  constexpr int kRocks = 12;
  double weight_sum = 0.0;
  for (int i = 0; i < kRocks; ++i)
    weight_sum += std::pow(1.45, i);
  for (int i = 0; i < kRocks; ++i) {
    const uint32_t target =
        std::max<uint32_t>(32, uint32_t(total * 0.30 * std::pow(1.45, i) / weight_sum));
    const uint32_t mesh = scene.add_mesh(make_rock(target, stone, rng));
    const uint32_t copies = 20 + 160 / uint32_t(i + 1);
    for (uint32_t c = 0; c < copies; ++c) {
      scene.add_instance({"rock", mesh, random_placement(rng, 0.3f, 3.0f, 1.8f, 0.3f)});
    }
  }
  for (int i = 0; i < 3; ++i) {
    const uint32_t mesh = scene.add_mesh(make_grass_tuft(budget(0.1 / 3.0), grass, rng));
    for (uint32_t c = 0; c < 120; ++c) {
      scene.add_instance({"grass", mesh, random_placement(rng, 0.5f, 1.5f, 1.3f, 0.0f)});
    }
  }
  const uint32_t foliage = scene.add_mesh(make_foliage(budget(0.03), leaves, rng));
  for (uint32_t c = 0; c < 100; ++c) {
    scene.add_instance({"foliage", foliage, random_placement(rng, 0.8f, 2.5f, 1.2f, 2.0f)});
  }
  const uint32_t box = scene.add_mesh(make_unit_box(concrete));
  for (uint32_t c = 0; c < 400; ++c) {
    const float x = rng.range(-0.9f, 0.9f) * kTerrainHalfSize,
                z = rng.range(-0.9f, 0.9f) * kTerrainHalfSize;
    const glm::vec3 size = {rng.range(1.0f, 6.0f), rng.log_range(2.0f, 40.0f),
                            rng.range(1.0f, 6.0f)};
    glm::mat4 t = glm::translate(glm::mat4(1.0f), {x, terrain_height(x, z) - 1.0f, z});
    t = glm::rotate(t, rng.range(0.0f, 1.5707963f), glm::vec3(0, 1, 0));
    scene.add_instance({"tower", box, glm::scale(t, size)});
  }

  // The soup takes whatever the tessellations above left of the budget, so
  // the scene has (at least) the requested number of unique triangles.
  const size_t so_far = scene.triangle_count_unique();
  add_single(make_soup(
      std::max<uint32_t>(budget(0.1), uint32_t(std::max<double>(total - double(so_far), 0.0))),
      plastic, rng));

  Environment env;
  env.color = {0.6f, 0.7f, 0.9f};
  scene.set_environment(env);
  Camera cam;
  cam.position = {85.0f, 45.0f, 95.0f};
  cam.forward = glm::normalize(glm::vec3(-80.0f, -35.0f, -90.0f));
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  cam.yfov = 0.9f;
  cam.aspect_ratio = 16.0f / 9.0f;
  scene.set_camera(cam);
  return scene;
}

}  // namespace tandem
