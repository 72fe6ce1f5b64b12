// The feature pass (core/kernel/features.h) on the CPU: TBB over rows, one
// primary ray per pixel through the backend's Tracer.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/kernel/features.h"

namespace tandem {

template <class Tracer>
void render_features_on_cpu(const KernelData& kd, const Tracer& tracer, const FeaturePass& pass,
                            PixelFeatures* out) {
  const uint32_t width = kd.constants.camera.width, height = kd.constants.camera.height;
  tbb::parallel_for(
      tbb::blocked_range<uint32_t>(0, height, 2), [&](const tbb::blocked_range<uint32_t>& rows) {
        for (uint32_t y = rows.begin(); y != rows.end(); ++y)
          for (uint32_t x = 0; x < width; ++x)
            out[size_t(y) * width + x] = compute_pixel_features(kd, tracer, pass, x, y);
      });
}

}  // namespace tandem
