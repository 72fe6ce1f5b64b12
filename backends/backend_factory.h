// Creating backends by name, and the `auto` policy.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/kernel_variant.h"
#include "core/render/backend.h"

namespace tandem {

// kCpu (`cpu`) and kHost (`host`) are the one CPU backend with its two
// traversals, Embree and Tandem's BVH (backends/cpu/cpu_backend.h).
enum class BackendKind { kAuto, kCpu, kHost, kCuda, kHetero };

// Parses cpu|host|cuda|hetero|auto; throws UsageError otherwise.
BackendKind parse_backend_kind(const std::string& name);

// How the created backends trace. The kernel applies to every backend
// created: the CUDA backend and the CPU backend in either traversal.
struct BackendOptions {
  CudaKernelVariant kernel = CudaKernelVariant::kMegakernel;
  // `cuda` as part of a backend list: a device failure while syncing or
  // rendering falls back to the CPU (as under auto) instead of ending the run.
  bool cuda_falls_back = false;
  // auto/hetero without a usable GPU say so (once per process, however
  // many backend lists are made); false: not at all (`--quiet`).
  bool announce_cpu_fallback = true;
};

// Whether the CUDA backend has a device to run on (a GPU, or the simulated
// one under TANDEM_DEVICE=sim); on false, `reason` says why (not built with
// CUDA, no device, driver too old, ...).
bool cuda_device_available(std::string* reason);

// The backends that will render for `kind`. `auto` falls back to the CPU
// with a one-line notice when no GPU is usable; `cuda` without a device
// throws InputError with the reason. Under auto and hetero (and with
// cuda_falls_back) any device failure later, in sync() or render(), gives
// one warning naming the error, and the CPU takes over from a full sync:
// the frame in flight is completed on the CPU and the run goes on.
std::vector<std::unique_ptr<Backend>> create_backends(BackendKind kind,
                                                      const BackendOptions& options = {});

// The fallback wrapper itself, around any backend that may throw
// DeviceError (tests wrap a CUDA backend on the simulated device).
std::unique_ptr<Backend> make_cpu_fallback(std::unique_ptr<Backend> device_backend);

}  // namespace tandem
