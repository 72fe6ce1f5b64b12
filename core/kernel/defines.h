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

constexpr float kPi = 3.14159265358979323846f;
constexpr float kTwoPi = 6.28318530717958647692f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInv2Pi = 0.15915494309189533577f;
constexpr float kInv4Pi = 0.07957747154594766788f;
constexpr float kFloatMax = 3.402823466e+38f;
constexpr uint32_t kInvalidIndex = 0xffffffffu;

TANDEM_HD uint32_t float_as_uint(float f) {
#if TANDEM_DEVICE_COMPILE && defined(__CUDA_ARCH__)
  return __float_as_uint(f);
#else
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
#endif
}

TANDEM_HD float uint_as_float(uint32_t u) {
#if TANDEM_DEVICE_COMPILE && defined(__CUDA_ARCH__)
  return __uint_as_float(u);
#else
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
#endif
}

TANDEM_HD bool is_finite(float x) {
  return (float_as_uint(x) & 0x7f800000u) != 0x7f800000u;
}

}  // namespace tandem
