// The feature pass (core/kernel/features.h) on the CPU: TBB over rows, one
// primary ray per pixel through the backend's Tracer; with a PassStop, in
// bands of rows with the stop asked between them.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "core/kernel/features.h"
#include "core/render/pass_stop.h"

namespace tandem {

// Bands of the pass between which the stop is asked: a 1280x720 image of
// a textured model takes ~40 ms on two cores, so a band is ~5 ms of it.
inline constexpr uint32_t kFeatureBands = 8;

template <class Tracer>
void render_features_on_cpu(const KernelData& kd, const Tracer& tracer, const FeaturePass& pass,
                            PixelFeatures* out, const PassStop& stop) {
  const uint32_t width = kd.constants.camera.width, height = kd.constants.camera.height;
  const uint32_t band = stop ? std::max((height + kFeatureBands - 1) / kFeatureBands, 8u) : height;
  for (uint32_t y0 = 0; y0 < height; y0 += band) {
    if (y0 > 0 && pass_should_stop(stop)) return;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(y0, std::min(y0 + band, height), 2),
                      [&](const tbb::blocked_range<uint32_t>& rows) {
                        for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                          for (uint32_t x = 0; x < width; ++x)
                            out[size_t(y) * width + x] =
                                compute_pixel_features(kd, tracer, pass, x, y);
                      });
  }
}

}  // namespace tandem
