#include "backends/backend_factory.h"

#include <atomic>
#include <mutex>

#include "backends/cpu/cpu_backend.h"
#include "backends/cuda/cuda_backend.h"
#include "core/util/errors.h"
#include "core/util/log.h"

namespace tandem {

namespace {

// `--backend auto` (and `cuda` in a list) promises an image whatever the
// GPU does: a device failure in sync() or render() (out of memory, a launch
// failure, an illegal address, a lost device) logs one warning and hands the
// scene to the CPU backend, which has not seen any of it, so it gets a full
// sync. A render that failed part-way is completed on the CPU: the film
// holds only batches the device finished, and the CPU renders the tiles the
// device took but did not finish, then the rest of the frame.
//
// Two threads may be inside: the core tracer syncs the next frame while
// this one renders (the device backend allows it). The wrapped backend is
// therefore only replaced while no render() runs on it, and the CPU never
// reads the host scene during a render the tracer overlaps with compiling
// (pass.host_scene_may_change): then the tracer completes the frame.
class CpuFallbackBackend final : public Backend {
 public:
  explicit CpuFallbackBackend(std::unique_ptr<Backend> device) : active_(std::move(device)) {}
  std::string name() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return active_->name();
  }
  BackendTraits traits() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return active_->traits();
  }
  std::string failure() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return failure_;
  }

  void sync(const KernelScene& scene, const SceneDelta& delta) override {
    sync_active(scene, nullptr, [&](Backend& b) { b.sync(scene, delta); });
  }
  // Forwarded whole: the device backend keeps a generation per buffer set.
  void sync_from(const KernelScene& scene, const KernelChangeLog& log) override {
    sync_active(scene, &log, [&](Backend& b) { b.sync_from(scene, log); });
  }
  void forget_synced() override {
    std::lock_guard<std::mutex> lock(mutex_);
    active_->forget_synced();
  }

  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override {
    Backend* backend;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      rendering_ = true;
      backend = active_.get();
    }
    struct Done {
      CpuFallbackBackend* self;
      ~Done() {
        std::lock_guard<std::mutex> lock(self->mutex_);
        self->rendering_ = false;
      }
    } done{this};
    if (fell_back_) return backend->render(pass, tiles, film);
    std::vector<Tile> unfinished;
    BackendStats finished;
    std::string failure;
    try {
      return backend->render(pass, tiles, film);
    } catch (const DeviceRenderError& e) {
      unfinished = e.unfinished();
      finished = e.finished();
      failure = e.what();
    } catch (const DeviceError& e) {
      failure = e.what();
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      fall_back_locked(failure);
      if (pass.host_scene_may_change) {
        throw RenderIncomplete("the GPU failed while rendering: " + failure, std::move(unfinished),
                               finished);
      }
      sync_whole_locked(*scene_);
      backend = active_.get();
    }
    ResumedTiles resumed(std::move(unfinished), tiles);
    BackendStats stats = backend->render(pass, resumed, film);
    stats += finished;
    return stats;
  }

  // A device that fails in the feature pass falls back like one that fails
  // in render(): the CPU backend gets the whole scene and computes the
  // features, so the denoiser never sees a device error.
  bool render_features(const FeaturePass& pass, PixelFeatures* out, const PassStop& stop) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!fell_back_) {
      try {
        return active_->render_features(pass, out, stop);
      } catch (const DeviceError& e) {
        fall_back_and_sync_locked(e.what(), *scene_);
      }
    }
    return active_->render_features(pass, out, stop);
  }

 private:
  // One sync of the active backend: a device failure falls back to the CPU
  // (at once, or after the render in flight, which still uses the device).
  template <class Sync>
  void sync_active(const KernelScene& scene, const KernelChangeLog* log, Sync&& sync) {
    Backend* backend;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      scene_ = &scene;
      log_ = log;
      if (!deferred_failure_.empty() && !rendering_) {
        // A sync that failed while the previous frame rendered.
        fall_back_and_sync_locked(deferred_failure_, scene);
        return;
      }
      backend = active_.get();
    }
    try {
      sync(*backend);
    } catch (const DeviceError& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (rendering_) {
        deferred_failure_ = e.what();  // the render in flight still uses the device backend
        return;
      }
      fall_back_and_sync_locked(e.what(), scene);
    }
  }

  // The whole scene to the active backend, through the caller's log when it
  // syncs from one (so that its next sync_from() sends only what is new).
  void sync_whole_locked(const KernelScene& scene) {
    if (log_) {
      active_->forget_synced();
      active_->sync_from(scene, *log_);
    } else {
      active_->sync(scene, SceneDelta::everything());
    }
  }

  // Replaces the device backend by a CPU backend that has seen nothing yet.
  // The device backend is kept, not destroyed: the other thread may still be
  // inside its sync().
  void fall_back_locked(const std::string& failure) {
    log_warning("the GPU failed (" + failure + "); rendering on the CPU from now on");
    failure_ = failure;
    deferred_failure_.clear();
    fell_back_ = true;
    retired_ = std::move(active_);
    active_ = std::make_unique<CpuBackend>(CpuTraversal::kEmbree);
  }

  // Falls back and gives the new CPU backend the whole scene at once (when
  // nothing renders from the device backend any more).
  void fall_back_and_sync_locked(const std::string& failure, const KernelScene& scene) {
    fall_back_locked(failure);
    sync_whole_locked(scene);
  }

  mutable std::mutex mutex_;
  std::unique_ptr<Backend> retired_;  // the failed device backend (see fall_back_locked)
  std::unique_ptr<Backend> active_;
  const KernelScene* scene_ = nullptr;
  const KernelChangeLog* log_ = nullptr;  // of the last sync, when it came from a log
  std::atomic<bool> fell_back_{false};
  bool rendering_ = false;
  std::string deferred_failure_;
  std::string failure_;  // why it fell back; empty before
};

