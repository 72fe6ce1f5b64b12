#include "scenes/procedural_rigs.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "scenes/builtin_scenes.h"

namespace tandem {

namespace {

constexpr float kPi = 3.14159265358979f;

// Box [lo, hi] with its four sides cut into `segments` bands along y, so a
// limb bends smoothly where its weights blend.
void append_segmented_box(Mesh& mesh, glm::vec3 lo, glm::vec3 hi, uint32_t segments,
                          uint32_t material) {
  const glm::vec3 c = (lo + hi) * 0.5f;
  for (uint32_t s = 0; s < segments; ++s) {
    const float y0 = lo.y + (hi.y - lo.y) * float(s) / float(segments);
    const float y1 = lo.y + (hi.y - lo.y) * float(s + 1) / float(segments);
    const glm::vec2 corners[4] = {{lo.x, lo.z}, {hi.x, lo.z}, {hi.x, hi.z}, {lo.x, hi.z}};
    for (int k = 0; k < 4; ++k) {
      const glm::vec2 a = corners[k], b = corners[(k + 1) % 4];
      const glm::vec3 mid((a.x + b.x) * 0.5f, (y0 + y1) * 0.5f, (a.y + b.y) * 0.5f);
      append_quad(mesh, {a.x, y0, a.y}, {b.x, y0, b.y}, {b.x, y1, b.y}, {a.x, y1, a.y}, material,
                  glm::vec3(mid.x - c.x, 0.0f, mid.z - c.z));
    }
  }
  append_quad(mesh, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z},
              material, {0, 1, 0});
  append_quad(mesh, {lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, lo.y, hi.z}, {lo.x, lo.y, hi.z},
              material, {0, -1, 0});
}

// Walker joints: 0 pelvis (carries the placement), 1/2 left thigh/shin,
// 3/4 right thigh/shin, 5/6 left/right arm. Bind pose: the figure stands at
// the origin, feet on y = 0, facing +z.
constexpr float kHipY = 0.95f, kKneeY = 0.5f, kShoulderY = 1.45f, kLegX = 0.1f, kArmX = 0.27f;
constexpr float kKneeBlend = 0.06f;  // half height of the knee's blend zone

glm::mat4 about(const glm::vec3& pivot, float angle, const glm::vec3& axis) {
  return glm::translate(glm::mat4(1.0f), pivot) * glm::rotate(glm::mat4(1.0f), angle, axis) *
         glm::translate(glm::mat4(1.0f), -pivot);
}

void set_influence(MeshDeformation& d, size_t v, uint16_t j0, float w0, uint16_t j1 = 0,
                   float w1 = 0.0f) {
  d.joints[4 * v] = j0, d.weights[4 * v] = w0;
  d.joints[4 * v + 1] = j1, d.weights[4 * v + 1] = w1;
}

}  // namespace

ProceduralRig make_walker_rig(uint32_t material) {
  ProceduralRig rig;
  Mesh& m = rig.mesh;
  m.name = "rig.walker";
  struct Part {
    size_t first;
    int kind;  // 0 body, 1 left leg, 2 right leg, 3 left arm, 4 right arm
  };
  std::vector<Part> parts;
  auto part = [&](int kind) { parts.push_back({m.positions.size(), kind}); };
  part(0);
  append_segmented_box(m, {-0.2f, kHipY, -0.12f}, {0.2f, 1.5f, 0.12f}, 1, material);     // torso
  append_segmented_box(m, {-0.11f, 1.55f, -0.11f}, {0.11f, 1.77f, 0.11f}, 1, material);  // head
  for (int side = 0; side < 2; ++side) {
    const float x = side == 0 ? kLegX : -kLegX;
    part(1 + side);
    append_segmented_box(m, {x - 0.075f, 0.06f, -0.075f}, {x + 0.075f, kHipY, 0.075f}, 12,
                         material);
    append_segmented_box(m, {x - 0.07f, 0.0f, -0.07f}, {x + 0.07f, 0.06f, 0.2f}, 1, material);
  }
  for (int side = 0; side < 2; ++side) {
    const float x = side == 0 ? kArmX : -kArmX;
    part(3 + side);
    append_segmented_box(m, {x - 0.055f, 0.85f, -0.055f}, {x + 0.055f, kShoulderY, 0.055f}, 4,
                         material);
  }
  parts.push_back({m.positions.size(), -1});

  MeshDeformation& d = rig.deformation;
  d.base_positions = m.positions;
  d.palette_size = kWalkerJoints;
  d.influences = 4;
  d.joints.assign(m.positions.size() * 4, 0);
  d.weights.assign(m.positions.size() * 4, 0.0f);
  for (size_t p = 0; p + 1 < parts.size(); ++p) {
    for (size_t v = parts[p].first; v < parts[p + 1].first; ++v) {
      const float y = m.positions[v].y;
      switch (parts[p].kind) {
        case 0:
          set_influence(d, v, 0, 1.0f);
          break;
        case 1:
        case 2: {
          const uint16_t thigh = parts[p].kind == 1 ? 1 : 3;
          const float s = std::clamp((y - (kKneeY - kKneeBlend)) / (2.0f * kKneeBlend), 0.0f, 1.0f);
          set_influence(d, v, thigh, s, uint16_t(thigh + 1), 1.0f - s);
          break;
        }
        default:
          set_influence(d, v, parts[p].kind == 3 ? 5 : 6, 1.0f);
      }
    }
  }
  return rig;
}

