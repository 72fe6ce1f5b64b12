#include "core/scene/kernel_scene.h"

#include <algorithm>
#include <cmath>

#include "core/kernel/lights.h"
#include "core/kernel/microfacet.h"
#include "core/kernel/texture.h"
#include "core/scene/light_tables.h"

namespace tandem {

// ---------------------------------------------------------------------------
// KernelScene / deltas

KernelData KernelScene::view() const {
  KernelData kd{};
#define TANDEM_FILL_VIEW(T, name) \
  kd.name = name.data();          \
  kd.name##_count = uint32_t(name.size());
  TANDEM_KERNEL_ARRAYS(TANDEM_FILL_VIEW)
#undef TANDEM_FILL_VIEW
  kd.constants = constants;
  return kd;
}

uint32_t KernelScene::vertex_count() const {
  return positions.empty() ? 0u : uint32_t(positions.size() - 1);
}

size_t KernelScene::byte_size() const {
  size_t bytes = sizeof(constants);
#define TANDEM_ADD_BYTES(T, name) bytes += name.size() * sizeof(T);
  TANDEM_KERNEL_ARRAYS(TANDEM_ADD_BYTES)
#undef TANDEM_ADD_BYTES
  return bytes;
}

SceneDelta SceneDelta::everything() {
  SceneDelta all;
  all.full = all.constants = all.instances_changed = true;
#define TANDEM_MARK_REALLOCATED(T, name) all.name.reallocated = true;
  TANDEM_KERNEL_ARRAYS(TANDEM_MARK_REALLOCATED)
#undef TANDEM_MARK_REALLOCATED
  return all;
}

void SceneDelta::merge(const SceneDelta& later) {
#define TANDEM_MERGE_CHANGE(T, name)                             \
  name.reallocated = name.reallocated || later.name.reallocated; \
  name.mark(later.name.begin, later.name.end);
  TANDEM_KERNEL_ARRAYS(TANDEM_MERGE_CHANGE)
#undef TANDEM_MERGE_CHANGE
  full = full || later.full;
  constants = constants || later.constants;
  instances_changed = instances_changed || later.instances_changed;
  auto add_unique = [](std::vector<uint32_t>& to, const std::vector<uint32_t>& from) {
    for (uint32_t m : from) {
      if (std::find(to.begin(), to.end(), m) == to.end()) to.push_back(m);
    }
  };
  add_unique(meshes_rebuilt, later.meshes_rebuilt);
  add_unique(meshes_refit, later.meshes_refit);
}

void ArrayChange::mark(uint32_t b, uint32_t e) {
  if (e <= b) return;
  if (end <= begin) {
    begin = b;
    end = e;
  } else {
    begin = std::min(begin, b);
    end = std::max(end, e);
  }
}

bool SceneDelta::any() const {
  bool any_array = false;
#define TANDEM_ANY_CHANGE(T, name) any_array = any_array || name.any();
  TANDEM_KERNEL_ARRAYS(TANDEM_ANY_CHANGE)
#undef TANDEM_ANY_CHANGE
  return any_array || full || constants || instances_changed;
}

size_t SceneDelta::bytes(const KernelScene& ks) const {
  size_t total = constants ? sizeof(KernelConstants) : 0;
#define TANDEM_CHANGE_BYTES(T, name)     \
  if (name.reallocated)                  \
    total += ks.name.size() * sizeof(T); \
  else if (name.end > name.begin)        \
    total += size_t(name.end - name.begin) * sizeof(T);
  TANDEM_KERNEL_ARRAYS(TANDEM_CHANGE_BYTES)
#undef TANDEM_CHANGE_BYTES
  return total;
}

// ---------------------------------------------------------------------------
// Conversions

namespace {

Vec3 to_vec3(const glm::vec3& v) {
  return {v.x, v.y, v.z};
}

Mat34 to_mat34(const glm::mat4& m) {
  // glm is column-major: m[col][row].
  Mat34 r;
  r.rows[0] = {m[0][0], m[1][0], m[2][0], m[3][0]};
  r.rows[1] = {m[0][1], m[1][1], m[2][1], m[3][1]};
  r.rows[2] = {m[0][2], m[1][2], m[2][2], m[3][2]};
  return r;
}

uint32_t to_wrap(WrapMode w) {
  switch (w) {
    case WrapMode::kClampToEdge:
      return kWrapClamp;
    case WrapMode::kMirroredRepeat:
      return kWrapMirror;
    default:
      return kWrapRepeat;
  }
}

uint32_t to_alpha_mode(AlphaMode a) {
  switch (a) {
    case AlphaMode::kMask:
      return kAlphaMask;
    case AlphaMode::kBlend:
      return kAlphaBlend;
    default:
      return kAlphaOpaque;
  }
}

// KHR_texture_transform: uv' = T * R * S * uv, stored as a 2x3 matrix.
KTextureRef to_texture_ref(const TextureRef& ref, int32_t slot) {
  KTextureRef r{};
  r.texture = slot;
  r.uv_set = ref.transform.uv_set;
  const float c = std::cos(ref.transform.rotation), s = std::sin(ref.transform.rotation);
  const glm::vec2 sc = ref.transform.scale, off = ref.transform.offset;
  // Rotation matrix of the extension: [c s; -s c] applied after scaling.
  r.m[0] = c * sc.x;
  r.m[1] = s * sc.y;
  r.m[2] = off.x;
  r.m[3] = -s * sc.x;
  r.m[4] = c * sc.y;
  r.m[5] = off.y;
  return r;
}

// The KHR_materials_clearcoat and _sheen factors (their texture references
// are compiled with the others).
void compile_layers(const Material& m, KMaterial& k) {
  k.clearcoat = std::clamp(m.clearcoat, 0.0f, 1.0f);
  k.clearcoat_roughness = std::clamp(m.clearcoat_roughness, 0.0f, 1.0f);
  k.sheen_color = to_vec3(glm::clamp(m.sheen_color, glm::vec3(0.0f), glm::vec3(1.0f)));
  k.sheen_roughness = std::clamp(m.sheen_roughness, 0.0f, 1.0f);
}

bool material_emits(const Material& m) {
  return m.emissive_strength > 0.0f &&
         (m.emissive.x > 0.0f || m.emissive.y > 0.0f || m.emissive.z > 0.0f);
}

}  // namespace

// ---------------------------------------------------------------------------
// Compilation

uint32_t SceneCompiler::texture_index(uint32_t texture, bool srgb) const {
  return texture_slots_.at((uint64_t(texture) << 1) | (srgb ? 1u : 0u));
}

void SceneCompiler::compile_textures(const Scene& scene, KernelScene& out) {
  // Texels are stored once per image; KTexture entries are created per
  // (image, colour space) usage because sRGB decoding depends on the slot.
  out.texels.clear();
  out.textures.clear();
  texture_slots_.clear();
  texture_texel_offset_.assign(scene.textures().size(), 0);
  texture_mean_luminance_.assign(scene.textures().size(), 0.0f);
  for (size_t i = 0; i < scene.textures().size(); ++i) {
    const Texture& t = scene.textures()[i];
    texture_texel_offset_[i] = uint32_t(out.texels.size());
    out.texels.insert(out.texels.end(), t.rgba8.begin(), t.rgba8.end());
    double sum = 0.0;
    for (uint32_t px : t.rgba8) {
      const Vec3 c = {srgb8_to_linear(px), srgb8_to_linear(px >> 8), srgb8_to_linear(px >> 16)};
      sum += luminance(c);
    }
    texture_mean_luminance_[i] = t.rgba8.empty() ? 0.0f : float(sum / double(t.rgba8.size()));
  }
  auto slot_for = [&](int32_t tex, bool srgb) {
    if (tex < 0 || size_t(tex) >= scene.textures().size()) return;
    const uint64_t key = (uint64_t(tex) << 1) | (srgb ? 1u : 0u);
    if (texture_slots_.count(key)) return;
    const Texture& t = scene.textures()[size_t(tex)];
    if (t.width == 0 || t.height == 0 || t.rgba8.size() != size_t(t.width) * t.height) return;
    KTexture kt{};
    kt.width = t.width;
    kt.height = t.height;
    kt.texel_offset = texture_texel_offset_[size_t(tex)];
    kt.flags = (srgb ? kTextureSrgb : 0u) | (t.nearest ? kTextureNearest : 0u);
    kt.wrap_s = to_wrap(t.wrap_s);
    kt.wrap_t = to_wrap(t.wrap_t);
    texture_slots_[key] = uint32_t(out.textures.size());
    out.textures.push_back(kt);
  };
  for (const Material& m : scene.materials()) {
    slot_for(m.base_color_texture.texture, true);
    slot_for(m.emissive_texture.texture, true);
    slot_for(m.metallic_roughness_texture.texture, false);
    slot_for(m.normal_texture.texture, false);
    slot_for(m.transmission_texture.texture, false);
    slot_for(m.clearcoat_texture.texture, false);
    slot_for(m.clearcoat_roughness_texture.texture, false);
    slot_for(m.sheen_color_texture.texture, true);
    slot_for(m.sheen_roughness_texture.texture, false);
  }
}

KMaterial SceneCompiler::compile_material(const Scene& scene, const Material& m) {
  KMaterial k{};
  k.base_color = {m.base_color.x, m.base_color.y, m.base_color.z, m.base_color.w};
  k.emission = to_vec3(m.emissive * m.emissive_strength);
  k.metallic = m.metallic;
  k.roughness = m.roughness;
  k.specular_color = to_vec3(glm::clamp(m.specular_color, glm::vec3(0.0f), glm::vec3(1.0f)));
  k.transmission = m.transmission;
  k.ior = m.ior > 0.0f ? m.ior : 1.5f;
  k.specular = m.specular;
  k.fresnel_avg_enter = fresnel_dielectric_average(k.ior);
  k.fresnel_avg_leave = fresnel_dielectric_average(1.0f / k.ior);
  k.alpha_cutoff = m.alpha_cutoff;
  k.alpha_mode = to_alpha_mode(m.alpha_mode);
  k.flags = m.double_sided ? kMaterialDoubleSided : 0u;
  k.normal_scale = m.normal_scale;
  k.emission_luminance_scale = 1.0f;
  auto ref = [&](const TextureRef& r, bool srgb) {
    const uint64_t key = (uint64_t(std::max(r.texture, 0)) << 1) | (srgb ? 1u : 0u);
    const bool valid = r.texture >= 0 && texture_slots_.count(key);
    return to_texture_ref(r, valid ? int32_t(texture_slots_.at(key)) : -1);
  };
  k.base_color_tex = ref(m.base_color_texture, true);
  k.metallic_roughness_tex = ref(m.metallic_roughness_texture, false);
  k.normal_tex = ref(m.normal_texture, false);
  k.emissive_tex = ref(m.emissive_texture, true);
  k.transmission_tex = ref(m.transmission_texture, false);
  compile_layers(m, k);
  k.clearcoat_tex = ref(m.clearcoat_texture, false);
  k.clearcoat_roughness_tex = ref(m.clearcoat_roughness_texture, false);
  k.sheen_color_tex = ref(m.sheen_color_texture, true);
  k.sheen_roughness_tex = ref(m.sheen_roughness_texture, false);
  if (k.emissive_tex.texture >= 0) {
    k.emission_luminance_scale = texture_mean_luminance_[size_t(m.emissive_texture.texture)];
  }
  (void)scene;
  return k;
}

void SceneCompiler::write_mesh_vertices(const Mesh& mesh, uint32_t mesh_index, KernelScene& out) {
  const KMesh& km = out.meshes[mesh_index];
  const uint32_t base = km.vertex_offset;
  for (uint32_t v = 0; v < km.vertex_count; ++v) {
    out.positions[base + v] = to_vec3(mesh.positions[v]);
    if (!out.normals.empty())
      out.normals[base + v] = mesh.normals.empty() ? Vec3{0, 0, 0} : to_vec3(mesh.normals[v]);
    if (!out.tangents.empty()) {
      const glm::vec4 t = mesh.tangents.empty() ? glm::vec4(0.0f) : mesh.tangents[v];
      out.tangents[base + v] = {t.x, t.y, t.z, t.w};
    }
    if (!out.uv0.empty())
      out.uv0[base + v] = mesh.uv0.empty() ? Vec2{0, 0} : Vec2{mesh.uv0[v].x, mesh.uv0[v].y};
    if (!out.uv1.empty())
      out.uv1[base + v] = mesh.uv1.empty() ? Vec2{0, 0} : Vec2{mesh.uv1[v].x, mesh.uv1[v].y};
  }
}

namespace {

// Whether two affine maps scale every area alike: their linear parts have the
// same Gram matrix (A^T A), up to float rounding (rotations, translations).
bool same_areas(const Mat34& a, const Mat34& b) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double ga = 0.0, gb = 0.0, scale = 0.0;
      for (int r = 0; r < 3; ++r) {
        const float* ra = &a.rows[r].x;
        const float* rb = &b.rows[r].x;
        ga += double(ra[i]) * ra[j];
        gb += double(rb[i]) * rb[j];
        scale += double(ra[i]) * ra[i] + double(ra[j]) * ra[j];
      }
      if (std::fabs(ga - gb) > 1e-5 * std::max(scale, 1e-30)) return false;
    }
  }
  return true;
}

}  // namespace

