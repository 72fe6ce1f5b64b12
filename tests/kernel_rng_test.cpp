// The counter-based sampler: Owen-scrambled Sobol pairs must be stratified
// (a (0, m, 2)-net for every power-of-two prefix), uniform, and independent
// between pairs and pixels.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "core/kernel/rng.h"

namespace tandem {
namespace {

// Every elementary interval of area 2^-m holds exactly one of the first 2^m
// points, for every split 2^a x 2^(m - a) of the unit square.
void expect_net(uint32_t pixel, uint32_t dim_x, uint32_t dim_y, uint32_t m,
                uint32_t first_sample = 0) {
  const uint32_t n = 1u << m;
  for (uint32_t a = 0; a <= m; ++a) {
    const uint32_t cols = 1u << a, rows = 1u << (m - a);
    std::vector<int> count(n, 0);
    for (uint32_t s = 0; s < n; ++s) {
      const PathRng r = make_path_rng(pixel, first_sample + s, 17);
      const float x = rng_1d(r, dim_x), y = rng_1d(r, dim_y);
      ASSERT_GE(x, 0.0f);
      ASSERT_LT(x, 1.0f);
      const uint32_t cx = uint32_t(x * float(cols)), cy = uint32_t(y * float(rows));
      count[cy * cols + cx] += 1;
    }
    for (uint32_t c = 0; c < n; ++c) {
      ASSERT_EQ(count[c], 1) << "pixel " << pixel << " dims " << dim_x << "," << dim_y
                             << " interval " << cols << "x" << rows << " cell " << c;
    }
  }
}

TEST(KernelRng, PairsAreStratifiedForEveryPowerOfTwoPrefix) {
  const uint32_t light_u = bounce_dimension(2, kBounceLightU),
                 light_v = bounce_dimension(2, kBounceLightV);
  const uint32_t bsdf_u = bounce_dimension(0, kBounceBsdfU),
                 bsdf_v = bounce_dimension(0, kBounceBsdfV);
  for (uint32_t pixel : {0u, 1u, 12345u, 999999u}) {
    for (uint32_t m : {2u, 4u, 8u}) {
      expect_net(pixel, kDimPixelJitter, kDimPixelJitter + 1, m);
      expect_net(pixel, kDimLens, kDimLens + 1, m);
      expect_net(pixel, light_u, light_v, m);
      expect_net(pixel, bsdf_u, bsdf_v, m);
    }
  }
}

TEST(KernelRng, OneDimensionalDecisionsAreStratified) {
  for (uint32_t dim : {bounce_dimension(0, kBounceLightSelect), bounce_dimension(3, kBounceLobe),
                       bounce_dimension(1, kBounceRoulette)}) {
    std::vector<int> count(64, 0);
    for (uint32_t s = 0; s < 64; ++s)
      count[uint32_t(rng_1d(make_path_rng(77, s, 5), dim) * 64.0f)] += 1;
    for (int c : count)
      EXPECT_EQ(c, 1) << "dimension " << dim;
  }
}

TEST(KernelRng, DifferentPairsAndPixelsAreUncorrelated) {
  // Pearson correlation over many (pixel, sample) draws: pairs that share the
  // Sobol structure must not share its points (the per-pair index shuffle).
  const uint32_t dims[][2] = {
      {kDimPixelJitter, bounce_dimension(0, kBounceLightU)},
      {kDimLens, bounce_dimension(0, kBounceBsdfU)},
      {bounce_dimension(0, kBounceBsdfU), bounce_dimension(1, kBounceBsdfU)},
      {bounce_dimension(0, kBounceLightSelect), bounce_dimension(0, kBounceLobe)}};
  constexpr int kPixels = 256, kSamples = 64;
  for (const auto& d : dims) {
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    const double n = double(kPixels * kSamples);
    for (uint32_t p = 0; p < kPixels; ++p) {
      for (uint32_t s = 0; s < kSamples; ++s) {
        const PathRng r = make_path_rng(p, s, 3);
        const double x = rng_1d(r, d[0]), y = rng_1d(r, d[1]);
        sx += x;
        sy += y;
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
      }
    }
    const double cov = sxy / n - (sx / n) * (sy / n);
    const double corr =
        cov / std::sqrt((sxx / n - (sx / n) * (sx / n)) * (syy / n - (sy / n) * (sy / n)));
    // Independent draws: standard error 1/sqrt(n) = 0.0078.
    EXPECT_LT(std::fabs(corr), 5.0 / std::sqrt(n)) << "dims " << d[0] << ", " << d[1];
  }
  // Neighbouring pixels get different scrambles of the same sample.
  int equal = 0;
  for (uint32_t p = 0; p < 1000; ++p) {
    equal += rng_1d(make_path_rng(p, 0, 1), kDimPixelJitter) ==
             rng_1d(make_path_rng(p + 1, 0, 1), kDimPixelJitter);
  }
  EXPECT_LT(equal, 3);
}

TEST(KernelRng, SobolSecondDimensionMatchesItsDirectionNumbers) {
  // Definition: v_1 = 1 << 31, v_(k+1) = v_k ^ (v_k >> 1); x(i) = xor of the
  // v_k whose index bit k is set.
  uint32_t state = 1;
  for (int t = 0; t < 20000; ++t) {
    state = state * 1664525u + 1013904223u;
    const uint32_t index = t < 64 ? uint32_t(t) : state;
    uint32_t expected = 0;
    uint32_t v = 1u << 31;
    for (uint32_t i = index; i != 0; i >>= 1, v ^= v >> 1) {
      if (i & 1u) expected ^= v;
    }
    ASSERT_EQ(sobol_dimension1(index), expected) << "index " << index;
  }
}

TEST(KernelRng, TwoDimensionalDrawsEqualTheirOneDimensionalParts) {
  for (uint32_t p = 0; p < 50; ++p) {
    for (uint32_t s = 0; s < 40; ++s) {
      const PathRng r = make_path_rng(p * 7919u, s * 13u, 4);
      for (uint32_t first :
           {uint32_t(kDimPixelJitter), uint32_t(kDimLens), bounce_dimension(0, kBounceLightU),
            bounce_dimension(5, kBounceBsdfU)}) {
        const Vec2 v = rng_2d(r, first);
        ASSERT_EQ(v.x, rng_1d(r, first));
        ASSERT_EQ(v.y, rng_1d(r, first + 1));
      }
    }
  }
}

// The CPU tile loop's cache of the sample-independent hashes gives exactly
// the numbers of the plain draws, for bounces in any order (the cache fills
// lazily), past its last cached bounce too, and for several samples of a
// pixel in a row.
TEST(KernelRng, PixelCacheDrawsEqualThePlainDraws) {
  PixelRngCache cache;
  for (uint32_t pixel : {0u, 17u, 65535u, 123457u}) {
    for (uint32_t seed : {0u, 9u}) {
      pixel_rng_cache_reset(&cache, pixel, seed);
      for (uint32_t s = 0; s < 24; ++s) {
        const PathRng r = make_path_rng(pixel, s, seed);
        ASSERT_EQ(r.key, cache.key);
        const CachedPathRng c{r, &cache};
        const Vec2 j = rng_jitter_2d(c), l = rng_lens_2d(c);
        ASSERT_EQ(j.x, rng_2d(r, kDimPixelJitter).x);
        ASSERT_EQ(j.y, rng_2d(r, kDimPixelJitter).y);
        ASSERT_EQ(l.x, rng_2d(r, kDimLens).x);
        ASSERT_EQ(l.y, rng_2d(r, kDimLens).y);
        // Sample 0 visits bounces 3 then 0 (out of order), later ones up to 23.
        const uint32_t deepest = s == 0 ? 3u : s;
        for (uint32_t k = 0; k <= deepest; ++k) {
          const uint32_t b = s == 0 ? deepest - k : k;
          for (uint32_t which : {uint32_t(kBounceLightU), uint32_t(kBounceBsdfU)}) {
            const Vec2 a = bounce_rng_2d(c, b, which), e = rng_2d(r, bounce_dimension(b, which));
            ASSERT_EQ(a.x, e.x) << "bounce " << b << " which " << which;
            ASSERT_EQ(a.y, e.y) << "bounce " << b << " which " << which;
          }
          for (uint32_t which :
               {uint32_t(kBounceLightSelect), uint32_t(kBounceLobe), uint32_t(kBounceRoulette)}) {
            ASSERT_EQ(bounce_rng_1d(c, b, which), rng_1d(r, bounce_dimension(b, which)))
                << "bounce " << b << " which " << which;
          }
          for (uint32_t which : {uint32_t(kBounceAlpha), uint32_t(kBounceShadowAlpha)})
            ASSERT_EQ(bounce_rng_bits(c, b, which), rng_bits(r, bounce_dimension(b, which)));
        }
      }
      EXPECT_EQ(cache.bounces_filled, PixelRngCache::kMaxBounces);
    }
  }
}

// The reversal by bytes (rng_tables.h) against a bit-by-bit one, and the
// Pascal matrix and unit float after it against the plain functions.
uint32_t reverse_bit_by_bit(uint32_t x) {
  uint32_t r = 0;
  for (int i = 0; i < 32; ++i)
    r |= ((x >> i) & 1u) << (31 - i);
  return r;
}

TEST(KernelRng, ByteTableReversalsEqualTheBitwiseOnes) {
  uint32_t state = 12345;
  for (uint32_t t = 0; t < 300000; ++t) {
    state = state * 1664525u + 1013904223u;
    const uint32_t x = t < 65536 ? t : t < 131072 ? (t - 65536) << 16 : state;
    const uint32_t r = reverse_bit_by_bit(x);
    ASSERT_EQ(reverse_bits_u32(x), r) << x;
    ASSERT_EQ(reverse_bits_u32_shifts(x), r) << x;
    ASSERT_EQ(pascal_mod2_of_reversed(x), pascal_mod2(r)) << x;
    const float f = unit_float_of_reversed(x), e = u32_to_unit_float(r);
    ASSERT_EQ(std::memcmp(&f, &e, sizeof f), 0) << x;
  }
}

// The draws as first defined (lk_permute in one piece, the index reversed
// before each component), written out here so that any rewrite of rng.h
// that changes a single bit of any number fails.
float reference_rng_1d(const PathRng& r, uint32_t dimension) {
  const auto lk = [](uint32_t x, uint32_t seed) {
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
  };
  uint32_t first = dimension;
  if (dimension < kDimBounceBase) {
    first = dimension & ~1u;
  } else {
    const uint32_t which = (dimension - kDimBounceBase) % kDimsPerBounce;
    if (which == kBounceLightV || which == kBounceBsdfV) first = dimension - 1;
  }
  const uint32_t component = dimension - first;
  const uint32_t pair_seed = hash_u32(r.key ^ (first * 0x9e3779b9u + 0x632be5abu));
  const uint32_t index = reverse_bit_by_bit(lk(reverse_bit_by_bit(r.sample), pair_seed));
  const uint32_t point = component == 0 ? index : pascal_mod2(index);
  const uint32_t seed = hash_u32(pair_seed + component + 1u);
  return u32_to_unit_float(reverse_bit_by_bit(lk(point, seed)));
}

TEST(KernelRng, DrawsEqualTheirFirstDefinitionBitForBit) {
  PixelRngCache cache;
  for (uint32_t pixel : {0u, 3u, 4097u, 999999u}) {
    pixel_rng_cache_reset(&cache, pixel, 5);
    for (uint32_t s : {0u, 1u, 7u, 15u, 255u, 256u, 65537u, 0xfffffffeu}) {
      const PathRng r = make_path_rng(pixel, s, 5);
      const CachedPathRng c{r, &cache};
      for (uint32_t d = 0; d < 80; ++d)
        ASSERT_EQ(rng_1d(r, d), reference_rng_1d(r, d)) << "sample " << s << " dim " << d;
      const Vec2 j = rng_jitter_2d(c), l = rng_lens_2d(c);
      ASSERT_EQ(j.x, reference_rng_1d(r, kDimPixelJitter));
      ASSERT_EQ(j.y, reference_rng_1d(r, kDimPixelJitter + 1));
      ASSERT_EQ(l.x, reference_rng_1d(r, kDimLens));
      ASSERT_EQ(l.y, reference_rng_1d(r, kDimLens + 1));
      // Bounces past the cache's last one share its `deep` slot: alternate.
      for (uint32_t b : {0u, 20u, 5u, 17u, 20u, 15u, 16u}) {
        const auto br = rng_at_bounce(c, b);
        const Vec2 u = bounce_rng_2d(br, kBounceBsdfU);
        ASSERT_EQ(u.x, reference_rng_1d(r, bounce_dimension(b, kBounceBsdfU))) << b;
        ASSERT_EQ(u.y, reference_rng_1d(r, bounce_dimension(b, kBounceBsdfV))) << b;
        ASSERT_EQ(bounce_rng_1d(br, kBounceRoulette),
                  reference_rng_1d(r, bounce_dimension(b, kBounceRoulette)))
            << b;
        const auto pr = rng_at_bounce(r, b);
        ASSERT_EQ(bounce_rng_1d(pr, kBounceLightSelect),
                  reference_rng_1d(r, bounce_dimension(b, kBounceLightSelect)))
            << b;
      }
    }
  }
}

TEST(KernelRng, ValuesAreAPureFunctionOfTheirKey) {
  const PathRng a = make_path_rng(42, 1000, 9), b = make_path_rng(42, 1000, 9);
  for (uint32_t d = 0; d < 64; ++d)
    EXPECT_EQ(rng_1d(a, d), rng_1d(b, d));
  EXPECT_NE(rng_1d(make_path_rng(42, 1000, 9), 0), rng_1d(make_path_rng(42, 1000, 10), 0));
}

}  // namespace
}  // namespace tandem