void walker_palette(double t, const WalkerPath& path, JointMatrix* out) {
  const double theta = double(path.angle) + double(path.speed) / double(path.radius) * t;
  const glm::vec3 position =
      path.center + path.radius * glm::vec3(float(std::cos(theta)), 0.0f, float(std::sin(theta)));
  glm::vec3 heading(float(-std::sin(theta)), 0.0f, float(std::cos(theta)));
  if (path.speed < 0.0f) heading = -heading;
  const float yaw = std::atan2(heading.x, heading.z);
  // About 1.1 strides per second at 0.8 m/s for a full-size figure.
  const double cycle_hz = std::fabs(double(path.speed)) * 1.4 / double(path.scale);
  const float phi =
      float(std::fmod(double(path.cycle_phase) + 2.0 * M_PI * cycle_hz * t, 2.0 * M_PI));
  const float bob = 0.025f * std::cos(2.0f * phi);
  const glm::mat4 root = glm::translate(glm::mat4(1.0f), position) *
                         glm::rotate(glm::mat4(1.0f), yaw, glm::vec3(0, 1, 0)) *
                         glm::scale(glm::mat4(1.0f), glm::vec3(path.scale)) *
                         glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, bob, 0.0f));
  const glm::vec3 x_axis(1, 0, 0);
  glm::mat4 joints[kWalkerJoints];
  joints[0] = root;
  for (int side = 0; side < 2; ++side) {
    const float leg_phase = phi + (side == 0 ? 0.0f : kPi);
    const float x = side == 0 ? kLegX : -kLegX;
    // Swing about the hip; the knee bends (backwards only) while the foot
    // travels forward.
    const float swing = -0.45f * std::sin(leg_phase);
    const float knee = 0.9f * std::max(0.0f, std::sin(leg_phase + 1.2f));
    joints[1 + 2 * side] = root * about({x, kHipY, 0.0f}, swing, x_axis);
    joints[2 + 2 * side] = joints[1 + 2 * side] * about({x, kKneeY, 0.0f}, knee, x_axis);
    // Arms swing against the leg of their side.
    joints[5 + side] = root * about({side == 0 ? kArmX : -kArmX, kShoulderY, 0.0f},
                                    0.4f * std::sin(leg_phase), x_axis);
  }
  for (uint32_t j = 0; j < kWalkerJoints; ++j)
    out[j] = joint_matrix(joints[j]);
}

const std::vector<WalkerPath>& arena_walker_paths() {
  // Around the cube's pedestal, inside the orbs' orbits: three figures at
  // different places on the circle and in their walk cycles.
  static const std::vector<WalkerPath> paths = {
      {{0.0f, 0.0f, 0.0f}, 1.65f, 0.7f, 0.0f, 0.0f, 0.8f},
      {{0.0f, 0.0f, 0.0f}, 1.65f, 0.7f, 2.1f, 1.9f, 0.8f},
      {{0.0f, 0.0f, 0.0f}, 1.65f, 0.7f, 4.2f, 4.1f, 0.8f},
  };
  return paths;
}

