// The core tracer: Brigade's frame loop over any set of backends.
//
//   SyncScene      SceneSync compiles the scene's dirty objects into kernel
//   UpdateAccStruc array ranges and rebuilds/refits BLAS and the TLAS (only
//                  when some backend traverses Tandem's own BVH): a new
//                  generation of the kernel arrays
//   SyncAccStruc   every backend commits what changed since the generation
//                  it last committed (Backend::sync_from; the CUDA backend
//                  uploads only the changed ranges, asynchronously)
//   Render         all backends render concurrently, each pulling tiles of
//                  the frame from the TileScheduler
//   Combine        tiles land in one Film; pixels may change owner from one
//                  frame to the next because the Film holds sums, not means
//   Present        the caller's: image() / film()
//
// Accumulation is progressive: every frame adds samples_per_frame samples
// per pixel with consecutive sample indices, and any scene change or
// settings change starts over.
#pragma once

#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/render/backend.h"
#include "core/world/kernel_scene.h"
#include "core/world/motion_history.h"
#include "core/world/scene.h"
#include "sync/scene_sync.h"
#include "tracer/tile_scheduler.h"

namespace tandem {

struct TracerSettings {
  RenderSettings render;  // resolution, depth, seed, clamp
  uint32_t samples_per_frame = 1;
  uint32_t tile_size = 32;
  SchedulerSettings scheduler;
  // Backends that run on the host's CPU cores (cpu, host) compete for them:
  // splitting a frame between two of them cannot beat the faster one alone.
  // When set (and no --split is forced), the tracer times each of them alone
  // for a frame, then lets only the fastest render, and re-checks now and
  // then. GPU backends are unaffected.
  bool exclusive_host_cores = true;
};

struct BackendFrameMetrics {
  std::string name;
  uint32_t tiles = 0;
  uint32_t stolen = 0;         // tiles taken from another backend's share
  bool enabled = true;         // false: left out to keep the CPU cores for a faster backend
  double planned_share = 0.0;  // of the frame's estimated cost
  double seconds = 0.0;        // inside render()
  double idle_seconds = 0.0;   // waiting for the slowest backend
  uint64_t rays = 0, samples = 0;
  uint64_t commit_bytes = 0;  // scene data this backend sent to its device
  // Device time of those copies, and how much of it ran while the previous
  // frame was still rendering (hidden by the overlap).
  double commit_copy_seconds = 0.0, commit_hidden_seconds = 0.0;
  bool completed_after_failure = false;  // the device failed; the CPU finished its tiles
  std::string failure;                   // Backend::failure(): why it runs on the CPU now
  double mrays_per_second() const { return seconds > 0.0 ? double(rays) / seconds * 1e-6 : 0.0; }
};

struct FrameMetrics {
  uint64_t frame = 0;
  uint32_t accumulated_spp = 0;  // after this frame
  bool accumulation_reset = false;
  // SyncScene/UpdateAccStruc ran during the previous frame's render.
  bool overlapped_prepare = false;
  // SyncAccStruc too: the delta went to the device backends during the
  // previous frame's render (only edits made after that were sent now).
  bool overlapped_commit = false;
  double sync_scene_seconds = 0.0, update_accstruc_seconds = 0.0, sync_accstruc_seconds = 0.0;
  double render_seconds = 0.0, total_seconds = 0.0;
  uint64_t delta_bytes = 0;  // size of the frame's changed kernel-array ranges
  // cancel_frame() stopped it: its samples were dropped (accumulation
  // restarts next frame) and the scheduler learnt nothing from it.
  bool cancelled = false;
  std::vector<BackendFrameMetrics> backends;
  uint64_t rays() const;
  uint64_t samples() const;
};

class CoreTracer {
 public:
  CoreTracer(std::vector<std::unique_ptr<Backend>> backends, TracerSettings settings = {});
  ~CoreTracer();
  CoreTracer(const CoreTracer&) = delete;
  CoreTracer& operator=(const CoreTracer&) = delete;

  // Runs one frame of the loop on `scene` (whose dirty flags it consumes):
  // begin_frame() then end_frame().
  const FrameMetrics& render_frame(Scene& scene);
  // The same in two halves. begin_frame() runs SyncScene, UpdateAccStruc and
  // SyncAccStruc and starts every backend rendering on its own thread;
  // the renderers read only the compiled KernelScene, so between the two
  // calls the caller may advance the Scene to the next frame (simulation,
  // animation, input) while this one renders. end_frame() waits for the
  // backends, combines and updates the split. Film and image are only valid
  // after end_frame().
  void begin_frame(Scene& scene);
  const FrameMetrics& end_frame();
  // Between begin_frame() and end_frame(): waits up to `seconds` for every
  // backend to finish rendering; true once they have (end_frame() then
  // returns without waiting). A caller that must stay responsive (the
  // viewer reading input) waits in slices.
  bool wait_rendered(double seconds);
  // Between begin_frame() and end_frame().
  bool frame_in_flight() const { return in_flight_; }
  // Between begin_frame() and end_frame(): no backend takes another tile,
  // so end_frame() returns once the tiles in flight are done (one tile's
  // time). The frame's samples are dropped: accumulation restarts with
  // the next frame, which is what a camera move or a quit wants anyway.
  void cancel_frame();
  // SyncScene, UpdateAccStruc and SyncAccStruc alone, outside a frame: the
  // set-up the first begin_frame() would otherwise do (BVH builds, the
  // environment's sampling tables), for a caller that wants it done before
  // its render loop (`tandem render` runs it while a signal still ends the
  // process at once). Not while a frame is in flight or prepared ahead.
  void sync_scene(Scene& scene);
  // Between begin_frame() and end_frame(): runs the next frame's SyncScene
  // and UpdateAccStruc now, while this frame renders, when no backend reads
  // the host KernelScene during render() (GPU-only rendering), and
  // SyncAccStruc for the backends that can commit during a render (the CUDA
  // backend uploads into its other buffer set). Returns false (and does
  // nothing) otherwise; the next begin_frame() then does it. Scene edits
  // made after this call still reach the next frame.
  bool prepare_next_frame(Scene& scene);
  // The whole loop for callers whose scene moves from frame to frame (the
  // viewer, `bench --frames`, `render --frames`): begin_frame(scene), then
  // `advance_to_next(scene)` poses the Scene for the next frame while this
  // one renders, prepare_next_frame(scene), end_frame(). An empty
  // `advance_to_next` (no next frame) makes it render_frame(scene).
  const FrameMetrics& render_frame(Scene& scene,
                                   const std::function<void(Scene&)>& advance_to_next);

