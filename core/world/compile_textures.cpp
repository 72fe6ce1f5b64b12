// Textures: texels once per image, one KTexture per (image, colour space)
// a material uses. Only a full build compiles them (a changed texture
// moves every later texel offset).
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
    for (uint32_t px : t.rgba8) {
      const Vec3 c = {srgb8_to_linear(px), srgb8_to_linear(px >> 8), srgb8_to_linear(px >> 16)};
      sum += luminance(c);
    }
    mean = t.rgba8.empty() ? 0.0f : float(sum / double(t.rgba8.size()));
  }
  return mean;
}

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
  texture_mean_luminance_.assign(scene.textures().size(), -1.0f);
  size_t texel_count = 0;
  for (const Texture& t : scene.textures())
    texel_count += t.rgba8.size();
  // Reserved and advised before the first write, so that the pages are
  // huge from the start (texture lookups land at random all over the
  // array).
  out.texels.reserve(texel_count);
  advise_huge_pages(out.texels.data(), texel_count * sizeof(uint32_t));
  for (size_t i = 0; i < scene.textures().size(); ++i) {
    const Texture& t = scene.textures()[i];
    texture_texel_offset_[i] = uint32_t(out.texels.size());
    out.texels.insert(out.texels.end(), t.rgba8.begin(), t.rgba8.end());
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

}  // namespace tandem
