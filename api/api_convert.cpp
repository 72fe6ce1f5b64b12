#include "api/api_convert.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "core/kernel/math.h"
#include "core/world/mesh_pose.h"
#include "core/world/scene_ranges.h"

#include <glm/gtc/type_ptr.hpp>

namespace tandem::api_detail {

namespace {

constexpr uint32_t kMaxResolution = 16384;
constexpr uint32_t kMaxSamplesPerFrame = 4096;
constexpr uint32_t kMaxDepth = 1024;

std::string field(const char* what, const char* name) {
  return std::string(what) + ": " + name;
}

void check_finite(float v, const char* what, const char* name) {
  if (!std::isfinite(v)) invalid(field(what, name) + " is not a finite number");
}

void check_range(float v, float lo, float hi, const char* what, const char* name) {
  check_finite(v, what, name);
  if (v < lo || v > hi) {
    invalid(field(what, name) + " is " + std::to_string(v) + ", outside [" + std::to_string(lo) +
            ", " + std::to_string(hi) + "]");
  }
}

void check_non_negative(const float* v, int n, const char* what, const char* name) {
  for (int i = 0; i < n; ++i) {
    check_finite(v[i], what, name);
    if (v[i] < 0.0f) invalid(field(what, name) + " has a negative component");
  }
}

// A point rays can start from: within the range Tandem traces.
void check_place(const glm::vec3& p, const char* what, const char* name) {
  if (glm::all(glm::lessThanEqual(glm::abs(p), glm::vec3(kMaxWorldCoordinate)))) return;
  char text[96];
  std::snprintf(text, sizeof text, " (%g, %g, %g) lies beyond %g of the origin", p.x, p.y, p.z,
                double(kMaxWorldCoordinate));
  invalid(field(what, name) + text + ", the range Tandem can trace");
}

// Radiance `scale` x `strength`, each finite, whose product floats cannot carry.
void check_radiance(float scale, float strength, const char* what, const char* name) {
  const double radiance = double(scale) * double(strength);
  if (radiance <= kMaxRadiance) return;
  char text[96];
  std::snprintf(text, sizeof text, " is %g, beyond the largest radiance that can be rendered (%g)",
                radiance, kMaxRadiance);
  invalid(field(what, name) + text);
}

glm::vec3 vec3(const float v[3], const char* what, const char* name) {
  for (int i = 0; i < 3; ++i)
    check_finite(v[i], what, name);
  return {v[0], v[1], v[2]};
}

// The vertex arrays of `data` after their presence and values are checked.
void check_vertices(const MeshData& data, const char* what) {
  if (data.vertex_count == 0) invalid(std::string(what) + ": the mesh has no vertices");
  if (data.vertex_count > std::numeric_limits<uint32_t>::max())
    invalid(std::string(what) + ": more than 2^32 - 1 vertices");
  if (!data.positions) invalid(std::string(what) + ": positions is null");
  const size_t n = data.vertex_count;
  for (size_t i = 0; i < n * 3; ++i) {
    if (!std::isfinite(data.positions[i]))
      invalid(std::string(what) + ": position of vertex " + std::to_string(i / 3) +
              " is not finite");
    if (data.normals && !std::isfinite(data.normals[i]))
      invalid(std::string(what) + ": normal of vertex " + std::to_string(i / 3) + " is not finite");
  }
  if (data.uvs) {
    for (size_t i = 0; i < n * 2; ++i) {
      if (!std::isfinite(data.uvs[i]))
        invalid(std::string(what) + ": uv of vertex " + std::to_string(i / 2) + " is not finite");
    }
  }
}

void copy_vertices(const MeshData& data, Mesh& mesh) {
  const size_t n = data.vertex_count;
  mesh.positions.resize(n);
  for (size_t i = 0; i < n; ++i)
    mesh.positions[i] = glm::make_vec3(data.positions + 3 * i);
  if (data.normals) {
    mesh.normals.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const glm::vec3 nrm = glm::make_vec3(data.normals + 3 * i);
      const float len = glm::length(nrm);
      // A zero normal would make shading NaN: fall back to +z rather than fail
      // on the odd degenerate vertex an exporter writes.
      mesh.normals[i] = len > 0.0f ? nrm / len : glm::vec3(0.0f, 0.0f, 1.0f);
    }
  }
  if (data.uvs) {
    mesh.uv0.resize(n);
    for (size_t i = 0; i < n; ++i)
      mesh.uv0[i] = glm::make_vec2(data.uvs + 2 * i);
  }
}

}  // namespace