KInstance SceneCompiler::compile_instance(const Instance& inst) const {
  KInstance k{};
  k.object_to_world = to_mat34(inst.transform);
  k.world_to_object = to_mat34(glm::inverse(inst.transform));
  k.mesh = inst.mesh;
  k.handedness = glm::determinant(glm::mat3(inst.transform)) < 0.0f ? -1.0f : 1.0f;
  return k;
}

void SceneCompiler::compile_lights(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  out.lights.clear();
  std::vector<double> power;
  const SceneBounds bounds = scene.bounds();
  const float radius = std::max(bounds.radius(), 1e-3f);
  lights_radius_ = radius;

  for (const Light& l : scene.lights()) {
    KLight k{};
    const glm::vec3 intensity = l.color * l.intensity;
    k.intensity = to_vec3(intensity);
    k.position = to_vec3(l.position);
    k.direction = to_vec3(glm::normalize(l.direction));
    k.cos_inner = std::cos(l.inner_cone_angle);
    k.cos_outer = std::cos(l.outer_cone_angle);
    const float lum = luminance(k.intensity);
    switch (l.type) {
      case LightType::kPoint:
        k.type = kLightPoint;
        power.push_back(4.0 * kPi * lum);
        break;
      case LightType::kSpot:
        k.type = kLightSpot;
        power.push_back(2.0 * kPi * lum * (1.0 - 0.5 * (k.cos_inner + k.cos_outer)));
        break;
      case LightType::kDirectional:
        k.type = kLightDirectional;
        power.push_back(kPi * radius * radius * lum);
        break;
    }
    out.lights.push_back(k);
  }

  out.constants.environment_light_index = kInvalidIndex;
  const KEnvironment& env = out.constants.environment;
  const float env_lum = env.has_map
                            ? luminance(env.color) * env.map_integral /
                                  std::max(1.0f, float(env.width) * float(env.height) * 0.6366f)
                            : luminance(env.color);
  if (env_lum > 0.0f) {
    KLight k{};
    k.type = kLightEnvironment;
    out.constants.environment_light_index = uint32_t(out.lights.size());
    out.lights.push_back(k);
    // Flux of a uniform radiance L through the scene's bounding disk.
    power.push_back(kPi * kPi * radius * radius * env_lum);
  }

  // Emissive triangles, one light per (instance, triangle). Power comes from
  // the same kernel function the integrator uses for MIS.
  const KernelData kd = out.view();
  double triangle_power = 0.0;
  for (uint32_t i = 0; i < out.instances.size(); ++i) {
    const uint32_t mesh_index = out.instances[i].mesh;
    if (!mesh_emissive_[mesh_index]) continue;
    const KMesh& km = out.meshes[mesh_index];
    for (uint32_t p = 0; p < km.triangle_count; ++p) {
      const KMaterial& m = out.materials[out.triangles[km.triangle_offset + p].material];
      if (is_black(m.emission)) continue;
      const float pw = triangle_light_power(m, triangle_world_area(kd, out.instances[i], p));
      if (!(pw > 0.0f)) continue;
      KLight k{};
      k.type = kLightTriangle;
      k.instance = i;
      k.prim = p;
      out.lights.push_back(k);
      power.push_back(pw);
      triangle_power += pw;
    }
  }
  out.light_alias = build_alias_table(power);
  double total = 0.0;
  for (double p : power)
    total += p;
  out.constants.total_light_power = float(total);
  (void)triangle_power;
  delta.lights.reallocated = true;
  delta.light_alias.reallocated = true;
  delta.constants = true;
}

