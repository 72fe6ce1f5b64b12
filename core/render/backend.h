// The one virtual interface of the renderer: a backend that can hold a
// compiled scene and render tiles of it. The CPU (Embree), host (our BVH on
// the CPU) and CUDA backends implement it; the tracer drives any mix of them.
#pragma once

#include <cstdint>
#include <string>

#include "core/render/film.h"
#include "core/render/tiles.h"
#include "core/scene/kernel_scene.h"

namespace tandem {

// Samples [sample_begin, sample_begin + sample_count) of every pixel of the
// tiles a backend takes.
struct RenderPass {
  uint32_t sample_begin = 0;
  uint32_t sample_count = 1;
};

struct BackendStats {
  double seconds = 0.0;  // wall time inside render()
  uint64_t rays = 0;     // closest-hit + shadow rays traced
  uint64_t samples = 0;  // pixel samples (camera paths) traced
  uint32_t tiles = 0;
  uint64_t pixels = 0;

  BackendStats& operator+=(const BackendStats& o) {
    seconds += o.seconds;
    rays += o.rays;
    samples += o.samples;
    tiles += o.tiles;
    pixels += o.pixels;
    return *this;
  }
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;

  // Makes the backend's copy of the scene match `scene`, given what changed.
  // `scene` must outlive the next render() calls (backends may keep
  // pointers into it).
  virtual void sync(const KernelScene& scene, const SceneDelta& delta) = 0;

  // Renders tiles pulled from `tiles` until it is empty, adding every
  // pixel's samples to `film`.
  virtual BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) = 0;
};

}  // namespace tandem
