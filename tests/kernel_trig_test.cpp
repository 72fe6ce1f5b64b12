// sincos_pi (core/kernel/trig.h), the kernels' only sine and cosine, against
// double-precision sin/cos of the exact angle.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/kernel/trig.h"

namespace tandem {
namespace {

// Allowed error in units in the last place of the exact result (measured
// maximum: 1.6 ulp).
constexpr double kMaxUlps = 2.0;

float from_bits(uint32_t u) {
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

struct Reference {
  double sin, cos;
};

// sin(pi x), cos(pi x) with the reduction done exactly: x - n/2 is exact in
// double, and pi * r then carries only double rounding error.
Reference reference(float x) {
  const double n = std::nearbyint(2.0 * double(x));
  const double r = double(x) - 0.5 * n;
  const double s = std::sin(M_PI * r), c = std::cos(M_PI * r);
  switch (int(std::fmod(std::fmod(n, 4.0) + 4.0, 4.0))) {
    case 0:
      return {s, c};
    case 1:
      return {c, -s};
    case 2:
      return {-s, -c};
    default:
      return {-c, s};
  }
}

// |got - exact| in ulps of the float nearest to exact; an exact zero must be
// met exactly.
double ulp_error(float got, double exact) {
  if (exact == 0.0) return got == 0.0f ? 0.0 : INFINITY;
  int e;
  std::frexp(exact, &e);  // |exact| in [2^(e-1), 2^e)
  const double ulp = std::ldexp(1.0, std::max(e - 24, -149));
  return std::fabs(double(got) - exact) / ulp;
}

struct ErrorStats {
  double sin_ulps = 0, cos_ulps = 0;
  float worst_sin_x = 0, worst_cos_x = 0;
  uint64_t asymmetric = 0;  // sin(-x) != -sin(x) or cos(-x) != cos(x), bit for bit
  void check(float x) {
    const SinCos got = sincos_pi(x);
    const Reference ref = reference(x);
    const double es = ulp_error(got.sin, ref.sin), ec = ulp_error(got.cos, ref.cos);
    if (!(es <= sin_ulps)) sin_ulps = es, worst_sin_x = x;
    if (!(ec <= cos_ulps)) cos_ulps = ec, worst_cos_x = x;
    const SinCos mirrored = sincos_pi(-x);
    asymmetric += mirrored.sin != -got.sin || mirrored.cos != got.cos;
  }
};

void expect_within(const ErrorStats& st) {
  EXPECT_LE(st.sin_ulps, kMaxUlps) << "sin(pi x) at x = " << std::hexfloat << st.worst_sin_x;
  EXPECT_LE(st.cos_ulps, kMaxUlps) << "cos(pi x) at x = " << std::hexfloat << st.worst_cos_x;
  EXPECT_EQ(st.asymmetric, 0u);
}

// The reduced interval [1/8, 1/4], where the polynomials are evaluated at
// their largest arguments: every float.
TEST(KernelTrig, EveryFloatOfTheTopReducedBinade) {
  ErrorStats st;
  for (uint32_t u = 0x3e000000u; u <= 0x3e800000u; ++u)
    st.check(from_bits(u));
  expect_within(st);
}

// [0, 2] (and by the symmetry check [-2, 0]): every 97th float, which visits
// every binade down to the denormals at a few thousand points each, and the
// regular grid k / 2^20 that the samplers' 2u, 2u - 1 and v arguments fill.
TEST(KernelTrig, DenseGridOverMinusTwoToTwo) {
  ErrorStats st;
  for (uint32_t u = 0; u <= 0x40000000u; u += 97)
    st.check(from_bits(u));
  for (int k = 0; k <= (2 << 20); ++k)
    st.check(float(k) * 0x1p-20f);
  expect_within(st);
}

TEST(KernelTrig, ExactAtMultiplesOfAHalf) {
  for (int k = -8; k <= 8; ++k) {
    const SinCos sc = sincos_pi(0.5f * float(k));
    const float s = (k % 2 == 0) ? 0.0f : ((k + 8) % 4 == 1 ? 1.0f : -1.0f);
    const float c = (k % 2 != 0) ? 0.0f : ((k + 8) % 4 == 0 ? 1.0f : -1.0f);
    EXPECT_EQ(sc.sin, s) << k;
    EXPECT_EQ(sc.cos, c) << k;
  }
}

TEST(KernelTrig, LargeArgumentsAndNaN) {
  // The reduction stays exact up to 2^22 (used by rotate_y with any angle).
  ErrorStats st;
  for (float x : {3.0f, 100.25f, -1234.567f, 4194303.5f, 0x1p22f, 1e5f + 0.1f})
    st.check(x);
  expect_within(st);
  EXPECT_TRUE(std::isnan(sin_pi(NAN)));
  EXPECT_TRUE(std::isnan(cos_pi(NAN)));
}

}  // namespace
}  // namespace tandem
