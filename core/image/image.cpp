#include "core/image/image.h"

#include <algorithm>
#include <cmath>

#include "core/kernel/texture.h"
#include "core/util/errors.h"

namespace tandem {

ToneMap parse_tone_map(const std::string& name) {
  if (name == "standard") return ToneMap::kStandard;
  if (name == "aces") return ToneMap::kAces;
  if (name == "reinhard") return ToneMap::kReinhard;
  throw UsageError("unknown tone map '" + name + "' (expected standard, aces or reinhard)");
}

namespace {

float apply_curve(float x, ToneMap curve) {
  x = std::max(x, 0.0f);
  switch (curve) {
    case ToneMap::kAces:
      // Narkowicz's rational fit of the ACES reference rendering transform,
      // with its customary 0.6 pre-scale so 1.0 maps to ~0.8.
      x *= 0.6f;
      return (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    case ToneMap::kReinhard:
      return x / (1.0f + x);
    default:
      return x;
  }
}

}  // namespace

std::vector<uint8_t> tone_map_to_srgb8(const ImageRGB& image, float exposure_stops, ToneMap curve) {
  const float scale = std::exp2(exposure_stops);
  std::vector<uint8_t> out(image.rgb.size());
  for (size_t i = 0; i < image.rgb.size(); ++i) {
    float v = image.rgb[i];
    if (!std::isfinite(v)) v = 0.0f;
    v = std::clamp(apply_curve(v * scale, curve), 0.0f, 1.0f);
    out[i] = uint8_t(std::lround(linear_to_srgb(v) * 255.0f));
  }
  return out;
}

}  // namespace tandem
