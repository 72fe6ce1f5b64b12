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
  // Optional, indexed by Tile::index: a backend writes the seconds each tile
  // took (for one worker), from which the tile scheduler learns which parts
  // of the frame are expensive. Backends that cannot time tiles skip it.
  double* tile_seconds = nullptr;
};

struct BackendStats {
  double seconds = 0.0;  // wall time inside render()
  uint64_t rays = 0;     // closest-hit + shadow rays traced
  uint64_t samples = 0;  // pixel samples (camera paths) traced
  uint32_t tiles = 0;
  uint64_t pixels = 0;
  uint64_t commit_bytes = 0;  // scene data sent to a device since the last render()

  BackendStats& operator+=(const BackendStats& o) {
    seconds += o.seconds;
    rays += o.rays;
    samples += o.samples;
    tiles += o.tiles;
    pixels += o.pixels;
    commit_bytes += o.commit_bytes;
    return *this;
  }
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;

  // Whether the backend traces Tandem's own BVH (the kernel arrays bvh_nodes
  // etc.) rather than building its own structure. The caller runs
  // AccelStructure::update_and_mark() on the KernelScene before sync() when
  // any of its backends needs it; the others never pay for the build.
  virtual bool needs_bvh() const { return false; }

  // Whether render() runs on the host's CPU cores (TBB workers). Two such
  // backends compete for the same cores, so splitting a frame between them
  // cannot beat the faster one alone; the core tracer uses this to decide.
  virtual bool uses_host_cores() const { return false; }

  // Whether render() reads the host KernelScene (CPU backends trace it in
  // place). A backend that works from its own copy made in sync() (the CUDA
  // backend's device buffers) lets the core tracer compile the next frame
  // into the KernelScene while this one renders: Brigade's overlap.
  virtual bool reads_host_scene_while_rendering() const { return true; }

  // Makes the backend's copy of the scene match `scene`, given what changed.
  // `scene` must outlive the next render() calls (backends may keep
  // pointers into it).
  virtual void sync(const KernelScene& scene, const SceneDelta& delta) = 0;

  // Renders tiles pulled from `tiles` until it is empty, adding every
  // pixel's samples to `film`.
  virtual BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) = 0;
};

}  // namespace tandem
