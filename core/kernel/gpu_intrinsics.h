// The GPU intrinsics of the kernel code's GPU branches (TANDEM_GPU_CODE,
// defines.h), under names of their own. In nvcc's device pass they are
// CUDA's; in the simulated device's emulated build (TANDEM_EMULATED_GPU)
// they are CPU code that computes what the GPU computes and checks what a
// GPU would fault on or leave undefined: a read-only load must be aligned
// and lie inside device memory (an allocation of the simulated device, or
// one of the kernel headers' __device__ tables), and so must an atomic.
#pragma once

#include "core/kernel/defines.h"

// A table that the GPU reads from global memory through the read-only cache
// rather than from __constant__ memory: neighbouring threads read different
// entries, which the constant cache would serialise. Under nvcc a __device__
// array; in the emulated build an array of its own, which the simulated
// device counts as device memory (backends/cuda/device_exec.h).
#if defined(__CUDACC__)
#define TANDEM_DEVICE_TABLE static __device__ const
#define TANDEM_HAS_DEVICE_TABLES 1
#elif TANDEM_GPU_CODE
#define TANDEM_DEVICE_TABLE inline constexpr
#define TANDEM_HAS_DEVICE_TABLES 1
#else
#define TANDEM_HAS_DEVICE_TABLES 0
#endif

#if !defined(__CUDACC__)
#include <cstddef>

namespace tandem::gpu_emulation {
// Defined by the simulated device (backends/cuda/emulated_grid.cpp): checks
// an access of `bytes` at `p` by the running emulated thread, and ends the
// kernel with a fault report, as a GPU would, when it is misaligned or
// outside device memory. Outside the namespace of the kernel copies, so
// that every emulated copy calls the one definition.
void check_device_access(const void* p, size_t bytes, size_t alignment, const char* what);
}  // namespace tandem::gpu_emulation
#endif

#if TANDEM_GPU_CODE

// Unrolls the loop that follows, for each compiler of the GPU branches.
#if defined(__CUDACC__) || defined(__clang__)
#define TANDEM_GPU_UNROLL _Pragma("unroll")
#else
#define TANDEM_GPU_UNROLL _Pragma("GCC unroll 16")
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

// Four words loaded as one 16-byte vector.
#if defined(__CUDA_ARCH__)
using GpuWord4 = uint4;
#else
struct alignas(16) GpuWord4 {
  uint32_t x, y, z, w;
};
#endif

// __ldg: a load through the read-only (non-coherent) data cache, for data
// that no thread writes during the launch.
template <class T>
TANDEM_HD T gpu_load_readonly(const T* p) {
#if defined(__CUDA_ARCH__)
  return __ldg(p);
#else
  gpu_emulation::check_device_access(p, sizeof(T), alignof(T), "read-only load (__ldg)");
  return *p;
#endif
}

// __brev: the bits of x in reverse order.
TANDEM_HD uint32_t gpu_reverse_bits(uint32_t x) {
#if defined(__CUDA_ARCH__)
  return __brev(x);
#else
  x = (x >> 16) | (x << 16);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  return ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
#endif
}

// __ffs: one plus the index of the lowest set bit, 0 when x is 0.
TANDEM_HD uint32_t gpu_find_first_set(uint32_t x) {
#if defined(__CUDA_ARCH__)
  return uint32_t(__ffs(int(x)));
#else
  return x ? uint32_t(__builtin_ctz(x)) + 1u : 0u;
#endif
}

// __popc: the number of set bits.
TANDEM_HD uint32_t gpu_popcount(uint32_t x) {
#if defined(__CUDA_ARCH__)
  return uint32_t(__popc(x));
#else
  return uint32_t(__builtin_popcount(x));
#endif
}

// __fmul_rn: a product nvcc never contracts into an FMA.
TANDEM_HD float gpu_mul_rn(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __fmul_rn(a, b);
#else
  return a * b;
#endif
}

// atomicAdd on a word of device memory; returns the old value.
TANDEM_HD uint32_t gpu_atomic_add(uint32_t* p, uint32_t v) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(p, v);
#else
  gpu_emulation::check_device_access(p, sizeof *p, alignof(uint32_t), "atomicAdd");
  return __atomic_fetch_add(p, v, __ATOMIC_RELAXED);
#endif
}

TANDEM_KERNEL_END
}  // namespace tandem

#endif  // TANDEM_GPU_CODE