void SceneCompiler::compile_environment(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  const Environment& e = scene.environment();
  KEnvironment& k = out.constants.environment;
  k = {};
  k.color = to_vec3(e.color * e.intensity);
  k.rotation = e.rotation;
  out.env_texels.clear();
  out.env_marginal_cdf.clear();
  out.env_conditional_cdf.clear();
  if (!e.texels.empty() && e.width > 0 && e.height > 0) {
    k.has_map = 1;
    k.width = e.width;
    k.height = e.height;
    out.env_texels.resize(e.texels.size());
    for (size_t i = 0; i < e.texels.size(); ++i)
      out.env_texels[i] = make_vec4(to_vec3(e.texels[i]), 0.0f);
    k.map_integral =
        build_environment_cdfs(out.view(), out.env_marginal_cdf, out.env_conditional_cdf);
  }
  delta.env_texels.reallocated = delta.env_marginal_cdf.reallocated =
      delta.env_conditional_cdf.reallocated = true;
  delta.constants = true;
}

void SceneCompiler::compile_constants(const Scene& scene, const RenderSettings& s,
                                      KernelScene& out) {
  const Camera& c = scene.camera();
  KCamera& k = out.constants.camera;
  k.type = c.type == CameraType::kOrthographic ? kCameraOrthographic : kCameraPerspective;
  k.position = to_vec3(c.position);
  k.forward = normalize(to_vec3(c.forward));
  k.right = normalize(cross(k.forward, to_vec3(c.up)));
  k.up = cross(k.right, k.forward);
  k.tan_half_fov_y = std::tan(0.5f * c.yfov);
  k.aspect = float(s.width) / float(s.height);
  k.aperture_radius = c.aperture_radius;
  k.focus_distance = c.focus_distance;
  k.ortho_half_height = c.ortho_half_height;
  k.width = s.width;
  k.height = s.height;
  KIntegratorParams& ip = out.constants.integrator;
  ip.max_depth = s.max_depth;
  ip.rr_start_depth = s.rr_start_depth;
  ip.radiance_clamp = s.radiance_clamp;
  ip.seed = s.seed;
  const SceneBounds b = scene.bounds();
  out.constants.scene_center = to_vec3(b.center());
  out.constants.scene_radius = b.radius();
}

