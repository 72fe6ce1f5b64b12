// The CUDA device's kernels: the host-side function of each (what
// cudaLaunchKernel takes), registered by the .cu files. Plain types only;
// included by the .cu files and by the CUDA device (cuda_device_ops.cpp).
#pragma once

#include <cstddef>

#include "backends/cuda/device_kernel_ids.h"

namespace tandem {

struct CudaKernelTable {
  struct Kernel {
    const void* function = nullptr;
    size_t args_bytes = 0;
  };
  Kernel kernels[kDeviceKernelCount];

  void add(DeviceKernel kernel, const void* function, size_t args_bytes) {
    kernels[uint32_t(kernel)] = Kernel{function, args_bytes};
  }
  // The __device__ tables are the module's own memory on a GPU: nothing to
  // record (the emulated table records them as device memory).
  void add_device_table(const void*, size_t) {}
};

// One per .cu file (TANDEM_KERNEL_REGISTRY, device_exec.h).
#define TANDEM_DECLARE_CUDA_REGISTRY(name) \
  void register_cuda_kernels_##name(CudaKernelTable& table);
TANDEM_DEVICE_KERNEL_FILES(TANDEM_DECLARE_CUDA_REGISTRY)
#undef TANDEM_DECLARE_CUDA_REGISTRY

// Every kernel, registered on first use (cuda_device_ops.cpp).
const CudaKernelTable& cuda_kernels();

}  // namespace tandem
