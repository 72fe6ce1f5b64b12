#include "backends/backend_factory.h"

#include "backends/cpu/embree_backend.h"
#include "backends/host/host_backend.h"
#include "core/util/errors.h"
#include "core/util/log.h"

#if TANDEM_HAVE_CUDA
#include "backends/cuda/cuda_backend.h"
#include "backends/cuda/cuda_check.h"
#endif

namespace tandem {

#if TANDEM_HAVE_CUDA
namespace {

// `--backend auto` promises an image whatever the GPU does: a CUDA failure
// while uploading the scene (out of device memory, a driver fault) logs a
// warning and hands the scene to the CPU backend, which has not seen any of
// it, so it gets a delta that says "everything".
class CudaOrCpuBackend final : public Backend {
 public:
  explicit CudaOrCpuBackend(std::unique_ptr<Backend> cuda) : active_(std::move(cuda)) {}
  std::string name() const override { return active_->name(); }
  bool needs_bvh() const override { return active_->needs_bvh(); }
  void sync(const KernelScene& scene, const SceneDelta& delta) override {
    if (!fell_back_) {
      try {
        active_->sync(scene, delta);
        return;
      } catch (const CudaError& e) {
        log_warning(std::string("the CUDA backend failed (") + e.what() +
                    "); rendering on the CPU");
        fell_back_ = true;
        active_.reset();
        active_ = std::make_unique<EmbreeBackend>();
      }
      SceneDelta everything = delta;
      everything.full = everything.constants = everything.instances_changed = true;
#define TANDEM_MARK_REALLOCATED(T, name) everything.name.reallocated = true;
      TANDEM_KERNEL_ARRAYS(TANDEM_MARK_REALLOCATED)
#undef TANDEM_MARK_REALLOCATED
      active_->sync(scene, everything);
      return;
    }
    active_->sync(scene, delta);
  }
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override {
    return active_->render(pass, tiles, film);
  }

 private:
  std::unique_ptr<Backend> active_;
  bool fell_back_ = false;
};

// The CUDA backend for auto/hetero, or null (with a warning) when it cannot
// be created.
std::unique_ptr<Backend> try_create_cuda(bool wrap_for_fallback, CudaKernelVariant kernel) {
  std::string reason;
  if (!cuda_query_device(&reason)) {
    log_warning("no usable GPU (" + reason + "); rendering on the CPU");
    return nullptr;
  }
  try {
    std::unique_ptr<Backend> cuda = std::make_unique<CudaBackend>(kernel);
    if (wrap_for_fallback) cuda = std::make_unique<CudaOrCpuBackend>(std::move(cuda));
    return cuda;
  } catch (const std::exception& e) {
    log_warning(std::string("the CUDA backend failed to start (") + e.what() +
                "); rendering on the CPU");
    return nullptr;
  }
}

}  // namespace
#endif

BackendKind parse_backend_kind(const std::string& name) {
  if (name == "auto") return BackendKind::kAuto;
  if (name == "cpu") return BackendKind::kCpu;
  if (name == "host") return BackendKind::kHost;
  if (name == "cuda") return BackendKind::kCuda;
  if (name == "hetero") return BackendKind::kHetero;
  throw UsageError("unknown backend '" + name + "' (expected cpu, host, cuda, hetero or auto)");
}

bool cuda_device_available(std::string* reason) {
#if TANDEM_HAVE_CUDA
  return cuda_query_device(reason);
#else
  if (reason)
    *reason =
        "this build of tandem has no CUDA backend (nvcc was not found when it was configured)";
  return false;
#endif
}

std::vector<std::unique_ptr<Backend>> create_backends(BackendKind kind,
                                                      const BackendOptions& options) {
  std::vector<std::unique_ptr<Backend>> out;
  std::string reason;
  switch (kind) {
    case BackendKind::kCuda:
      if (!cuda_device_available(&reason)) throw InputError("--backend cuda: " + reason);
#if TANDEM_HAVE_CUDA
      // Asked for by name: failures reach the user instead of a fallback.
      out.push_back(std::make_unique<CudaBackend>(options.kernel));
      return out;
#else
      break;  // unreachable: cuda_device_available() is false without CUDA
#endif
    case BackendKind::kHost:
      // Our BVH and the shared kernels on the CPU: what the CUDA backend runs.
      if (options.kernel != CudaKernelVariant::kMegakernel) {
        throw UsageError("--kernel " + std::string(kernel_variant_name(options.kernel)) +
                         ": the host backend has only the megakernel");
      }
      out.push_back(std::make_unique<HostBackend>());
      return out;
    case BackendKind::kAuto:
    case BackendKind::kHetero: {
#if TANDEM_HAVE_CUDA
      // auto: the GPU alone (falling back to the CPU if it fails while
      // syncing); hetero: the GPU first, then the CPU backend beside it
      // (the heterogeneous tracer decides the split).
      std::unique_ptr<Backend> cuda = try_create_cuda(kind == BackendKind::kAuto, options.kernel);
      if (cuda) {
        out.push_back(std::move(cuda));
        if (kind == BackendKind::kAuto) return out;
      }
#else
      if (!cuda_device_available(&reason)) {
        log_warning("no usable GPU (" + reason + "); rendering on the CPU");
      }
#endif
      break;
    }
    case BackendKind::kCpu:
      break;
  }
  out.push_back(std::make_unique<EmbreeBackend>());
  return out;
}

}  // namespace tandem
