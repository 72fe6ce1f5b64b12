// What one kernel launch of the CUDA backend works on, and the per-item
// bodies of its small kernels, written once: the .cu kernels call them on the
// GPU and the simulated device (sim_device.cpp) calls them on the CPU, so a
// CI run of the backend's pipeline computes exactly what the GPU computes.
// POD structs and TANDEM_HD free functions only; no CUDA headers.
#pragma once

#include <cstdint>

#include "core/kernel/defines.h"
#include "core/kernel/tone_map.h"
#include "core/kernel/types.h"

namespace tandem {

// A tile of a batch; pixel_offset is the sum of pixel counts of the tiles
// before it, so pixel i of the batch lives in the tile whose range holds i.
struct DeviceTile {
  uint32_t x0, y0, x1, y1;
  uint32_t pixel_offset;
};
static_assert(sizeof(DeviceTile) == 20, "GPU layout: copied byte for byte");

// A batch of tiles and a chunk of samples: work item i is sample
// sample_begin + i / pixel_count of batch pixel i % pixel_count, so
// neighbouring threads trace neighbouring pixels (coherent camera rays).
struct TileBatch {
  const DeviceTile* tiles = nullptr;  // device
  uint32_t tile_count = 0;
  uint32_t pixel_count = 0;
  uint32_t sample_begin = 0;
  uint32_t sample_count = 0;
  TANDEM_HD uint64_t items() const { return uint64_t(pixel_count) * sample_count; }
};

// Device-resident film for GPU-only output: per pixel a double RGB sum and
// a sample count, like the host Film.
struct DeviceFilmView {
  double* sums = nullptr;
  uint32_t* samples = nullptr;
  uint32_t width = 0, height = 0;
};

// Device scratch of the wavefront variant, owned by the backend (allocated
// through its device so that allocation failures are handled like any other).
struct WavefrontScratch {
  Ray* rays = nullptr;
  uint32_t* alpha_keys = nullptr;
  Hit* hits = nullptr;
  uint32_t* queues = nullptr;    // hit queue at [0, n), miss queue at [n, 2n)
  uint32_t* counters = nullptr;  // work counter, hit count, miss count, spare
  uint64_t capacity = 0;         // items
};

// Pixel (x, y) of batch pixel p: binary search for the tile holding p.
TANDEM_HD void batch_pixel(const TileBatch& batch, uint32_t p, uint32_t* x, uint32_t* y) {
  uint32_t lo = 0, hi = batch.tile_count - 1;
  while (lo < hi) {
    const uint32_t mid = (lo + hi + 1) / 2;
    if (batch.tiles[mid].pixel_offset <= p)
      lo = mid;
    else
      hi = mid - 1;
  }
  const DeviceTile t = batch.tiles[lo];
  const uint32_t local = p - t.pixel_offset;
  const uint32_t w = t.x1 - t.x0;
  *x = t.x0 + local % w;
  *y = t.y0 + local / w;
}

// Work item -> (x, y, sample); see TileBatch.
TANDEM_HD void batch_item(const TileBatch& batch, uint64_t item, uint32_t* x, uint32_t* y,
                          uint32_t* sample) {
  const uint32_t p = uint32_t(item % batch.pixel_count);
  *sample = batch.sample_begin + uint32_t(item / batch.pixel_count);
  batch_pixel(batch, p, x, y);
}

// Adds the chunk's samples of batch pixel p to its sums in sample order and
// double precision: what the CPU tile loop does, so equal samples give equal
// pixels.
TANDEM_HD void reduce_pixel_samples(const TileBatch& batch, const Vec3* radiance, uint32_t p,
                                    double* pixel_sums) {
  double r = pixel_sums[3 * p], g = pixel_sums[3 * p + 1], b = pixel_sums[3 * p + 2];
  for (uint32_t s = 0; s < batch.sample_count; ++s) {
    const Vec3 l = radiance[uint64_t(s) * batch.pixel_count + p];
    r += double(l.x);
    g += double(l.y);
    b += double(l.z);
  }
  pixel_sums[3 * p] = r;
  pixel_sums[3 * p + 1] = g;
  pixel_sums[3 * p + 2] = b;
}

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

}  // namespace tandem
