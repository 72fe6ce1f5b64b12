// Scene-model types to kernel types: the small conversions every per-kind
// compiler (compile_*.cpp) shares. Internal to core/world.
#pragma once

#include <cmath>

#include "core/kernel/types.h"
#include "core/world/scene.h"

namespace tandem {

inline Vec3 to_vec3(const glm::vec3& v) {
  return {v.x, v.y, v.z};
}

inline Mat34 to_mat34(const glm::mat4& m) {
  // glm is column-major: m[col][row].
  Mat34 r;
  r.rows[0] = {m[0][0], m[1][0], m[2][0], m[3][0]};
  r.rows[1] = {m[0][1], m[1][1], m[2][1], m[3][1]};
  r.rows[2] = {m[0][2], m[1][2], m[2][2], m[3][2]};
  return r;
}

inline uint32_t to_wrap(WrapMode w) {
  switch (w) {
    case WrapMode::kClampToEdge:
      return kWrapClamp;
    case WrapMode::kMirroredRepeat:
      return kWrapMirror;
    default:
      return kWrapRepeat;
  }
}

inline uint32_t to_alpha_mode(AlphaMode a) {
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
inline KTextureRef to_texture_ref(const TextureRef& ref, int32_t slot) {
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

inline bool material_emits(const Material& m) {
  return m.emissive_strength > 0.0f &&
         (m.emissive.x > 0.0f || m.emissive.y > 0.0f || m.emissive.z > 0.0f);
}

}  // namespace tandem
