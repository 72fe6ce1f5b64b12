// The per-pixel functions of the CUDA backend's film kernels
// (film_kernels.cu), which the GPU and the simulated device's emulated grid
// both run.
// POD structs and TANDEM_HD free functions only; no CUDA headers.
#pragma once

#include <cstdint>

#include "core/kernel/defines.h"
#include "core/kernel/tile_batch.h"
#include "core/kernel/tone_map.h"
#include "core/kernel/types.h"
#include "core/kernel/wavefront.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Device-resident film for GPU-only output: per pixel a double RGB sum and
// a sample count, like the host Film.
struct DeviceFilmView {
  double* sums = nullptr;
  uint32_t* samples = nullptr;
  uint32_t width = 0, height = 0;
};

// Adds batch pixel p's sums to the device film. Pixels outside the film are
// skipped: the host checks every tile against the film before a launch, this
// keeps a bad tile from writing out of bounds all the same.
TANDEM_HD void accumulate_film_pixel(const TileBatch& batch, const double* pixel_sums,
                                     uint32_t samples, const DeviceFilmView& film, uint32_t p) {
  uint32_t x, y;
  batch_pixel(batch, p, &x, &y);
  if (x >= film.width || y >= film.height) return;
  const uint64_t i = uint64_t(y) * film.width + x;
  film.sums[3 * i] += pixel_sums[3 * p];
  film.sums[3 * i + 1] += pixel_sums[3 * p + 1];
  film.sums[3 * i + 2] += pixel_sums[3 * p + 2];
  film.samples[i] += samples;
}

// Film::resolve's arithmetic exactly: sum * (1 / samples) in double.
TANDEM_HD void film_pixel_mean(const DeviceFilmView& film, uint64_t i, float out[3]) {
  const uint32_t n = film.samples[i];
  const double inv = n ? 1.0 / double(n) : 0.0;
  for (int c = 0; c < 3; ++c)
    out[c] = float(film.sums[3 * i + c] * inv);
}

TANDEM_HD void tone_map_film_pixel(const DeviceFilmView& film, uint64_t i, float scale,
                                   uint32_t curve, uint8_t* rgb8) {
  float mean[3];
  film_pixel_mean(film, i, mean);
  for (int c = 0; c < 3; ++c)
    rgb8[3 * i + c] = tone_map_channel_srgb8(mean[c], scale, curve);
}

TANDEM_KERNEL_END
}  // namespace tandem