namespace {

// The number of each grid point (i, j): its rank in Morton (Z) order, so
// that points near each other on the sheet are near each other in memory.
// Row by row, a triangle's vertices lay a row (12 KB of positions) apart,
// so the refit's gathers over a BVH leaf touched a page a row; exporters
// number a real mesh's vertices by a cache-friendly walk of its triangles,
// which keeps neighbours close as this does.
std::vector<uint32_t> grid_vertex_numbers(uint32_t resolution) {
  const auto spread = [](uint32_t x) {  // bit b of x (< 2^16) to bit 2b
    uint64_t r = 0;
    for (int b = 0; b < 16; ++b)
      r |= uint64_t((x >> b) & 1u) << (2 * b);
    return r;
  };
  // The Morton code above the point's row-major index, sorted as one
  // integer (a grid has fewer than 2^32 points, so i, j < 2^16).
  const size_t n = size_t(resolution) * resolution;
  std::vector<uint64_t> keys(n);
  for (uint32_t j = 0; j < resolution; ++j) {
    for (uint32_t i = 0; i < resolution; ++i) {
      const size_t p = size_t(j) * resolution + i;
      keys[p] = (spread(i) | spread(j) << 1) << 32 | p;
    }
  }
  std::sort(keys.begin(), keys.end());
  std::vector<uint32_t> number(n);
  for (size_t rank = 0; rank < n; ++rank)
    number[keys[rank] & 0xffffffffu] = uint32_t(rank);
  return number;
}

}  // namespace

ProceduralRig make_skinned_grid_rig(uint32_t resolution, uint32_t material) {
  resolution = std::max(resolution, 2u);
  ProceduralRig rig;
  Mesh& m = rig.mesh;
  m.name = "rig.skinned-grid";
  const size_t n = size_t(resolution) * resolution;
  // number[j * resolution + i]: the vertex of grid point (i, j).
  const std::vector<uint32_t> number = grid_vertex_numbers(resolution);
  m.positions.resize(n);
  m.normals.assign(n, glm::vec3(0.0f, 1.0f, 0.0f));
  for (uint32_t j = 0; j < resolution; ++j) {
    for (uint32_t i = 0; i < resolution; ++i) {
      m.positions[number[size_t(j) * resolution + i]] = {
          -5.0f + 10.0f * float(i) / float(resolution - 1), 0.0f,
          -5.0f + 10.0f * float(j) / float(resolution - 1)};
    }
  }
  m.triangles.reserve(size_t(resolution - 1) * (resolution - 1) * 2);
  for (uint32_t j = 0; j + 1 < resolution; ++j) {
    for (uint32_t i = 0; i + 1 < resolution; ++i) {
      const uint32_t p = j * resolution + i;
      const uint32_t a = number[p], b = number[p + 1], c = number[p + resolution],
                     e = number[p + resolution + 1];
      m.triangles.push_back({a, c, b});  // counter-clockwise seen from +y
      m.triangles.push_back({b, c, e});
    }
  }
  m.triangle_materials.assign(m.triangles.size(), material);

  MeshDeformation& d = rig.deformation;
  d.base_positions = m.positions;
  d.base_normals = m.normals;
  d.palette_size = kGridJoints;
  d.influences = 4;
  d.joints.resize(n * 4);
  d.weights.resize(n * 4);
  // Uniform cubic B-spline weights over the four nearest joints along x:
  // they sum to one and blend smoothly, as a real skin's would.
  for (uint32_t i = 0; i < resolution; ++i) {
    const float u = float(i) / float(resolution - 1) * float(kGridJoints - 1);
    const int k = std::min(int(u), int(kGridJoints) - 2);
    const float f = u - float(k);
    const float b[4] = {(1 - f) * (1 - f) * (1 - f) / 6.0f, (3 * f * f * f - 6 * f * f + 4) / 6.0f,
                        (-3 * f * f * f + 3 * f * f + 3 * f + 1) / 6.0f, f * f * f / 6.0f};
    for (uint32_t j = 0; j < resolution; ++j) {
      const size_t v = number[size_t(j) * resolution + i];
      for (int s = 0; s < 4; ++s) {
        d.joints[4 * v + size_t(s)] = uint16_t(std::clamp(k - 1 + s, 0, int(kGridJoints) - 1));
        d.weights[4 * v + size_t(s)] = b[s];
      }
    }
  }
  return rig;
}

