// A batch of tiles and a chunk of samples: the unit of work of the CUDA
// backend's launches and of the wavefront pipelines (wavefront.h), and how a
// work item maps to its pixel sample. POD structs and TANDEM_HD functions:
// the GPU, the simulated device and the host backend share them.
#pragma once

#include <cstdint>

#include "core/kernel/defines.h"
#include "core/kernel/math.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

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
  // Every thread does this once: no 64-bit integer division, which the GPU
  // emulates in a long instruction sequence. A 32-bit division covers the
  // usual batch; beyond 2^32 items the quotient (a sample index, so it fits
  // in 32 bits) comes from a double division (exact below 2^53 up to the
  // one-off correction).
  const uint32_t n = batch.pixel_count;
  uint32_t q, p;
  if ((item >> 32) == 0) {
    q = uint32_t(item) / n;
    p = uint32_t(item) - q * n;
  } else {
    q = uint32_t(double(item) / double(n));
    int64_t r = int64_t(item) - int64_t(uint64_t(q) * n);
    if (r < 0) {
      --q;
      r += n;
    } else if (r >= int64_t(n)) {
      ++q;
      r -= n;
    }
    p = uint32_t(r);
  }
  *sample = batch.sample_begin + q;
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

TANDEM_KERNEL_END
}  // namespace tandem
