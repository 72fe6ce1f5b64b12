#include "app/view/denoise_view.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace tandem {

namespace {

uint8_t to8(float v) {
  return uint8_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

float srgb_encode(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

const char* view_buffer_name(ViewBuffer b) {
  switch (b) {
    case ViewBuffer::kImage:
      return "image";
    case ViewBuffer::kAlbedo:
      return "albedo";
    case ViewBuffer::kNormal:
      return "normal";
    case ViewBuffer::kDepth:
      return "depth";
    case ViewBuffer::kMotion:
      return "motion";
    case ViewBuffer::kVariance:
      return "variance";
    case ViewBuffer::kHistory:
      return "history length";
    case ViewBuffer::kCount:
      break;
  }
  return "?";
}

std::optional<ViewBuffer> parse_view_buffer(const std::string& name) {
  for (int i = 0; i < int(ViewBuffer::kCount); ++i) {
    const std::string full = view_buffer_name(ViewBuffer(i));
    if (name == full || name == full.substr(0, full.find(' '))) return ViewBuffer(i);
  }
  return std::nullopt;
}

std::vector<uint8_t> feature_view_rgb8(ViewBuffer view, const std::vector<PixelFeatures>& features,
                                       const std::vector<Vec4>& moments, uint32_t max_history,
                                       uint32_t width, uint32_t height) {
  const size_t n = size_t(width) * height;
  std::vector<uint8_t> out(3 * n, 0);
  if (features.size() != n) return out;
  const bool have_moments = moments.size() == n;
  float far = 0.0f;
  if (view == ViewBuffer::kDepth)
    for (const PixelFeatures& f : features)
      if (features_hit(f)) far = std::max(far, f.depth);
  for (size_t i = 0; i < n; ++i) {
    const PixelFeatures& f = features[i];
    float c[3] = {0.0f, 0.0f, 0.0f};
    switch (view) {
      case ViewBuffer::kAlbedo:
        c[0] = srgb_encode(f.albedo.x), c[1] = srgb_encode(f.albedo.y),
        c[2] = srgb_encode(f.albedo.z);
        break;
      case ViewBuffer::kNormal:
        if (features_hit(f)) {
          c[0] = f.normal.x * 0.5f + 0.5f, c[1] = f.normal.y * 0.5f + 0.5f,
          c[2] = f.normal.z * 0.5f + 0.5f;
        }
        break;
      case ViewBuffer::kDepth:
        if (features_hit(f) && far > 0.0f) c[0] = c[1] = c[2] = 1.0f - 0.9f * f.depth / far;
        break;
      case ViewBuffer::kMotion:
        c[0] = 0.5f + f.motion.x / (2.0f * kMotionViewPixels);
        c[1] = 0.5f + f.motion.y / (2.0f * kMotionViewPixels);
        c[2] = 0.5f;
        break;
      case ViewBuffer::kVariance:
        if (have_moments) {
          const float s = std::sqrt(std::max(0.0f, moments[i].y - moments[i].x * moments[i].x));
          c[0] = c[1] = c[2] = srgb_encode(s / (1.0f + s));
        }
        break;
      case ViewBuffer::kHistory:
        if (have_moments) {
          const float len = moments[i].z;
          const float g = std::min(len, float(max_history)) / float(std::max(max_history, 1u));
          c[0] = c[1] = c[2] = g;
          if (len <= 1.0f) c[0] = 1.0f, c[1] = c[2] = 0.0f;
        }
        break;
      case ViewBuffer::kImage:
      case ViewBuffer::kCount:
        break;
    }
    for (int k = 0; k < 3; ++k)
      out[3 * i + k] = to8(c[k]);
  }
  return out;
}

}  // namespace tandem
