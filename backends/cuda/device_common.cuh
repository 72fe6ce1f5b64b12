// Small device helpers shared by the CUDA backend's .cu files. Device code
// only; included after cuda_kernels.h.
#pragma once

#include "backends/cuda/cuda_kernels.h"

namespace tandem {

// The kernels read the scene description through a block-wide copy of
// KernelData in shared memory: every thread dereferences its pointers in the
// innermost traversal loops, and shared memory serves those uniform loads
// without touching the L1 data cache that the BVH nodes need.
__device__ __forceinline__ void load_kernel_data(KernelData* dst, const KernelData* src) {
  static_assert(sizeof(KernelData) % sizeof(uint32_t) == 0, "copied as words");
  const uint32_t* s = reinterpret_cast<const uint32_t*>(src);
  uint32_t* d = reinterpret_cast<uint32_t*>(dst);
  for (uint32_t i = threadIdx.x; i < sizeof(KernelData) / sizeof(uint32_t); i += blockDim.x)
    d[i] = s[i];
  __syncthreads();
}

// Adds each thread's ray count to *total with one atomic per warp. Every
// lane of the warp must call it.
__device__ __forceinline__ void add_ray_count(uint32_t rays, unsigned long long* total) {
  const uint32_t sum = __reduce_add_sync(0xffffffffu, rays);
  if ((threadIdx.x & 31u) == 0) atomicAdd(total, static_cast<unsigned long long>(sum));
}

inline uint32_t blocks_for(uint64_t items, uint32_t threads) {
  return uint32_t((items + threads - 1) / threads);
}

}  // namespace tandem
