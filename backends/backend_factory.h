// Creating backends by name, and the `auto` policy.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/kernel_variant.h"
#include "core/render/backend.h"

namespace tandem {

enum class BackendKind { kAuto, kCpu, kHost, kCuda, kHetero };

// Parses cpu|host|cuda|hetero|auto; throws UsageError otherwise.
BackendKind parse_backend_kind(const std::string& name);

// Whether a usable CUDA device exists; on false, `reason` says why (not
// built with CUDA, no device, driver too old, ...).
bool cuda_device_available(std::string* reason);

// How the created backends trace. The kernel applies to the CUDA backend
// (auto, hetero and cuda) and to the host backend, which has only the
// megakernel so far (asking it for the wavefront is a UsageError).
struct BackendOptions {
  CudaKernelVariant kernel = CudaKernelVariant::kMegakernel;
};

// The backends that will render for `kind`. `auto` falls back to the CPU
// with a one-line notice when no GPU is usable; `cuda` without a device
// throws InputError with the reason.
std::vector<std::unique_ptr<Backend>> create_backends(BackendKind kind,
                                                      const BackendOptions& options = {});

}  // namespace tandem
