#include "core/render/film.h"

#include <algorithm>

namespace tandem {

void Film::resize(uint32_t width, uint32_t height) {
  width_ = width;
  height_ = height;
  sum_.assign(size_t(width) * height * 3, 0.0);
  samples_.assign(size_t(width) * height, 0u);
}

void Film::clear() {
  std::fill(sum_.begin(), sum_.end(), 0.0);
  std::fill(samples_.begin(), samples_.end(), 0u);
}

void Film::clear_rect(uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) {
  for (uint32_t y = y0; y < y1; ++y) {
    const size_t row = size_t(y) * width_;
    std::fill(sum_.begin() + std::ptrdiff_t(3 * (row + x0)),
              sum_.begin() + std::ptrdiff_t(3 * (row + x1)), 0.0);
    std::fill(samples_.begin() + std::ptrdiff_t(row + x0),
              samples_.begin() + std::ptrdiff_t(row + x1), 0u);
  }
}

ImageRGB Film::resolve() const {
  ImageRGB img(width_, height_);
  resolve_into(img.rgb.data());
  return img;
}

void Film::resolve_into(float* rgb) const {
  for (size_t i = 0; i < samples_.size(); ++i) {
    const double inv = samples_[i] ? 1.0 / double(samples_[i]) : 0.0;
    for (int c = 0; c < 3; ++c)
      rgb[3 * i + c] = float(sum_[3 * i + c] * inv);
  }
}

}  // namespace tandem
