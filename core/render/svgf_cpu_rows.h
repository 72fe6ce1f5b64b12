// What the CPU filter's row kernels (svgf_cpu.cpp) share with its
// hand-written AVX2 loop (svgf_cpu_avx2.cpp): the output planes, the store
// of one pixel, the instruction-set clone macros. Internal to those two
// files.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/kernel/svgf.h"

namespace tandem::svgf_cpu_detail {

// Every row kernel of svgf_cpu.cpp exists twice: compiled for baseline x86-64 (SSE2:
// 4 floats per vector instruction) and, where GCC or Clang can target it,
// for AVX2 + FMA (8 floats, fused multiply-adds), chosen at run time by
// what the CPU supports. The build itself stays baseline, so the binary
// runs on any x86-64. Both clones compile the same always-inlined body (the
// per-pixel functions of svgf.h), so they differ only in float rounding
// (FMA contraction, the order of the vector reductions).
#if defined(__x86_64__) && defined(__GNUC__)
#define TANDEM_SVGF_HAVE_AVX2 1
#define TANDEM_SVGF_AVX2 __attribute__((target("avx2,fma")))
#else
#define TANDEM_SVGF_HAVE_AVX2 0
#define TANDEM_SVGF_AVX2
#endif

// One set of illumination + variance planes (an a-trous iteration's output).
struct IllumPlanes {
  float* r;
  float* g;
  float* b;
  float* var;
};

TANDEM_SVGF_INLINE void store(const IllumPlanes& out, size_t i, const Vec4& v) {
  out.r[i] = v.x;
  out.g[i] = v.y;
  out.b[i] = v.z;
  out.var[i] = v.w;
}

#if TANDEM_SVGF_HAVE_AVX2
// The 3x3 a-trous iteration over the interior run [x0, x1) of row y, by
// hand with AVX2 intrinsics (svgf_cpu_avx2.cpp).
TANDEM_SVGF_AVX2 void svgf_atrous_interior_r1_avx2(const SvgfParams& params,
                                                   const SvgfAtrousPlanes& in, uint32_t step, int y,
                                                   int x0, int x1, const IllumPlanes& out);
#endif

}  // namespace tandem::svgf_cpu_detail