  // Changing anything that alters the image restarts accumulation; a new
  // resolution or tile size also restarts the scheduler's estimates. While a
  // frame is in flight the change applies from the next begin_frame().
  void set_settings(const TracerSettings& settings);
  const TracerSettings& settings() const {
    return pending_settings_ ? *pending_settings_ : settings_;
  }
  void reset_accumulation() { reset_pending_ = true; }

  uint32_t accumulated_spp() const { return accumulated_spp_; }
  const Film& film() const { return film_; }
  ImageRGB image() const { return film_.resolve(); }

  size_t backend_count() const { return backends_.size(); }
  // Backend i in the order they were given, for what is particular to one
  // (a CUDA backend's device image); never while a frame is in flight.
  Backend& backend(size_t i) { return *backends_.at(i); }
  // Primary-hit features (core/kernel/features.h) of the last frame's
  // scene, from the first backend with a feature pass, with motion measured
  // from the frame of motion's previous advance(). Call after end_frame()
  // and before the next prepare_next_frame()/begin_frame(). Returns false
  // when no backend has a feature pass (a GPU-only list). A CPU pass asks
  // `stop` between bands of rows (core/render/pass_stop.h): when it says
  // stop, `out` is left incomplete and `motion` has advanced all the same.
  bool render_features(MotionHistory& motion, std::vector<PixelFeatures>& out,
                       const PassStop& stop = {});
  // Which backend rendered each tile of the last frame (index into
  // backends; -1: none), for the split overlay.
  const std::vector<Tile>& tiles() const { return scheduler_.tiles(); }
  const std::vector<int32_t>& tile_owners() const { return scheduler_.owners(); }

 private:
  void apply_settings(const TracerSettings& settings);
  void refresh_traits();
  // SyncScene and UpdateAccStruc for the next frame under `settings`.
  const SceneSyncUpdate& update_scene(Scene& scene, const RenderSettings& settings);
  // SyncAccStruc of backend b: what changed since the generation it has.
  void sync_backend(size_t b);
  // Backend b has lost its copy of the scene: it gets all of it.
  void resync_backend(size_t b);
  void choose_host_core_backends();
  void complete_incomplete_renders();
  void record_host_core_probe();
  void launch_render();

  // State of the frame between begin_frame() and end_frame().
  struct Flight {
    RenderPass pass;
    std::vector<TileSource*> sources;
    // Backends that sync during render() wait to be told that this render
    // holds its scene copy before the next frame is committed to them.
    std::mutex claim_mutex;
    std::condition_variable claim_cv;
    std::vector<bool> claimed;
    std::vector<double> tile_seconds;
    std::vector<BackendStats> stats;
    std::vector<std::exception_ptr> errors;
    std::vector<std::thread> threads;
    std::chrono::steady_clock::time_point start;
    // Backends done rendering (wait_rendered()); cancel_frame() stops the
    // tile sources through `cancelled`.
    std::mutex done_mutex;
    std::condition_variable done_cv;
    size_t done = 0;
    std::atomic<bool> cancelled{false};
    std::vector<std::unique_ptr<CancellableTiles>> cancellable;
  };

  std::vector<std::unique_ptr<Backend>> backends_;
  std::vector<BackendTraits> traits_;  // as of the last begin_frame()
  // Whether some backend of traits_ traces Tandem's BVH.
  bool bvh_needed() const;
  // The BVH layout for traits_: wide when every backend that traces the BVH
  // prefers it, else binary.
  KBvhLayout bvh_layout() const;
  TracerSettings settings_;
  // The kernel arrays; with Tandem's BVH when some backend traces it.
  std::unique_ptr<SceneSync> scene_sync_;
  // The generation the last frame rendered (its changes reset accumulation).
  uint64_t frame_generation_ = 0;
  TileScheduler scheduler_;
  Film film_;
  FrameMetrics metrics_;
  // Among backends that use the host's cores: which one is being timed
  // alone (probe_ < its count), and the samples/s each achieved alone.
  std::vector<size_t> host_core_backends_;
  size_t probe_ = 0;
  std::vector<double> probe_rate_;
  uint64_t frames_since_probe_ = 0;
  // prepare_next_frame() updated the scene for the next frame, and
  // committed it to some backend.
  bool prepared_ = false, committed_ahead_ = false;
  double prepared_sync_seconds_ = 0.0, prepared_accstruc_seconds_ = 0.0;
  double prepared_commit_seconds_ = 0.0;
  Flight flight_;
  bool in_flight_ = false;
  std::optional<TracerSettings> pending_settings_;
  std::chrono::steady_clock::time_point frame_start_;
  uint64_t frame_ = 0;
  uint32_t accumulated_spp_ = 0;
  bool reset_pending_ = true;
  bool grid_stale_ = true;
};

}  // namespace tandem