// The CUDA backend for auto/hetero, or null (with a warning) when it cannot
// be created.
std::unique_ptr<Backend> try_create_cuda(const BackendOptions& options) {
  std::string reason;
  if (!cuda_device_available(&reason)) {
    // Said once: a viewer that switches backends, or a bench that makes a
    // list per measurement, would otherwise repeat it every time.
    static std::atomic<bool> said{false};
    if (options.announce_cpu_fallback && !said.exchange(true))
      log_warning("no usable GPU (" + reason + "); rendering on the CPU");
    return nullptr;
  }
  try {
    return make_cpu_fallback(std::make_unique<CudaBackend>(options.kernel));
  } catch (const DeviceError& e) {
    log_warning(std::string("the CUDA backend failed to start (") + e.what() +
                "); rendering on the CPU");
    return nullptr;
  }
}

}  // namespace

std::unique_ptr<Backend> make_cpu_fallback(std::unique_ptr<Backend> device_backend) {
  return std::make_unique<CpuFallbackBackend>(std::move(device_backend));
}

BackendKind parse_backend_kind(const std::string& name) {
  if (name == "auto") return BackendKind::kAuto;
  if (name == "cpu") return BackendKind::kCpu;
  if (name == "host") return BackendKind::kHost;
  if (name == "cuda") return BackendKind::kCuda;
  if (name == "hetero") return BackendKind::kHetero;
  throw UsageError("unknown backend '" + name + "' (expected cpu, host, cuda, hetero or auto)");
}

bool cuda_device_available(std::string* reason) {
  return cuda_backend_device_available(reason);
}

std::vector<std::unique_ptr<Backend>> create_backends(BackendKind kind,
                                                      const BackendOptions& options) {
  std::vector<std::unique_ptr<Backend>> out;
  std::string reason;
  switch (kind) {
    case BackendKind::kCuda: {
      if (!cuda_device_available(&reason))
        throw InputError("the cuda backend cannot run: " + reason);
      // Asked for by name: failures reach the user instead of a fallback,
      // unless the user listed other backends beside it.
      std::unique_ptr<Backend> cuda = std::make_unique<CudaBackend>(options.kernel);
      if (options.cuda_falls_back) cuda = make_cpu_fallback(std::move(cuda));
      out.push_back(std::move(cuda));
      return out;
    }
    case BackendKind::kHost:
      // Our BVH and the shared kernels on the CPU: what the CUDA backend runs.
      out.push_back(std::make_unique<CpuBackend>(CpuTraversal::kTandemBvh, options.kernel));
      return out;
    case BackendKind::kAuto:
    case BackendKind::kHetero: {
      // auto: the GPU alone; hetero: the GPU first, then the CPU backend
      // beside it (the core tracer decides the split).
      std::unique_ptr<Backend> cuda = try_create_cuda(options);
      if (cuda) {
        out.push_back(std::move(cuda));
        if (kind == BackendKind::kAuto) return out;
      }
      break;
    }
    case BackendKind::kCpu:
      break;
  }
  out.push_back(std::make_unique<CpuBackend>(CpuTraversal::kEmbree, options.kernel));
  return out;
}

}  // namespace tandem