void skinned_grid_palette(double t, JointMatrix* out) {
  // A chain along x: joint k turns about z at its own x, all children with it.
  glm::mat4 m(1.0f);
  for (uint32_t k = 0; k < kGridJoints; ++k) {
    const float x = -5.0f + 10.0f * float(k) / float(kGridJoints - 1);
    const float a = k == 0 ? 0.0f : 0.22f * float(std::sin(1.5 * t - 0.8 * k));
    m = m * about({x, 0.0f, 0.0f}, a, glm::vec3(0, 0, 1));
    out[k] = joint_matrix(m);
  }
}

Scene make_skinned_grid_scene(uint32_t resolution) {
  Scene scene;
  scene.source = "builtin:skinned-grid";
  Material mat;
  mat.name = "sheet";
  mat.base_color = {0.7f, 0.55f, 0.35f, 1.0f};
  mat.metallic = 0.0f;
  mat.roughness = 0.5f;
  mat.double_sided = true;
  const uint32_t material = scene.add_material(mat);
  ProceduralRig rig = make_skinned_grid_rig(resolution, material);
  const uint32_t mesh = scene.add_mesh(std::move(rig.mesh));
  scene.set_mesh_deforms(mesh);
  scene.add_instance({"rig.skinned-grid", mesh, glm::mat4(1.0f)});
  Light sun;
  sun.name = "sun";
  sun.type = LightType::kDirectional;
  sun.intensity = 3.0f;
  sun.direction = glm::normalize(glm::vec3(-0.3f, -1.0f, -0.4f));
  scene.add_light(sun);
  Environment env;
  env.color = {0.3f, 0.4f, 0.55f};
  scene.set_environment(env);
  Camera cam;
  cam.position = {0.0f, 7.0f, 11.0f};
  cam.forward = glm::normalize(-cam.position);
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  cam.aspect_ratio = 16.0f / 9.0f;
  cam.focus_distance = glm::length(cam.position);
  scene.set_camera(cam);
  return scene;
}

ProceduralRigPlayer::ProceduralRigPlayer(const Scene& scene) {
  const std::vector<WalkerPath>& paths = arena_walker_paths();
  const std::string walker = "rig.walker.";
  for (uint32_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& mesh = scene.meshes()[i];
    Rig rig;
    MeshDeformation deformation;
    if (mesh.name == "rig.skinned-grid") {
      const uint32_t r = uint32_t(std::lround(std::sqrt(double(mesh.positions.size()))));
      deformation = make_skinned_grid_rig(r, 0).deformation;
    } else if (mesh.name.rfind(walker, 0) == 0) {
      const size_t index = std::strtoul(mesh.name.c_str() + walker.size(), nullptr, 10);
      if (index >= paths.size()) continue;
      rig.walker = int(index);
      deformation = make_walker_rig(0).deformation;
    } else {
      continue;
    }
    // A mesh that only shares the name is left alone.
    if (deformation.vertex_count() != mesh.positions.size()) continue;
    deformation.mesh = i;
    rig.deformation = std::make_shared<const MeshDeformation>(std::move(deformation));
    rigs_.push_back(std::move(rig));
  }
}

size_t ProceduralRigPlayer::vertex_count() const {
  size_t n = 0;
  for (const Rig& r : rigs_)
    n += r.deformation->vertex_count();
  return n;
}

void ProceduralRigPlayer::pose(double t, Scene& scene) const {
  JointMatrix palette[std::max(kWalkerJoints, kGridJoints)];
  for (const Rig& r : rigs_) {
    if (r.walker >= 0) {
      walker_palette(t, arena_walker_paths()[size_t(r.walker)], palette);
    } else {
      skinned_grid_palette(t, palette);
    }
    deform_scene_mesh(r.deformation, palette, nullptr, scene, r.last);
  }
}

}  // namespace tandem
