// 2^x, log2(x) and x^y in plain float arithmetic, for the kernels.
//
// Like trig.h: expf/powf come from glibc on the CPU and from libdevice on the
// GPU and differ in their last bits, so a BSDF built on them would give the
// two backends different images. These use only bit operations and IEEE
// +, -, *, / and rintf (CUDA is compiled with -fmad=false), so both compilers
// return the same bits. They are meant for shading terms (the sheen lobe),
// not for general use: finite, positive arguments, relative error a few ulp
// (tests/kernel_exp_log_test.cpp).
#pragma once

#include "core/kernel/defines.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// log2(x) for x > 0 (0 and denormals give a large negative number, which
// exp2_f turns into 0). x = 2^e * m with m in [sqrt(1/2), sqrt(2)), and
// log2(m) = 2 / ln 2 * atanh(f), f = (m - 1) / (m + 1), |f| <= 0.172, whose
// odd series converges to float precision by the f^9 term.
TANDEM_HD float log2_f(float x) {
  if (!(x > 0.0f)) return -256.0f;
  uint32_t bits = float_as_uint(x);
  int e = int((bits >> 23) & 0xffu) - 127;
  if (e == -127) return -256.0f;              // denormal: far below anything a shading term needs
  bits = (bits & 0x007fffffu) | 0x3f800000u;  // m in [1, 2)
  float m = uint_as_float(bits);
  if (m > 1.41421356f) {
    m *= 0.5f;
    e += 1;
  }
  const float f = (m - 1.0f) / (m + 1.0f);
  const float f2 = f * f;
  const float series =
      f *
      (2.0f + f2 * (2.0f / 3.0f + f2 * (2.0f / 5.0f + f2 * (2.0f / 7.0f + f2 * (2.0f / 9.0f)))));
  return float(e) + series * 1.44269504f;  // 1 / ln 2
}

// 2^x; 0 below 2^-126, +inf above 2^128. x = n + r with |r| <= 1/2 (exact),
// 2^r by its Taylor series to r^7 (error below 2^-26), times 2^n through the
// exponent bits.
TANDEM_HD float exp2_f(float x) {
  if (x < -126.0f) return 0.0f;
  if (x >= 128.0f) return uint_as_float(0x7f800000u);
  const float n = rintf(x);
  const float r = (x - n) * 0.693147181f;  // ln 2
  const float p =
      1.0f + r * (1.0f + r * (0.5f + r * (1.0f / 6.0f +
                                          r * (1.0f / 24.0f +
                                               r * (1.0f / 120.0f +
                                                    r * (1.0f / 720.0f + r * (1.0f / 5040.0f)))))));
  // p is in [0.70, 1.42], so n + 127 in [1, 254] keeps the product normal
  // except at n = 127 with p > 1 (2^127 * p < 2^128: still finite).
  return p * uint_as_float(uint32_t(int(n) + 127) << 23);
}

// x^y for x >= 0 (0^y = 0 for y > 0).
TANDEM_HD float pow_f(float x, float y) {
  if (!(x > 0.0f)) return 0.0f;
  return exp2_f(y * log2_f(x));
}

// e^x.
TANDEM_HD float exp_f(float x) {
  return exp2_f(x * 1.44269504f);
}

TANDEM_KERNEL_END
}  // namespace tandem