void invalid(const std::string& message) {
  throw Error(Error::Kind::kInvalidArgument, message);
}

Mesh to_mesh(const MeshData& data, uint32_t material, const char* what) {
  check_vertices(data, what);
  if (data.triangle_count == 0) invalid(std::string(what) + ": the mesh has no triangles");
  if (data.triangle_count > std::numeric_limits<uint32_t>::max())
    invalid(std::string(what) + ": more than 2^32 - 1 triangles");
  if (!data.indices) invalid(std::string(what) + ": indices is null");
  for (size_t i = 0; i < data.triangle_count * 3; ++i) {
    if (data.indices[i] >= data.vertex_count) {
      invalid(std::string(what) + ": index " + std::to_string(i) + " (triangle " +
              std::to_string(i / 3) + ") is " + std::to_string(data.indices[i]) +
              ", out of range for " + std::to_string(data.vertex_count) + " vertices");
    }
  }
  Mesh mesh;
  copy_vertices(data, mesh);
  mesh.triangles.resize(data.triangle_count);
  for (size_t t = 0; t < data.triangle_count; ++t) {
    mesh.triangles[t] = {data.indices[3 * t], data.indices[3 * t + 1], data.indices[3 * t + 2]};
  }
  mesh.triangle_materials.assign(data.triangle_count, material);
  return mesh;
}

namespace {

// The attributes a caller gave: positions, and normals and uv0 where given
// (empty: the mesh keeps its own).
class GivenVertices final : public MeshPose {
 public:
  explicit GivenVertices(Mesh given) : given_(std::move(given)) {}
  size_t vertex_count() const override { return given_.positions.size(); }
  void write(Mesh& out) const override {
    out.positions = given_.positions;
    if (!given_.normals.empty()) out.normals = given_.normals;
    if (!given_.uv0.empty()) out.uv0 = given_.uv0;
  }
  bool write(const MeshVertexTarget& target, SceneBounds* box) const override {
    const size_t n = given_.positions.size();
    // An attribute the compiled mesh has no room for: the compiler's copy.
    if (target.vertex_count != n || (!given_.normals.empty() && target.normals == nullptr) ||
        (!given_.uv0.empty() && target.uv0 == nullptr))
      return false;
    for (size_t v = 0; v < n; ++v) {
      const glm::vec3& p = given_.positions[v];
      target.positions[v] = {p.x, p.y, p.z};
    }
    for (size_t v = 0; v < given_.normals.size(); ++v) {
      const glm::vec3& nrm = given_.normals[v];
      target.normals[v] = {nrm.x, nrm.y, nrm.z};
    }
    for (size_t v = 0; v < given_.uv0.size(); ++v)
      target.uv0[v] = {given_.uv0[v].x, given_.uv0[v].y};
    bool finite = false;
    *box = vertex_bounds(given_.positions.data(), n, &finite);
    return finite;
  }

 private:
  Mesh given_;
};

}  // namespace

std::shared_ptr<const MeshPose> vertices_pose(const MeshData& vertices, size_t mesh_vertices,
                                              const char* what) {
  check_vertices(vertices, what);
  if (vertices.vertex_count != mesh_vertices) {
    invalid(std::string(what) + ": " + std::to_string(vertices.vertex_count) +
            " vertices given, the mesh has " + std::to_string(mesh_vertices));
  }
  Mesh given;
  copy_vertices(vertices, given);
  return std::make_shared<GivenVertices>(std::move(given));
}

namespace {

TextureRef texture_slot(TextureId id, size_t textures, const char* what, const char* slot) {
  // The ids are the scene's texture indices (textures are never removed).
  TextureRef ref;
  if (id.index == TextureId::kNone) return ref;
  if (id.index >= textures) {
    invalid(std::string(what) + ": " + slot + " " + std::to_string(id.index) +
            " does not exist (there are " + std::to_string(textures) + " textures)");
  }
  ref.texture = int32_t(id.index);
  return ref;
}

WrapMode to_wrap(TextureWrap w, const char* what) {
  switch (w) {
    case TextureWrap::kRepeat:
      return WrapMode::kRepeat;
    case TextureWrap::kClampToEdge:
      return WrapMode::kClampToEdge;
    case TextureWrap::kMirroredRepeat:
      return WrapMode::kMirroredRepeat;
  }
  invalid(std::string(what) + ": unknown wrap mode");
}

}  // namespace

