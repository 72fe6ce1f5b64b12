// Texture lookups with bilinear filtering, glTF wrap modes and sRGB decode.
// Filtering is done in code (not by texture hardware) and the decode through
// a table (srgb_table.h) so that every backend returns bit-identical texel
// values.
#pragma once

#include "core/kernel/kernel_data.h"
#include "core/kernel/srgb_table.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// The tone map's encode stays on powf: its result is rounded to 8 bits, so a
// last-bit difference between glibc's and CUDA's powf moves a byte only for
// a value within an ulp of a rounding boundary.
TANDEM_HD float linear_to_srgb(float c) {
  return c <= 0.0031308f ? c * 12.92f : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

// The texel index i in [0, n) for wrap mode `mode`. sample_texture first
// reduces coordinates to [0, 2) texture widths, so its indices lie in
// [-1, 2n]; there one or two compares give the remainder that an integer
// division gives elsewhere (four divisions per bilinear lookup, tens of
// cycles each on the CPU and many instructions on the GPU), with the same
// result.
TANDEM_HD int wrap_coord(int i, int n, uint32_t mode) {
  if (mode == kWrapClamp) return i < 0 ? 0 : (i >= n ? n - 1 : i);
  const bool in_lookup_range = i >= -1 && i <= 2 * n;
  if (mode == kWrapMirror) {
    const int period = 2 * n;
    int m;
    if (in_lookup_range) {
      m = i < 0 ? i + period : (i == period ? 0 : i);
    } else {
      m = i % period;
      if (m < 0) m += period;
    }
    return m < n ? m : period - 1 - m;
  }
  if (in_lookup_range) {
    int m = i < 0 ? i + n : i;
    m = m >= n ? m - n : m;
    return m >= n ? m - n : m;
  }
  int m = i % n;
  return m < 0 ? m + n : m;
}

TANDEM_HD Vec4 fetch_texel(const KernelData& kd, const KTexture& tex, int x, int y) {
  const uint32_t at = tex.texel_offset + uint32_t(y) * tex.width + uint32_t(x);
  if (tex.flags & kTextureFloat) return kd.texels_f32[at];
  const uint32_t packed = kd.texels[at];
  if (tex.flags & kTextureSrgb) {
    // Alpha is linear in glTF even in sRGB images.
    return {srgb8_to_linear(packed), srgb8_to_linear(packed >> 8), srgb8_to_linear(packed >> 16),
            float(packed >> 24) * (1.0f / 255.0f)};
  }
  const float s = 1.0f / 255.0f;
  return {float(packed & 0xffu) * s, float((packed >> 8) & 0xffu) * s,
          float((packed >> 16) & 0xffu) * s, float(packed >> 24) * s};
}

// Bilinear lookup at uv (OpenGL convention: texel centres at (i + 0.5) / n,
// v = 0 at the first row of the image as glTF specifies).
TANDEM_HD Vec4 sample_texture(const KernelData& kd, uint32_t texture, const Vec2& uv) {
  const KTexture tex = kd.textures[texture];
  const int w = int(tex.width), h = int(tex.height);
  // Keep coordinates in a range where float->int is exact and cannot overflow.
  float fu = uv.x - floorf(uv.x * 0.5f) * 2.0f;
  float fv = uv.y - floorf(uv.y * 0.5f) * 2.0f;
  if (!is_finite(fu) || !is_finite(fv)) fu = fv = 0.0f;
  if (tex.wrap_s == kWrapClamp) fu = saturate(uv.x);
  if (tex.wrap_t == kWrapClamp) fv = saturate(uv.y);
  const float x = fu * float(w) - 0.5f;
  const float y = fv * float(h) - 0.5f;
  if (tex.flags & kTextureNearest) {
    const int ix = wrap_coord(int(floorf(x + 0.5f)), w, tex.wrap_s);
    const int iy = wrap_coord(int(floorf(y + 0.5f)), h, tex.wrap_t);
    return fetch_texel(kd, tex, ix, iy);
  }
  const float x0f = floorf(x), y0f = floorf(y);
  const float tx = x - x0f, ty = y - y0f;
  const int x0 = wrap_coord(int(x0f), w, tex.wrap_s), x1 = wrap_coord(int(x0f) + 1, w, tex.wrap_s);
  const int y0 = wrap_coord(int(y0f), h, tex.wrap_t), y1 = wrap_coord(int(y0f) + 1, h, tex.wrap_t);
  const Vec4 a = fetch_texel(kd, tex, x0, y0), b = fetch_texel(kd, tex, x1, y0);
  const Vec4 c = fetch_texel(kd, tex, x0, y1), d = fetch_texel(kd, tex, x1, y1);
  const float wa = (1 - tx) * (1 - ty), wb = tx * (1 - ty), wc = (1 - tx) * ty, wd = tx * ty;
  return {a.x * wa + b.x * wb + c.x * wc + d.x * wd, a.y * wa + b.y * wb + c.y * wc + d.y * wd,
          a.z * wa + b.z * wb + c.z * wc + d.z * wd, a.w * wa + b.w * wb + c.w * wc + d.w * wd};
}

TANDEM_HD Vec2 apply_texture_transform(const KTextureRef& ref, Vec2 uv) {
  return {ref.m[0] * uv.x + ref.m[1] * uv.y + ref.m[2],
          ref.m[3] * uv.x + ref.m[4] * uv.y + ref.m[5]};
}

TANDEM_KERNEL_END
}  // namespace tandem
