// How a denoised image and the accumulated one are combined while samples
// accumulate (the viewer and the embedding API share it): the filter's
// input is each frame's own samples, and the accumulated image takes over
// log-linearly as it converges.
#pragma once

#include <cstdint>

#include "core/image/image.h"

namespace tandem {

constexpr uint32_t kDenoiseBlendStartSpp = 8;
constexpr uint32_t kDenoiseBlendEndSpp = 64;
// Weight of the accumulated image against the filtered one at `spp`
// accumulated samples: 0 up to the start, 1 from the end, log-linear between
// (each doubling of the samples moves it by the same step).
float accumulated_blend_weight(uint32_t spp);

// This frame's own samples from the accumulated means before and after it:
// (now * spp_now - before * spp_before) / (spp_now - spp_before). With
// spp_before == 0 (a restart) it is `now`.
ImageRGB frame_samples(const ImageRGB& now, uint32_t spp_now, const ImageRGB& before,
                       uint32_t spp_before);

// a * (1 - t) + b * t per channel (same sizes).
ImageRGB blend_images(const ImageRGB& a, const ImageRGB& b, float t);

}  // namespace tandem