Texture to_texture(const TextureDesc& d, const char* what, float* peak) {
  if ((d.rgba8 == nullptr) == (d.rgba32f == nullptr))
    invalid(std::string(what) + ": give exactly one of rgba8 and rgba32f");
  if (d.width == 0 || d.height == 0 || d.width > kMaxResolution || d.height > kMaxResolution) {
    invalid(std::string(what) + ": a " + std::to_string(d.width) + "x" + std::to_string(d.height) +
            " texture is empty or wider or taller than 16384");
  }
  Texture t;
  t.width = d.width;
  t.height = d.height;
  t.wrap_s = to_wrap(d.wrap_u, what);
  t.wrap_t = to_wrap(d.wrap_v, what);
  t.nearest = d.nearest;
  switch (d.color_space) {
    case TextureColorSpace::kBySlot:
      break;
    case TextureColorSpace::kSrgb:
      if (d.rgba32f != nullptr)
        invalid(std::string(what) + ": a float texture is linear (color_space kSrgb)");
      t.encoding = TextureEncoding::kSrgb;
      break;
    case TextureColorSpace::kLinear:
      t.encoding = TextureEncoding::kLinear;
      break;
    default:
      invalid(std::string(what) + ": unknown color_space");
  }
  const size_t n = size_t(d.width) * d.height;
  *peak = 1.0f;
  if (d.rgba8 != nullptr) {
    t.rgba8.resize(n);
    std::memcpy(t.rgba8.data(), d.rgba8, n * 4);  // R, G, B, A bytes: R low
    return t;
  }
  t.rgba32f.resize(n);
  for (size_t i = 0; i < 4 * n; ++i) {
    const float v = d.rgba32f[i];
    if (!(v >= 0.0f && v <= 1e6f)) {
      invalid(std::string(what) + ": rgba32f value " + std::to_string(i) +
              " is NaN or outside [0, 1e6]");
    }
    *peak = std::max(*peak, v);
  }
  std::memcpy(t.rgba32f.data(), d.rgba32f, n * 16);
  return t;
}

