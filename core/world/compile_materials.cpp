// Materials: glTF metallic-roughness parameters and texture references to
// KMaterial. Texture slots must exist first (compile_textures).
#include <algorithm>
#include <vector>
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

#include "core/kernel/lights.h"
#include "core/kernel/microfacet.h"

namespace tandem {

namespace {

// The KHR_materials_clearcoat and _sheen factors (their texture references
// are compiled with the others).
void compile_layers(const Material& m, KMaterial& k) {
  k.clearcoat = std::clamp(m.clearcoat, 0.0f, 1.0f);
  k.clearcoat_roughness = std::clamp(m.clearcoat_roughness, 0.0f, 1.0f);
  k.sheen_color = to_vec3(glm::clamp(m.sheen_color, glm::vec3(0.0f), glm::vec3(1.0f)));
  k.sheen_roughness = std::clamp(m.sheen_roughness, 0.0f, 1.0f);
}

}  // namespace

void SceneCompiler::compile_materials(const Scene& scene, KernelScene& out) {
  out.materials.clear();
  for (const Material& m : scene.materials())
    out.materials.push_back(compile_material(scene, m));
  // The kernels index materials unchecked: a scene without any gets one.
  if (out.materials.empty()) out.materials.push_back(compile_material(scene, Material{}));
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
    const uint64_t key = texture_key(scene, r.texture, srgb);
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
    k.emission_luminance_scale =
        texture_mean_luminance(scene, uint32_t(m.emissive_texture.texture));
  }
  return k;
}

void SceneCompiler::update_materials(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                     Needs& needs) {
  std::vector<uint32_t> dirty = scene.dirty_materials();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    const KMaterial before = out.materials[i];
    out.materials[i] = compile_material(scene, scene.materials()[i]);
    delta.materials.mark(i, i + 1);
    // Emission changes move light power around; alpha changes need the
    // mesh flags recomputed, which only a full build does.
    needs.light_list |= !is_black(before.emission) || material_emits(scene.materials()[i]);
    if (before.alpha_mode != out.materials[i].alpha_mode) needs.full = true;
  }
}

}  // namespace tandem
