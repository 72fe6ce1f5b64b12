#include "backends/backend_factory.h"

#include "backends/cpu/embree_backend.h"
#include "core/util/errors.h"
#include "core/util/log.h"

namespace tandem {

BackendKind parse_backend_kind(const std::string& name) {
  if (name == "auto") return BackendKind::kAuto;
  if (name == "cpu") return BackendKind::kCpu;
  if (name == "host") return BackendKind::kHost;
  if (name == "cuda") return BackendKind::kCuda;
  if (name == "hetero") return BackendKind::kHetero;
  throw UsageError("unknown backend '" + name + "' (expected cpu, host, cuda, hetero or auto)");
}

bool cuda_device_available(std::string* reason) {
  if (reason) *reason = "this build of tandem has no CUDA backend";
  return false;
}

std::vector<std::unique_ptr<Backend>> create_backends(BackendKind kind) {
  std::vector<std::unique_ptr<Backend>> out;
  std::string reason;
  switch (kind) {
    case BackendKind::kCuda:
      if (!cuda_device_available(&reason)) throw InputError("--backend cuda: " + reason);
      break;
    case BackendKind::kHost:
      throw InputError("--backend host: not available in this build");
    case BackendKind::kAuto:
    case BackendKind::kHetero:
      if (!cuda_device_available(&reason)) {
        log_warning("no usable GPU (" + reason + "); rendering on the CPU");
      }
      break;
    case BackendKind::kCpu:
      break;
  }
  out.push_back(std::make_unique<EmbreeBackend>());
  return out;
}

}  // namespace tandem