Material to_material(const MaterialDesc& d, const std::vector<float>& texture_peaks,
                     const char* what) {
  Material m;
  const size_t textures = texture_peaks.size();
  auto slot = [&](TextureId id, const char* name) {
    return texture_slot(id, textures, what, name);
  };
  m.base_color_texture = slot(d.base_color_texture, "base_color_texture");
  m.metallic_roughness_texture = slot(d.metallic_roughness_texture, "metallic_roughness_texture");
  m.emissive_texture = slot(d.emission_texture, "emission_texture");
  m.transmission_texture = slot(d.transmission_texture, "transmission_texture");
  m.normal_texture = slot(d.normal_texture, "normal_texture");
  m.clearcoat_texture = slot(d.clearcoat_texture, "clearcoat_texture");
  m.clearcoat_roughness_texture =
      slot(d.clearcoat_roughness_texture, "clearcoat_roughness_texture");
  m.sheen_color_texture = slot(d.sheen_color_texture, "sheen_color_texture");
  m.sheen_roughness_texture = slot(d.sheen_roughness_texture, "sheen_roughness_texture");
  check_range(d.alpha, 0.0f, 1.0f, what, "alpha");
  check_range(d.alpha_cutoff, 0.0f, 1.0f, what, "alpha_cutoff");
  switch (d.alpha_mode) {
    case MaterialAlpha::kOpaque:
      m.alpha_mode = AlphaMode::kOpaque;
      break;
    case MaterialAlpha::kMask:
      m.alpha_mode = AlphaMode::kMask;
      break;
    case MaterialAlpha::kBlend:
      m.alpha_mode = AlphaMode::kBlend;
      break;
    default:
      invalid(std::string(what) + ": unknown alpha_mode");
  }
  m.alpha_cutoff = d.alpha_cutoff;
  check_range(d.specular, 0.0f, 1.0f, what, "specular");
  check_range(d.clearcoat, 0.0f, 1.0f, what, "clearcoat");
  check_range(d.clearcoat_roughness, 0.0f, 1.0f, what, "clearcoat_roughness");
  check_range(d.sheen_roughness, 0.0f, 1.0f, what, "sheen_roughness");
  check_range(d.normal_scale, -100.0f, 100.0f, what, "normal_scale");
  for (int i = 0; i < 3; ++i) {
    check_range(d.specular_color[i], 0.0f, 1.0f, what, "specular_color");
    check_range(d.sheen_color[i], 0.0f, 1.0f, what, "sheen_color");
  }
  m.specular = d.specular;
  m.specular_color = glm::vec3(d.specular_color[0], d.specular_color[1], d.specular_color[2]);
  m.clearcoat = d.clearcoat;
  m.clearcoat_roughness = d.clearcoat_roughness;
  m.sheen_color = glm::vec3(d.sheen_color[0], d.sheen_color[1], d.sheen_color[2]);
  m.sheen_roughness = d.sheen_roughness;
  m.normal_scale = d.normal_scale;
  for (int i = 0; i < 3; ++i)
    check_range(d.base_color[i], 0.0f, 1.0f, what, "base_color");
  check_range(d.roughness, 0.0f, 1.0f, what, "roughness");
  check_range(d.metallic, 0.0f, 1.0f, what, "metallic");
  check_non_negative(d.emission, 3, what, "emission");
  check_range(d.emission_strength, 0.0f, std::numeric_limits<float>::max(), what,
              "emission_strength");
  check_range(d.transmission, 0.0f, 1.0f, what, "transmission");
  check_range(d.ior, 1.0f, 5.0f, what, "ior");
  m.base_color = glm::vec4(d.base_color[0], d.base_color[1], d.base_color[2], d.alpha);
  m.roughness = d.roughness;
  m.metallic = d.metallic;
  m.emissive = glm::vec3(d.emission[0], d.emission[1], d.emission[2]);
  m.emissive_strength = d.emission_strength;
  // A float emission texture multiplies the radiance by up to its peak.
  const float peak =
      m.emissive_texture.texture >= 0 ? texture_peaks[size_t(m.emissive_texture.texture)] : 1.0f;
  check_radiance(std::max({d.emission[0], d.emission[1], d.emission[2]}) * peak,
                 d.emission_strength, what,
                 "emission times emission_strength (times a float emission texture's peak)");
  m.transmission = d.transmission;
  m.ior = d.ior;
  m.double_sided = d.double_sided;
  return m;
}

Light to_light(const LightDesc& d, const char* what) {
  Light l;
  switch (d.kind) {
    case LightKind::kPoint:
      l.type = LightType::kPoint;
      break;
    case LightKind::kSpot:
      l.type = LightType::kSpot;
      break;
    case LightKind::kDirectional:
      l.type = LightType::kDirectional;
      break;
    default:
      invalid(std::string(what) + ": unknown light kind");
  }
  l.position = vec3(d.position, what, "position");
  if (l.type != LightType::kDirectional) check_place(l.position, what, "position");
  const glm::vec3 dir = vec3(d.direction, what, "direction");
  if (l.type != LightType::kPoint) {
    if (!(glm::length(dir) > 0.0f)) invalid(std::string(what) + ": direction is zero");
    l.direction = glm::normalize(dir);
  }
  check_non_negative(d.color, 3, what, "color");
  l.color = glm::vec3(d.color[0], d.color[1], d.color[2]);
  check_range(d.intensity, 0.0f, std::numeric_limits<float>::max(), what, "intensity");
  l.intensity = d.intensity;
  check_radiance(std::max({d.color[0], d.color[1], d.color[2]}), d.intensity, what,
                 "color times intensity");
  if (l.type == LightType::kSpot) {
    check_range(d.outer_cone_angle, 0.0f, 1.5707963268f, what, "outer_cone_angle");
    check_range(d.inner_cone_angle, 0.0f, d.outer_cone_angle, what, "inner_cone_angle");
    if (!(d.outer_cone_angle > 0.0f)) invalid(std::string(what) + ": outer_cone_angle is zero");
    l.inner_cone_angle = d.inner_cone_angle;
    l.outer_cone_angle = d.outer_cone_angle;
  }
  return l;
}

