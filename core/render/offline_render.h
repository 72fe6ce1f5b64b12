// Offline (non-interactive) rendering of a whole image with one backend:
// what `tandem render` runs for --backend cpu/host/cuda.
#pragma once

#include <functional>

#include "core/render/backend.h"

namespace tandem {

struct OfflineRenderOptions {
  uint32_t spp = 64;
  uint32_t tile_size = 32;
  // Called from a monitor thread with the completed fraction in [0, 1].
  std::function<void(double)> progress;
};

struct OfflineRenderResult {
  ImageRGB image;
  BackendStats stats;
  double seconds = 0.0;
};

// Renders `spp` samples per pixel in a few passes over all tiles. The result
// depends only on the scene, settings and seed, never on thread count.
OfflineRenderResult render_offline(Backend& backend, uint32_t width, uint32_t height,
                                   const OfflineRenderOptions& options);

}  // namespace tandem
