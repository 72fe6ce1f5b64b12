#include "core/image/image.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "core/kernel/tone_map.h"
#include "core/util/errors.h"

namespace tandem {

ToneMap parse_tone_map(const std::string& name) {
  if (name == "standard") return ToneMap::kStandard;
  if (name == "aces") return ToneMap::kAces;
  if (name == "reinhard") return ToneMap::kReinhard;
  throw UsageError("unknown tone map '" + name + "' (expected standard, aces or reinhard)");
}

ExrPixelType parse_exr_pixel_type(const std::string& name) {
  if (name == "float") return ExrPixelType::kFloat;
  if (name == "half") return ExrPixelType::kHalf;
  throw UsageError("unknown EXR pixel type '" + name + "' (expected float or half)");
}

ExrCompression parse_exr_compression(const std::string& name) {
  static const char* const kNames[] = {"none",  "rle", "zips", "zip",  "piz",
                                       "pxr24", "b44", "b44a", "dwaa", "dwab"};
  for (size_t i = 0; i < std::size(kNames); ++i)
    if (name == kNames[i]) return ExrCompression(i);
  throw UsageError("unknown EXR compression '" + name +
                   "' (expected none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab)");
}

// The curves live in kernel code so the CUDA backend tone maps on the
// device with exactly the same arithmetic.
static_assert(uint32_t(ToneMap::kStandard) == kToneMapStandard &&
                  uint32_t(ToneMap::kAces) == kToneMapAces &&
                  uint32_t(ToneMap::kReinhard) == kToneMapReinhard,
              "ToneMap and KToneMap must agree");

std::vector<uint8_t> tone_map_to_srgb8(const ImageRGB& image, float exposure_stops, ToneMap curve) {
  std::vector<uint8_t> out(image.rgb.size());
  tone_map_to_srgb8_into(image, exposure_stops, curve, out.data());
  return out;
}

void tone_map_to_srgb8_into(const ImageRGB& image, float exposure_stops, ToneMap curve,
                            uint8_t* out) {
  const float scale = std::exp2(exposure_stops);
  // Threaded: the viewer tone maps every frame it shows, and at 1280x720
  // one core takes ~40 ms (a pow per channel), most of an input slice.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, image.rgb.size(), size_t(1) << 15),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i)
                        out[i] = tone_map_channel_srgb8(image.rgb[i], scale, uint32_t(curve));
                    });
}

double relative_mse(const ImageRGB& image, const ImageRGB& ref) {
  double sum = 0.0;
  for (size_t i = 0; i < image.rgb.size(); ++i) {
    const double d = double(image.rgb[i]) - ref.rgb[i];
    sum += d * d / (double(ref.rgb[i]) * ref.rgb[i] + 1e-2);
  }
  return image.rgb.empty() ? 0.0 : sum / double(image.rgb.size());
}

}  // namespace tandem