void SceneCompiler::compile_full(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  compile_textures(scene, out);

  out.materials.clear();
  for (const Material& m : scene.materials())
    out.materials.push_back(compile_material(scene, m));
  if (out.materials.empty()) out.materials.push_back(compile_material(scene, Material{}));

  // Meshes: per-vertex arrays are only allocated when some mesh has them.
  bool any_normals = false, any_tangents = false, any_uv0 = false, any_uv1 = false;
  uint32_t vertex_total = 0, triangle_total = 0;
  out.meshes.clear();
  mesh_emissive_.assign(scene.meshes().size(), false);
  for (size_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& m = scene.meshes()[i];
    KMesh km{};
    km.vertex_offset = vertex_total;
    km.vertex_count = uint32_t(m.positions.size());
    km.triangle_offset = triangle_total;
    km.triangle_count = uint32_t(m.triangles.size());
    km.flags = (m.normals.empty() ? 0u : kMeshHasNormals) |
               (m.tangents.empty() ? 0u : kMeshHasTangents) | (m.uv0.empty() ? 0u : kMeshHasUv0) |
               (m.uv1.empty() ? 0u : kMeshHasUv1);
    for (uint32_t mat : m.triangle_materials) {
      const KMaterial& k = out.materials[std::min<size_t>(mat, out.materials.size() - 1)];
      if (k.alpha_mode != kAlphaOpaque) km.flags |= kMeshHasAlphaTest;
      if (!is_black(k.emission)) km.flags |= kMeshHasEmission;
    }
    mesh_emissive_[i] = (km.flags & kMeshHasEmission) != 0;
    any_normals |= !m.normals.empty();
    any_tangents |= !m.tangents.empty();
    any_uv0 |= !m.uv0.empty();
    any_uv1 |= !m.uv1.empty();
    vertex_total += km.vertex_count;
    triangle_total += km.triangle_count;
    out.meshes.push_back(km);
  }
  // One extra position so 16-byte SIMD loads of the last vertex stay in bounds.
  out.positions.assign(vertex_total + 1, Vec3{0, 0, 0});
  out.normals.assign(any_normals ? vertex_total : 0, Vec3{0, 0, 0});
  out.tangents.assign(any_tangents ? vertex_total : 0, Vec4{0, 0, 0, 0});
  out.uv0.assign(any_uv0 ? vertex_total : 0, Vec2{0, 0});
  out.uv1.assign(any_uv1 ? vertex_total : 0, Vec2{0, 0});
  out.triangles.resize(triangle_total);
  for (size_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& m = scene.meshes()[i];
    write_mesh_vertices(m, uint32_t(i), out);
    const uint32_t toff = out.meshes[i].triangle_offset;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
      const uint32_t mat = t < m.triangle_materials.size() ? m.triangle_materials[t] : 0u;
      out.triangles[toff + t] = {m.triangles[t].x, m.triangles[t].y, m.triangles[t].z,
                                 std::min<uint32_t>(mat, uint32_t(out.materials.size() - 1))};
    }
    delta.meshes_rebuilt.push_back(uint32_t(i));
  }

  out.instances.clear();
  for (const Instance& inst : scene.instances())
    out.instances.push_back(compile_instance(inst));

  compile_environment(scene, out, delta);
  compile_lights(scene, out, delta);

  delta.full = true;
  delta.instances_changed = true;
