// Tone mapping to 8-bit sRGB as host/device code: the CUDA backend produces
// display images on the device, and the host's tone_map_to_srgb8
// (core/image/image.cpp) runs the same functions, so both give the same
// bytes, including for NaN and infinity.
#pragma once

#include "core/kernel/texture.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Same values and order as ToneMap in core/image/image.h.
enum KToneMap : uint32_t { kToneMapStandard = 0, kToneMapAces = 1, kToneMapReinhard = 2 };

TANDEM_HD float tone_map_curve(float x, uint32_t curve) {
  x = x < 0.0f ? 0.0f : x;  // std::max(x, 0.0f): NaN passes through
  if (curve == kToneMapAces) {
    // Narkowicz's rational fit of the ACES reference rendering transform,
    // with its customary 0.6 pre-scale so 1.0 maps to ~0.8.
    x *= 0.6f;
    return (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
  }
  if (curve == kToneMapReinhard) return x / (1.0f + x);
  return x;
}

// One channel: linear radiance -> exposure (scale = 2^stops) -> curve ->
// [0, 1] -> sRGB -> 8 bits. Non-finite input is black.
TANDEM_HD uint8_t tone_map_channel_srgb8(float v, float scale, uint32_t curve) {
  if (!is_finite(v)) v = 0.0f;
  v = tone_map_curve(v * scale, curve);
  v = v < 0.0f ? 0.0f : (1.0f < v ? 1.0f : v);  // std::clamp(v, 0, 1)
  return uint8_t(lroundf(linear_to_srgb(v) * 255.0f));
}

TANDEM_KERNEL_END
}  // namespace tandem