Camera to_camera(const CameraDesc& d, const char* what) {
  const glm::vec3 position = vec3(d.position, what, "position");
  const glm::vec3 target = vec3(d.target, what, "target");
  const glm::vec3 up = vec3(d.up, what, "up");
  const glm::vec3 view = target - position;
  if (!(glm::length(view) > 0.0f)) invalid(std::string(what) + ": target equals position");
  const glm::vec3 forward = glm::normalize(view);
  const glm::vec3 right = glm::cross(forward, up);
  // Relative test: a tiny but well-formed up vector is fine.
  if (!(glm::length(right) > 1e-6f * glm::length(up)) || !(glm::length(up) > 0.0f))
    invalid(std::string(what) + ": up is zero or parallel to the view direction");
  check_finite(d.vertical_fov, what, "vertical_fov");
  if (!(d.vertical_fov > 0.0f && d.vertical_fov < 3.14159265f))
    invalid(std::string(what) + ": vertical_fov is outside (0, pi) radians");
  check_range(d.aperture_radius, 0.0f, std::numeric_limits<float>::max(), what, "aperture_radius");
  check_finite(d.focus_distance, what, "focus_distance");
  if (!(d.focus_distance > 0.0f)) invalid(std::string(what) + ": focus_distance is not positive");
  Camera c;
  c.type = CameraType::kPerspective;
  c.position = position;
  c.forward = forward;
  c.up = glm::normalize(glm::cross(glm::normalize(right), forward));
  c.yfov = d.vertical_fov;
  c.aperture_radius = d.aperture_radius;
  c.focus_distance = d.focus_distance;
  const std::string problem = camera_problem(c);
  if (!problem.empty()) invalid(std::string(what) + ": " + problem);
  return c;
}

glm::mat4 to_matrix(const Transform& t, const char* what) {
  for (int i = 0; i < 16; ++i) {
    if (!std::isfinite(t.m[i]))
      invalid(std::string(what) + ": transform entry " + std::to_string(i) + " is not finite");
  }
  // Column-major: the last row is m[3], m[7], m[11], m[15].
  if (t.m[3] != 0.0f || t.m[7] != 0.0f || t.m[11] != 0.0f || t.m[15] != 1.0f)
    invalid(std::string(what) + ": transform is not affine (last row must be 0 0 0 1)");
  const glm::mat4 m = glm::make_mat4(t.m);
  check_place(glm::vec3(m[3]), what, "translation");
  // A singular transform (a scale of 0: how games hide an object) is
  // accepted; the instance is not drawn while it stays so (scene_ranges.h).
  return m;
}

void check_options(const RendererOptions& o, const char* what) {
  if (o.width == 0 || o.height == 0) {
    invalid(std::string(what) + ": image size " + std::to_string(o.width) + "x" +
            std::to_string(o.height) + " is empty");
  }
  if (o.width > kMaxResolution || o.height > kMaxResolution)
    invalid(std::string(what) + ": width and height must be at most 16384");
  if (o.samples_per_frame == 0 || o.samples_per_frame > kMaxSamplesPerFrame)
    invalid(std::string(what) + ": samples_per_frame must be in [1, 4096]");
  if (o.max_depth > kMaxDepth) invalid(std::string(what) + ": max_depth must be at most 1024");
  if (o.threads > 4096 || o.reserve_cores > 4096)
    invalid(std::string(what) + ": threads and reserve_cores must each be at most 4096");
  switch (o.backend) {
    case BackendChoice::kAuto:
    case BackendChoice::kCpu:
    case BackendChoice::kCuda:
    case BackendChoice::kHetero:
      break;
    default:
      invalid(std::string(what) + ": unknown backend");
  }
  if (o.light_sampling != LightSampling::kTree && o.light_sampling != LightSampling::kPower)
    invalid(std::string(what) + ": unknown light_sampling");
  // Only a GPU-only renderer has the whole image on the GPU.
  if (o.cuda_image && o.backend != BackendChoice::kCuda)
    invalid(std::string(what) + ": cuda_image needs BackendChoice::kCuda");
}

}  // namespace tandem::api_detail