#define TANDEM_MARK_ALL(T, name) delta.name.reallocated = true;
  TANDEM_KERNEL_ARRAYS(TANDEM_MARK_ALL)
#undef TANDEM_MARK_ALL
}

SceneDelta SceneCompiler::compile(Scene& scene, const RenderSettings& settings, KernelScene& out) {
  SceneDelta delta;
  const size_t counts[5] = {scene.textures().size(), scene.materials().size(),
                            scene.meshes().size(), scene.instances().size(), scene.lights().size()};
  bool structural = !compiled_once_ || !std::equal(counts, counts + 5, counts_);
  for (uint32_t d : scene.texture_dirty())
    structural |= d != 0;
  for (uint32_t d : scene.mesh_dirty())
    structural |= (d & (kDirtyTopology | kDirtyCreated)) != 0;

  if (structural) {
    compile_full(scene, out, delta);
  } else {
    bool lights_dirty = false;
    for (uint32_t i = 0; i < scene.materials().size(); ++i) {
      if (!scene.material_dirty()[i]) continue;
      const KMaterial before = out.materials[i];
      out.materials[i] = compile_material(scene, scene.materials()[i]);
      delta.materials.mark(i, i + 1);
      // Emission changes move light power around; alpha changes need the
      // mesh flags recomputed, which only a full build does.
      lights_dirty |= !is_black(before.emission) || material_emits(scene.materials()[i]);
      if (before.alpha_mode != out.materials[i].alpha_mode) structural = true;
    }
    for (uint32_t i = 0; i < scene.meshes().size(); ++i) {
      if (!(scene.mesh_dirty()[i] & kDirtyVertices)) continue;
      write_mesh_vertices(scene.meshes()[i], i, out);
      const KMesh& km = out.meshes[i];
      delta.positions.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
      if (!out.normals.empty())
        delta.normals.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
      if (!out.tangents.empty())
        delta.tangents.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
      if (!out.uv0.empty()) delta.uv0.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
      if (!out.uv1.empty()) delta.uv1.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
      delta.meshes_refit.push_back(i);
      delta.instances_changed = true;  // TLAS bounds change with the BLAS
      lights_dirty |= mesh_emissive_[i];
    }
    for (uint32_t i = 0; i < scene.instances().size(); ++i) {
      if (!scene.instance_dirty()[i]) continue;
      const KInstance before = out.instances[i];
      out.instances[i] = compile_instance(scene.instances()[i]);
      delta.instances.mark(i, i + 1);
      delta.instances_changed = true;
      // Triangle lights are stored as (instance, prim): moving an emissive
      // instance rigidly changes neither the light list nor any light's
      // power, so the (large) light arrays stay as they are.
      const KInstance& after = out.instances[i];
      lights_dirty |=
          (mesh_emissive_[before.mesh] || mesh_emissive_[after.mesh]) &&
          (before.mesh != after.mesh || !same_areas(before.object_to_world, after.object_to_world));
    }
    for (uint32_t d : scene.light_dirty())
      lights_dirty |= d != 0;
    if (scene.environment_dirty()) {
      compile_environment(scene, out, delta);
      lights_dirty = true;
    }
    // Directional and environment light powers scale with the scene's size,
    // which bodies moving about change a little every frame. The powers only
    // steer light selection (the alias table and total_light_power are
    // rebuilt together, so pdfs stay consistent), so they are refreshed only
    // when the size changed by more than 10%.
    if (!lights_dirty && delta.instances_changed) {
      const float radius = std::max(scene.bounds().radius(), 1e-3f);
      lights_dirty = std::fabs(radius - lights_radius_) > 0.1f * lights_radius_;
    }
    if (structural) {
      delta = SceneDelta{};
      compile_full(scene, out, delta);
    } else if (lights_dirty) {
      compile_lights(scene, out, delta);
    }
  }

  const bool settings_changed = settings != last_settings_;
  if (delta.any() || scene.camera_dirty() || settings_changed || !compiled_once_) {
    compile_constants(scene, settings, out);
    delta.constants = true;
  }
  last_settings_ = settings;
  compiled_once_ = true;
  std::copy(counts, counts + 5, counts_);
  scene.clear_dirty();
  return delta;
}

}  // namespace tandem
