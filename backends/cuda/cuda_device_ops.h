// The CUDA device: device_ops.h over the CUDA runtime and the .cu kernels.
// Only built when nvcc is found; no CUDA headers here.
#pragma once

#include <memory>
#include <string>

#include "backends/cuda/device_ops.h"

namespace tandem {

// Whether a CUDA GPU this build can run on exists; otherwise `reason` says
// why (no driver, driver too old, no device, no kernel image for the
// device's architecture, ...).
bool cuda_query_device(std::string* reason);

// Device 0, set up so that the host blocks instead of spinning while it
// waits for the GPU (the CPU backend needs those cores in a hetero frame).
// Null with `reason` when cuda_query_device() says no.
std::shared_ptr<DeviceOps> make_cuda_device(std::string* reason);

}  // namespace tandem
