// Accumulation buffer shared by all backends. Each pixel holds the sum of
// its samples in double precision and the number of samples, so progressive
// accumulation stays exact when pixels change owner between frames.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/kernel/math.h"

namespace tandem {

class Film {
 public:
  Film() = default;
  Film(uint32_t width, uint32_t height) { resize(width, height); }
  void resize(uint32_t width, uint32_t height);
  void clear();

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

  // Adds `samples` samples whose radiance sums to `sum` to pixel (x, y).
  // Different threads may add to different pixels concurrently.
  void add(uint32_t x, uint32_t y, const double sum[3], uint32_t samples) {
    const size_t i = size_t(y) * width_ + x;
    sum_[3 * i + 0] += sum[0];
    sum_[3 * i + 1] += sum[1];
    sum_[3 * i + 2] += sum[2];
    samples_[i] += samples;
  }
  uint32_t samples(uint32_t x, uint32_t y) const { return samples_[size_t(y) * width_ + x]; }
  // The sum of pixel (x, y)'s samples (3 doubles), for code that moves a
  // film's sums elsewhere (a distributed worker sends them to rank 0).
  const double* sum(uint32_t x, uint32_t y) const { return &sum_[3 * (size_t(y) * width_ + x)]; }
  // Zeroes the pixels of [x0, x1) x [y0, y1).
  void clear_rect(uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1);

  // Per-pixel mean radiance (black where no sample landed yet).
  ImageRGB resolve() const;
  // The same into `rgb` (width() * height() * 3 floats), without allocating.
  void resolve_into(float* rgb) const;

 private:
  uint32_t width_ = 0, height_ = 0;
  std::vector<double> sum_;
  std::vector<uint32_t> samples_;
};

}  // namespace tandem
