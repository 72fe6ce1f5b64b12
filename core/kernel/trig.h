// sin(pi x) and cos(pi x) in plain float arithmetic, for the kernels.
//
// sinf/cosf come from glibc on the CPU and from CUDA's libdevice on the GPU;
// their last bits differ, and so would every direction sampled from them.
// This version uses only IEEE-exact operations (rintf, floorf, +, -, *), and
// CUDA is compiled with -fmad=false, so both compilers round every step alike
// and return the same bits. Taking the angle in units of pi also makes the
// range reduction exact, so there is no Payne-Hanek slow path with its
// double-precision arithmetic and local-memory table on the GPU.
//
// Accuracy: at most 1.6 ulp from sin/cos of the exact pi * x (tests/kernel_trig_test.cpp
// checks every float of [1/8, 1/4], where the polynomials work hardest, and a
// dense grid of [-2, 2]); exact zeros and ones at multiples of 1/2, and
// sin_pi(-x) == -sin_pi(x) bit for bit.
#pragma once

#include "core/kernel/defines.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

struct SinCos {
  float sin, cos;
};

// Polynomials in t = r^2 for r in [-1/4, 1/4], fitted for minimum relative
// error (iteratively reweighted least squares, which converges to the minimax
// fit) with each coefficient rounded to float before the next ones were refit.
// sin(pi r) = r * P(t); cos(pi r) = 1 + t * Q(t).
TANDEM_HD_INLINE float sin_pi_reduced(float r, float t) {
  return r * (0x1.921fb6p+1f + t * (-0x1.4abc24p+2f + t * (0x1.4680a4p+1f + t * -0x1.33199p-1f)));
}
TANDEM_HD_INLINE float cos_pi_reduced(float t) {
  return 1.0f +
         t * (-0x1.3bd3ccp+2f + t * (0x1.03c1bp+2f + t * (-0x1.55b2b6p+0f + t * 0x1.d4f7eep-3f)));
}

// sin(pi x) and cos(pi x) for |x| <= 2^22 (the reduction stays exact there;
// the kernels pass |x| <= 2 or an angle over pi). NaN in, NaN out.
TANDEM_HD_INLINE SinCos sincos_pi(float x) {
  // x = n / 2 + r with integer n and |r| <= 1/4; both steps are exact.
  const float n = rintf(2.0f * x);
  const float r = x - 0.5f * n;
  const float t = r * r;
  const float s = sin_pi_reduced(r, t);
  const float c = cos_pi_reduced(t);
  // Quadrant n mod 4 in float, so that no float-to-int conversion can overflow.
  const float q = n - 4.0f * floorf(n * 0.25f);
  const bool odd = q == 1.0f || q == 3.0f;
  SinCos out = {odd ? c : s, odd ? s : c};
  if (q >= 2.0f) out.sin = -out.sin;
  if (q == 1.0f || q == 2.0f) out.cos = -out.cos;
  return out;
}

TANDEM_HD_INLINE float sin_pi(float x) {
  return sincos_pi(x).sin;
}
TANDEM_HD_INLINE float cos_pi(float x) {
  return sincos_pi(x).cos;
}

// atan(r) / pi for |r| <= tan(pi / 8): r / pi + r * t * Q(t) with t = r^2,
// Q fitted as the sine's and cosine's polynomials (relative error 7e-10 in
// exact arithmetic). 1 / pi is split into a float and its remainder, so the
// result rounds without a bias (atan2f times the float 1 / pi, 4e-8 low,
// put the equirectangular lookups a third of an ulp low on average).
TANDEM_HD_INLINE float atan_pi_reduced(float r) {
  const float t = r * r;
  const float tail =
      0x1.b9391p-27f +
      t * (-0x1.b2994ep-4f +
           t * (0x1.04bd12p-4f + t * (-0x1.735ffp-5f + t * (0x1.13f164p-5f + t * -0x1.3b677p-6f))));
  return r * 0x1.45f306p-2f + r * tail;
}

// atan2(y, x) / pi, in [-1, 1], in plain float arithmetic: the same bits
// from g++ and from nvcc (-fmad=false), where atan2f (glibc's, libdevice's)
// differs between them in its last bits; and about a quarter of glibc's
// instructions (the equirectangular lookups of every missed ray call it
// twice). Accuracy: at most 3 ulp from atan2 of the exact arguments over
// pi, and no bias (tests/kernel_trig_test.cpp). The signs follow atan2's: atan2_pi(+-0,
// -0) = +-1, atan2_pi(-0, x > 0) = -0; a NaN argument gives NaN.
TANDEM_HD_INLINE float atan2_pi(float y, float x) {
  if (!(x == x) || !(y == y)) return x + y;
  const float ax = fabsf(x), ay = fabsf(y);
  const bool steep = ay > ax;
  const float big = steep ? ay : ax, small = steep ? ax : ay;
  // small / big in [0, 1]: 0 for 0 / 0, 1 for inf / inf.
  const float a = small == big ? (big > 0.0f ? 1.0f : 0.0f) : small / big;
  // Past tan(pi / 8), atan(a) = pi / 4 + atan((a - 1) / (a + 1)).
  const bool far = a > 0x1.a827dap-2f;
  float at = atan_pi_reduced(far ? (a - 1.0f) / (a + 1.0f) : a);
  if (far) at += 0.25f;
  if (steep) at = 0.5f - at;
  if ((float_as_uint(x) >> 31) != 0u) at = 1.0f - at;
  return (float_as_uint(y) >> 31) != 0u ? -at : at;
}

TANDEM_KERNEL_END
}  // namespace tandem
