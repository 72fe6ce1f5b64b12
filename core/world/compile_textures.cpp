// Textures: texels once per image, one KTexture per (image, colour space)
// a material uses. Only a full build compiles them (a changed texture
// moves every later texel offset).
#include <algorithm>

#include "core/kernel/lights.h"
#include "core/kernel/texture.h"
#include "core/util/huge_pages.h"
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

namespace tandem {

float SceneCompiler::texture_mean_luminance(const Scene& scene, uint32_t texture) {
  if (texture >= texture_mean_luminance_.size() || texture >= scene.textures().size()) return 0.0f;
  float& mean = texture_mean_luminance_[texture];
  if (mean < 0.0f) {
    const Texture& t = scene.textures()[texture];
    double sum = 0.0;
    const bool srgb = t.decodes_srgb(true);  // as an emission texture reads it
    for (uint32_t px : t.rgba8) {
      const float s = 1.0f / 255.0f;
      const Vec3 c =
          srgb ? Vec3{srgb8_to_linear(px), srgb8_to_linear(px >> 8), srgb8_to_linear(px >> 16)}
               : Vec3{float(px & 0xffu) * s, float((px >> 8) & 0xffu) * s,
                      float((px >> 16) & 0xffu) * s};
      sum += luminance(c);
    }
    for (const glm::vec4& px : t.rgba32f)
      sum += luminance(Vec3{px.x, px.y, px.z});
    mean = t.texel_count() == 0 ? 0.0f : float(sum / double(t.texel_count()));
  }
  return mean;
}

uint64_t SceneCompiler::texture_key(const Scene& scene, int32_t texture, bool slot_srgb) {
  const bool srgb = texture >= 0 && size_t(texture) < scene.textures().size() &&
                    scene.textures()[size_t(texture)].decodes_srgb(slot_srgb);
  return (uint64_t(std::max(texture, 0)) << 1) | (srgb ? 1u : 0u);
}

void SceneCompiler::compile_textures(const Scene& scene, KernelScene& out) {
  // Texels are stored once per image; KTexture entries are created per
  // (image, colour space) usage because sRGB decoding depends on the slot.
  out.texels.clear();
  out.texels_f32.clear();
  out.textures.clear();
  texture_slots_.clear();
  texture_texel_offset_.assign(scene.textures().size(), 0);
  texture_mean_luminance_.assign(scene.textures().size(), -1.0f);
  size_t texel_count = 0, float_texel_count = 0;
  for (const Texture& t : scene.textures()) {
    texel_count += t.rgba8.size();
    float_texel_count += t.rgba32f.size();
  }
  out.texels_f32.reserve(float_texel_count);
  // Reserved and advised before the first write, so that the pages are
  // huge from the start (texture lookups land at random all over the
  // array).
  out.texels.reserve(texel_count);
  advise_huge_pages(out.texels.data(), texel_count * sizeof(uint32_t));
  for (size_t i = 0; i < scene.textures().size(); ++i) {
    const Texture& t = scene.textures()[i];
    if (!t.rgba32f.empty()) {
      texture_texel_offset_[i] = uint32_t(out.texels_f32.size());
      for (const glm::vec4& px : t.rgba32f)
        out.texels_f32.push_back(make_vec4(px.x, px.y, px.z, px.w));
      continue;
    }
    texture_texel_offset_[i] = uint32_t(out.texels.size());
    out.texels.insert(out.texels.end(), t.rgba8.begin(), t.rgba8.end());
  }
  auto slot_for = [&](int32_t tex, bool slot_srgb) {
    if (tex < 0 || size_t(tex) >= scene.textures().size()) return;
    const uint64_t key = texture_key(scene, tex, slot_srgb);
    if (texture_slots_.count(key)) return;
    const Texture& t = scene.textures()[size_t(tex)];
    if (t.width == 0 || t.height == 0 || t.texel_count() != size_t(t.width) * t.height) return;
    KTexture kt{};
    kt.width = t.width;
    kt.height = t.height;
    kt.texel_offset = texture_texel_offset_[size_t(tex)];
    kt.flags = ((key & 1u) ? kTextureSrgb : 0u) | (t.nearest ? kTextureNearest : 0u) |
               (t.rgba32f.empty() ? 0u : kTextureFloat);
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

}  // namespace tandem
