// The one virtual interface of the renderer: a backend that can hold a
// compiled scene and render tiles of it. The CPU (Embree), host (our BVH on
// the CPU) and CUDA backends implement it; the tracer drives any mix of them.
#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/render/film.h"
#include "core/render/pass_stop.h"
#include "core/render/tiles.h"
#include "core/world/kernel_change_log.h"
#include "core/world/kernel_scene.h"

namespace tandem {

struct FeaturePass;    // core/kernel/features.h
struct PixelFeatures;  // core/kernel/features.h

// Samples [sample_begin, sample_begin + sample_count) of every pixel of the
// tiles a backend takes.
struct RenderPass {
  uint32_t sample_begin = 0;
  uint32_t sample_count = 1;
  // Optional, indexed by Tile::index: a backend writes the seconds each tile
  // took (for one worker), from which the tile scheduler learns which parts
  // of the frame are expensive. Backends that cannot time tiles skip it.
  double* tile_seconds = nullptr;
  // Set by the core tracer when it may compile the next frame into the host
  // KernelScene while this render runs (every backend renders from a copy
  // of its own): a backend must then not start reading the host scene
  // inside render(), not even to recover from a failure (RenderIncomplete).
  bool host_scene_may_change = false;
  // A backend with traits().syncs_while_rendering calls this once it holds
  // the scene copy the render reads (from then on a sync() for the next
  // frame cannot change what this render sees). May be empty.
  std::function<void()> scene_claimed;
};

struct BackendStats {
  double seconds = 0.0;  // wall time inside render()
  uint64_t rays = 0;     // closest-hit + shadow rays traced
  uint64_t samples = 0;  // pixel samples (camera paths) traced
  uint32_t tiles = 0;
  uint64_t pixels = 0;
  uint64_t commit_bytes = 0;  // scene data sent to a device since the last render()
  // Of the commits since the last render(): seconds the device spent copying
  // them, and how much of that ran while an earlier frame was still rendering
  // (hidden by the overlap). Zero for backends without a device copy.
  double commit_copy_seconds = 0.0;
  double commit_hidden_seconds = 0.0;

  BackendStats& operator+=(const BackendStats& o) {
    seconds += o.seconds;
    rays += o.rays;
    samples += o.samples;
    tiles += o.tiles;
    pixels += o.pixels;
    commit_bytes += o.commit_bytes;
    commit_copy_seconds += o.commit_copy_seconds;
    commit_hidden_seconds += o.commit_hidden_seconds;
    return *this;
  }
};

// Thrown by render() when a backend stopped part-way and the frame must be
// completed by the caller: the film holds exactly the sums of the tiles the
// backend finished (`finished`); `unfinished` lists tiles it took from the
// source but did not add. The backend has switched to another way of
// rendering (the CPU after a GPU failure): the caller syncs it with a full
// delta and renders `unfinished` and the source's remaining tiles on it.
class RenderIncomplete : public std::runtime_error {
 public:
  RenderIncomplete(const std::string& what, std::vector<Tile> unfinished, BackendStats finished)
      : std::runtime_error(what), unfinished_(std::move(unfinished)), finished_(finished) {}
  const std::vector<Tile>& unfinished() const { return unfinished_; }
  const BackendStats& finished() const { return finished_; }

 private:
  std::vector<Tile> unfinished_;
  BackendStats finished_;
};

// What the tracer needs to know about a backend to drive it, as one value,
// so that a wrapper (the `auto` fallback) forwards all of it in one line and
// cannot forget a new capability.
struct BackendTraits {
  // Traces Tandem's own BVH (the kernel arrays bvh_nodes etc.) rather than
  // building its own structure. The caller's SceneSync builds it when any
  // of its backends needs it (its changes are in the same delta or log as
  // the compiler's); the others never pay for the build.
  bool needs_bvh = false;
  // With needs_bvh: the layout of Tandem's BVH this backend traces fastest.
  // The core tracer uses the wide one when every backend that needs the BVH
  // prefers it (they all trace the one kd.bvh.layout names).
  KBvhLayout bvh_layout = kBvhLayoutBinary;
  // render() runs on the host's CPU cores (TBB workers). Two such backends
  // compete for the same cores, so splitting a frame between them cannot beat
  // the faster one alone; the core tracer uses this to decide.
  bool uses_host_cores = false;
  // render() reads the host KernelScene (CPU backends trace it in place). A
  // backend that works from its own copy made in sync() (the CUDA backend's
  // device buffers) lets the core tracer compile the next frame into the
  // KernelScene while this one renders: Brigade's overlap.
  bool reads_host_scene_while_rendering = true;
  // sync() may be called from another thread while render() runs, and then
  // commits into a copy that the running render does not read (the CUDA
  // backend's second device buffer set): the next frame's upload overlaps
  // this frame's render.
  bool syncs_while_rendering = false;
  bool operator==(const BackendTraits&) const = default;
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // Why a backend that started on a device renders on the CPU now (the
  // device's failure, as its warning said); empty while it runs as made.
  virtual std::string failure() const { return {}; }
  virtual BackendTraits traits() const = 0;

  // Makes the backend's copy of the scene match `scene`, given what changed.
  // `scene` must outlive the next render() calls (backends may keep
  // pointers into it).
  virtual void sync(const KernelScene& scene, const SceneDelta& delta) = 0;
  // The same with the changes taken from `log`: everything it records after
  // the generation this backend last synced from it (all of the scene the
  // first time, or after forget_synced()). How the core tracer syncs, so
  // that no caller keeps track of what each backend has seen. By default
  // one generation per backend; a backend with several copies of the scene
  // keeps one per copy (the CUDA backend's buffer sets).
  virtual void sync_from(const KernelScene& scene, const KernelChangeLog& log);
  // The next sync_from() sends the whole scene (a backend that lost its
  // copy: a device that fell back to the CPU).
  virtual void forget_synced() { synced_log_ = 0; }

  // Renders tiles pulled from `tiles` until it is empty, adding every
  // pixel's samples to `film`.
  virtual BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) = 0;

  // Primary-hit features (core/kernel/features.h) of every pixel of the
  // synced scene's camera into out[y * width + x], for the denoiser. Returns
  // false when this backend has no feature pass (the caller asks another).
  // A CPU backend asks `stop` between bands of rows and leaves the rest
  // unwritten when it says so; a device computes the image in one launch
  // and never asks.
  virtual bool render_features(const FeaturePass& /*pass*/, PixelFeatures* /*out*/,
                               const PassStop& /*stop*/) {
    return false;
  }

 private:
  // What the default sync_from() last synced: the log's id and generation.
  uint64_t synced_log_ = 0, synced_generation_ = 0;
};

inline void Backend::sync_from(const KernelScene& scene, const KernelChangeLog& log) {
  const uint64_t since = log.id() == synced_log_ ? synced_generation_ : 0;
  sync(scene, log.changes_since(since));
  synced_log_ = log.id();
  synced_generation_ = log.generation();
}

}  // namespace tandem
