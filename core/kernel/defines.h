// Host/device portability layer for the shared kernel code.
//
// Everything under core/kernel/ is compiled twice: by g++ for the CPU and host
// backends and by nvcc for the CUDA backend. Only POD structs and free
// functions live here; every function is marked TANDEM_HD so both compilers
// emit it. Nothing in this directory may allocate, throw, or use virtuals.
#pragma once

#include <cstdint>

#if defined(__CUDACC__)
#define TANDEM_HD __host__ __device__ __forceinline__
#define TANDEM_DEVICE_COMPILE 1
#else
#define TANDEM_HD inline
#define TANDEM_DEVICE_COMPILE 0
#endif

// TANDEM_GPU_CODE: whether the GPU's own branches of the kernel code are
// compiled (vector loads through the read-only cache, bit intrinsics, the
// portable BVH loops, device atomics). They are in nvcc's device pass, and
// in the simulated device's emulated build (TANDEM_EMULATED_GPU, defined by
// backends/cuda/emulated_*.cpp before any include), which runs them on the
// CPU so that CI executes the code a GPU executes (gpu_intrinsics.h).
#if defined(__CUDA_ARCH__) || defined(TANDEM_EMULATED_GPU)
#define TANDEM_GPU_CODE 1
#else
#define TANDEM_GPU_CODE 0
#endif

// Every kernel header opens namespace tandem and then TANDEM_KERNEL_BEGIN.
// In an emulated build that is an inline namespace of its own: the emulated
// copy of each kernel function has the GPU branches, the host's copy does
// not, and in one program the two must not be taken for the same function
// (the linker would keep one of them for both). Elsewhere it is nothing.
#if defined(TANDEM_EMULATED_GPU)
#define TANDEM_KERNEL_BEGIN inline namespace emulated_gpu {
#define TANDEM_KERNEL_END }
#else
#define TANDEM_KERNEL_BEGIN
#define TANDEM_KERNEL_END
#endif

// For the small vector, random-number and sampling helpers that every
// shading point calls many times: nvcc inlines all TANDEM_HD functions, g++
// at -O3 left these as calls (a tenth of a CPU path-tracing sample went to
// call overhead and to packing Vec3 arguments into registers). Inlining
// changes no result: without FMA there is nothing to contract.
#if defined(__CUDACC__) || !defined(__GNUC__)
#define TANDEM_HD_INLINE TANDEM_HD
#else
#define TANDEM_HD_INLINE inline __attribute__((always_inline))
#endif

// For rarely taken slow paths inside hot inlined code (the CPU's lazy
// random-number seed fills): kept out of line so that they neither grow
// their callers nor shift g++'s inlining decisions for the code around them.
// Only the CPU calls them, so nvcc keeps its default.
#if defined(__CUDACC__)
#define TANDEM_HD_NOINLINE TANDEM_HD
#elif defined(__GNUC__)
#define TANDEM_HD_NOINLINE inline __attribute__((noinline))
#else
#define TANDEM_HD_NOINLINE inline
#endif

// nvcc's host pass compiles the host branches below (std::memcpy) too, so
// only NVRTC, which has no standard headers, goes without them.
#if !defined(__CUDACC_RTC__)
#include <cmath>
#include <cstring>
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

constexpr float kPi = 3.14159265358979323846f;
constexpr float kTwoPi = 6.28318530717958647692f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInv2Pi = 0.15915494309189533577f;
constexpr float kInv4Pi = 0.07957747154594766788f;
constexpr float kFloatMax = 3.402823466e+38f;
constexpr uint32_t kInvalidIndex = 0xffffffffu;

// The bits of a float and back. nvcc turns the copies into register moves
// (no intrinsic needed: the device pass compiles std::memcpy of a scalar to
// a move), so the GPU runs this very code.
TANDEM_HD uint32_t float_as_uint(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

TANDEM_HD float uint_as_float(uint32_t u) {
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

TANDEM_HD bool is_finite(float x) {
  return (float_as_uint(x) & 0x7f800000u) != 0x7f800000u;
}

TANDEM_KERNEL_END
}  // namespace tandem
