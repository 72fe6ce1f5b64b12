#include "core/render/denoise_blend.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace tandem {

float accumulated_blend_weight(uint32_t spp) {
  if (spp <= kDenoiseBlendStartSpp) return 0.0f;
  if (spp >= kDenoiseBlendEndSpp) return 1.0f;
  return float(std::log2(double(spp) / kDenoiseBlendStartSpp) /
               std::log2(double(kDenoiseBlendEndSpp) / kDenoiseBlendStartSpp));
}

ImageRGB frame_samples(const ImageRGB& now, uint32_t spp_now, const ImageRGB& before,
                       uint32_t spp_before) {
  if (spp_before == 0 || spp_before >= spp_now || before.width != now.width ||
      before.height != now.height) {
    return now;
  }
  ImageRGB out(now.width, now.height);
  const float a = float(spp_now), b = float(spp_before), inv = 1.0f / (a - b);
  for (size_t i = 0; i < out.rgb.size(); ++i)
    out.rgb[i] = std::max(0.0f, (now.rgb[i] * a - before.rgb[i] * b) * inv);
  return out;
}

ImageRGB blend_images(const ImageRGB& a, const ImageRGB& b, float t) {
  if (a.width != b.width || a.height != b.height)
    throw std::invalid_argument("blend_images: images of different sizes");
  ImageRGB out(a.width, a.height);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, out.rgb.size(), size_t(1) << 16),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i)
                        out.rgb[i] = a.rgb[i] + (b.rgb[i] - a.rgb[i]) * t;
                    });
  return out;
}

}  // namespace tandem
