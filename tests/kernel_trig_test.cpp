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

// atan2_pi, the equirectangular lookups' arctangent, against double atan2
// of the exact arguments over pi: directions all round the circle at every
// magnitude the float range gives a direction, the neighbourhood of the
// reduction's switch at tan(pi/8), and random pairs of unrelated scales.
constexpr double kMaxAtan2Ulps = 3.0;  // measured maximum: 2.22

double atan2_ulp_error(float y, float x) {
  return ulp_error(atan2_pi(y, x), std::atan2(double(y), double(x)) / M_PI);
}

// Error in ulps of the float nearest to the exact result, negative where
// the result is smaller in magnitude.
double atan2_signed_ulps(float y, float x) {
  const double exact = std::atan2(double(y), double(x)) / M_PI;
  const float got = atan2_pi(y, x);
  const double e = ulp_error(got, exact);
  return std::fabs(double(got)) < std::fabs(exact) ? -e : e;
}

TEST(KernelTrig, Atan2PiIsWithinThreeUlps) {
  double worst = 0.0;
  float worst_y = 0.0f, worst_x = 0.0f;
  // Over the unit directions of the equirectangular lookups, the mean
  // signed error, which an image comparison of smooth skies would see.
  double signed_sum = 0.0;
  uint64_t signed_count = 0;
  const auto check = [&](float y, float x) {
    const double e = atan2_ulp_error(y, x);
    if (!(e <= worst)) worst = e, worst_y = y, worst_x = x;
    // atan2(-y, x) = -atan2(y, x), bit for bit.
    EXPECT_EQ(float_as_uint(atan2_pi(-y, x)), float_as_uint(atan2_pi(y, x)) ^ 0x80000000u);
  };
  for (int k = 0; k < (1 << 20); ++k) {
    const SinCos a = sincos_pi(float(k) * 0x1p-19f);  // angle k pi / 2^19
    for (const int e : {-60, -7, 0, 9, 60})
      check(std::ldexp(a.sin, e), std::ldexp(a.cos, e));
    if (k % 2 == 1) {
      signed_sum += atan2_signed_ulps(a.sin, a.cos);
      ++signed_count;
    }
  }
  // Ratios around tan(pi / 8), where the reduction switches, every float.
  const float t8 = 0x1.a827dap-2f;
  float r = t8;
  for (int i = 0; i < 4096; ++i)
    r = std::nextafter(r, 0.0f);
  for (int i = 0; i < 8192; ++i, r = std::nextafter(r, 1.0f)) {
    check(r, 1.0f);
    check(1.0f, -r);
  }
  uint32_t state = 12345u;
  const auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return state;
  };
  for (int i = 0; i < 1000000; ++i) {
    const float y = std::ldexp(float(next() >> 8) * 0x1p-24f - 0.5f, int(next() % 120) - 60);
    const float x = std::ldexp(float(next() >> 8) * 0x1p-24f - 0.5f, int(next() % 120) - 60);
    check(y, x);
  }
  EXPECT_LE(worst, kMaxAtan2Ulps) << std::hexfloat << "at (" << worst_y << ", " << worst_x << ")";
  // atan2f(y, x) * (1 / pi in float) averages -0.52 ulp here.
  EXPECT_LT(std::fabs(signed_sum / double(signed_count)), 0.05);
}

TEST(KernelTrig, Atan2PiSignsZerosInfinitiesAndNaN) {
  const float z = 0.0f, inf = INFINITY;
  const float special[] = {z, -z, 1.0f, -1.0f, 0x1p-149f, -3.0e38f, inf, -inf};
  for (float y : special) {
    for (float x : special) {
      const float got = atan2_pi(y, x);
      const double want = std::atan2(double(y), double(x)) / M_PI;
      EXPECT_LE(ulp_error(got, want), kMaxAtan2Ulps) << std::hexfloat << y << ", " << x;
      EXPECT_EQ(std::signbit(got), std::signbit(want)) << std::hexfloat << y << ", " << x;
    }
  }
  EXPECT_TRUE(std::isnan(atan2_pi(NAN, 1.0f)));
  EXPECT_TRUE(std::isnan(atan2_pi(1.0f, NAN)));
}

}  // namespace
}  // namespace tandem
