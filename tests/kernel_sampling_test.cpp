// Goodness-of-fit tests for the warps in core/kernel/sampling.h and for the
// alias table (host builder + kernel alias_sample), plus self-tests of the
// chi-square machinery in test_stats.h that every sampling test relies on.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

#include "core/kernel/lights.h"
#include "core/kernel/sampling.h"
#include "core/world/light_tables.h"
#include "test_stats.h"

namespace tandem {
namespace {

using test_stats::chi_square_test;
using test_stats::kFamilySignificance;
using test_stats::sidak_alpha;
using test_stats::sphere_chi_square;
using test_stats::TestRng;

// Chi-square tests in this file (2 self-tests, 5 warps, 8 alias weight
// vectors); their family-wise false-alarm rate is 1e-4.
constexpr int kChiSquareTestsInFile = 2 + 5 + 8;
const double kAlpha = sidak_alpha(kFamilySignificance, kChiSquareTestsInFile);

// ---------------------------------------------------------------------------
// The statistics helpers themselves: a wrong survival function would make
// every test below either flaky or unable to fail.

TEST(KernelStats, ChiSquareSurvivalMatchesKnownValues) {
  // dof = 2 and dof = 4 have closed forms: Q = e^{-x/2} and e^{-x/2}(1 + x/2).
  for (double x : {0.1, 1.0, 5.0, 40.0, 120.0}) {
    EXPECT_NEAR(test_stats::chi2_survival(x, 2.0) / std::exp(-0.5 * x), 1.0, 1e-12) << x;
    EXPECT_NEAR(test_stats::chi2_survival(x, 4.0) / (std::exp(-0.5 * x) * (1.0 + 0.5 * x)), 1.0,
                1e-10)
        << x;
  }
  // Tabulated 95% quantiles (series side and continued-fraction side).
  EXPECT_NEAR(test_stats::chi2_survival(3.841458820694124, 1.0), 0.05, 1e-9);
  EXPECT_NEAR(test_stats::chi2_survival(18.307038053275146, 10.0), 0.05, 1e-9);
  EXPECT_NEAR(test_stats::chi2_survival(124.34211340400407, 100.0), 0.05, 1e-9);
  // 0.1% quantile of 50 dof: large-x branch for a << x.
  EXPECT_NEAR(test_stats::chi2_survival(86.66082, 50.0), 0.001, 1e-6);
  EXPECT_DOUBLE_EQ(test_stats::chi2_survival(0.0, 7.0), 1.0);

  EXPECT_NEAR(sidak_alpha(1e-4, 1), 1e-4, 1e-15);
  EXPECT_NEAR(sidak_alpha(1e-4, 100) * 100.0, 1e-4, 1e-8);
}

TEST(KernelStats, ChiSquareTestSeparatesRightFromWrong) {
  TestRng rng(7);
  const int n = 100000, cells = 50;
  std::vector<double> observed(cells, 0.0), expected(cells, double(n) / cells);
  for (int i = 0; i < n; ++i)
    observed[std::min(int(rng.next() * cells), cells - 1)] += 1.0;
  EXPECT_TRUE(chi_square_test(observed, expected).passed(kAlpha))
      << chi_square_test(observed, expected).summary();

  // Tilt the expectation by up to +-10% (same total): must be rejected.
  std::vector<double> wrong = expected;
  for (int i = 0; i < cells; ++i)
    wrong[i] *= 1.0 + 0.1 * (2.0 * i / (cells - 1) - 1.0);
  EXPECT_FALSE(chi_square_test(observed, wrong).passed(kAlpha))
      << chi_square_test(observed, wrong).summary();

  // A sample where the expected count is zero is an immediate failure.
  std::vector<double> hole = expected;
  hole[3] = 0.0;
  hole[4] += expected[3];
  EXPECT_FALSE(chi_square_test(observed, hole).error.empty());
}

// ---------------------------------------------------------------------------
// Warps.

TEST(KernelSampling, ConcentricDiskIsUniform) {
  // Cells uniform in (r^2, phi) have equal area, so a uniform map fills them
  // equally.
  constexpr int kRadial = 16, kAngular = 32, kSamples = 200000;
  TestRng rng(11);
  std::vector<double> observed(kRadial * kAngular, 0.0);
  std::vector<double> expected(kRadial * kAngular, double(kSamples) / (kRadial * kAngular));
  for (int s = 0; s < kSamples; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec2 p = sample_disk_concentric(u1, u2);
    const double r2 = double(p.x) * p.x + double(p.y) * p.y;
    ASSERT_LE(r2, 1.0 + 1e-6);
    double phi = std::atan2(double(p.y), double(p.x));
    if (phi < 0.0) phi += 2.0 * double(kPi);
    const int i = std::min(int(r2 * kRadial), kRadial - 1);
    const int j = std::min(int(phi / (2.0 * double(kPi)) * kAngular), kAngular - 1);
    observed[i * kAngular + j] += 1.0;
  }
  const auto r = test_stats::grid_chi_square(observed, expected, kRadial, kAngular);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
  // The square's centre maps to the disk's centre and edges to the rim.
  const Vec2 c = sample_disk_concentric(0.5f, 0.5f);
  EXPECT_EQ(c.x, 0.0f);
  EXPECT_EQ(c.y, 0.0f);
  const Vec2 e = sample_disk_concentric(1.0f, 0.5f);
  EXPECT_NEAR(e.x, 1.0f, 1e-6f);
  EXPECT_NEAR(e.y, 0.0f, 1e-6f);
}

TEST(KernelSampling, CosineHemisphereFollowsItsPdf) {
  TestRng rng(12);
  const auto r = sphere_chi_square(
      [&](Vec3* d) {
        const float u2 = rng.next(), u1 = rng.next();
        *d = sample_cosine_hemisphere(u1, u2);
        return d->z > 0.0f;
      },
      [](Vec3 d) { return pdf_cosine_hemisphere(d.z); }, 200000, 32, 64, double(kPi) / 2);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);
  EXPECT_EQ(pdf_cosine_hemisphere(-0.5f), 0.0f);
}

TEST(KernelSampling, CosineHemisphereSamplesAreUnitVectors) {
  TestRng rng(13);
  for (int s = 0; s < 10000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec3 d = sample_cosine_hemisphere(u1, u2);
    ASSERT_NEAR(length(d), 1.0f, 1e-5f);
    ASSERT_GE(d.z, 0.0f);
  }
}

TEST(KernelSampling, UniformSphereFollowsItsPdf) {
  TestRng rng(14);
  const auto r = sphere_chi_square(
      [&](Vec3* d) {
        const float u2 = rng.next(), u1 = rng.next();
        *d = sample_uniform_sphere(u1, u2);
        return true;
      },
      [](Vec3) { return kInv4Pi; }, 200000, 32, 64);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);
}

TEST(KernelSampling, TriangleBarycentricsAreUniform) {
  // Split the triangle (b1, b2 >= 0, b1 + b2 <= 1) into k^2 congruent
  // sub-triangles: the square cell (i, j) of side 1/k holds an "lower"
  // triangle (fractional parts sum < 1) and, if i + j < k - 1, an "upper" one.
  constexpr int k = 16, kSamples = 200000;
  TestRng rng(15);
  std::vector<double> observed(k * k * 2, 0.0), expected(k * k * 2, 0.0);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; i + j < k; ++j) {
      expected[(i * k + j) * 2] = double(kSamples) / (k * k);
      if (i + j < k - 1) expected[(i * k + j) * 2 + 1] = double(kSamples) / (k * k);
    }
  }
  for (int s = 0; s < kSamples; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec2 b = sample_triangle_barycentrics(u1, u2);
    ASSERT_GE(b.x, 0.0f);
    ASSERT_GE(b.y, 0.0f);
    ASSERT_LE(b.x + b.y, 1.0f + 1e-6f);
    const double x = double(b.x) * k, y = double(b.y) * k;
    const int i = std::min(int(x), k - 1), j = std::min(int(y), k - 1);
    const bool upper = (x - i) + (y - j) > 1.0;
    observed[(i * k + j) * 2 + (upper ? 1 : 0)] += 1.0;
  }
  const auto r = chi_square_test(observed, expected);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
}

TEST(KernelSampling, EquirectRoundTrip) {
  // uv -> direction -> uv, away from the poles where u is undefined.
  for (int i = 0; i < 64; ++i) {
    for (int j = 1; j < 32; ++j) {
      const float u = (float(i) + 0.37f) / 64.0f, v = float(j) / 32.0f;
      const Vec3 d = equirect_to_direction(u, v);
      ASSERT_NEAR(length(d), 1.0f, 1e-5f);
      const Vec2 uv = direction_to_equirect(d);
      float du = uv.x - u;
      du -= std::round(du);  // u wraps at 0/1
      EXPECT_NEAR(du, 0.0f, 2e-6f) << u << " " << v;
      EXPECT_NEAR(uv.y, v, 2e-6f) << u << " " << v;
      EXPECT_GE(uv.x, 0.0f);
      EXPECT_LT(uv.x, 1.0f);
    }
  }
  // Near the poles v must survive the round trip with relative precision:
  // env_pdf divides by sin(pi v), so an absolute error of 1e-4 in v there is
  // a large pdf error.
  for (float v : {1e-5f, 1e-4f, 1e-3f, 1.0f - 1e-3f, 1.0f - 1e-4f}) {
    const float back = direction_to_equirect(equirect_to_direction(0.3f, v)).y;
    const float theta = std::min(v, 1.0f - v), theta_back = std::min(back, 1.0f - back);
    EXPECT_NEAR(theta_back, theta, 1e-3f * theta) << "v=" << v;
  }
  // direction -> uv -> direction for random directions.
  TestRng rng(16);
  for (int s = 0; s < 10000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec3 d = sample_uniform_sphere(u1, u2);
    const Vec2 uv = direction_to_equirect(d);
    const Vec3 back = equirect_to_direction(uv.x, uv.y);
    ASSERT_NEAR(back.x, d.x, 1e-5f);
    ASSERT_NEAR(back.y, d.y, 1e-5f);
    ASSERT_NEAR(back.z, d.z, 1e-5f);
  }
  // Orientation: v = 0 is +y, u = 0.5 looks down -z, u = 0.75 down +x.
  const Vec3 up = equirect_to_direction(0.3f, 0.0f);
  EXPECT_NEAR(up.y, 1.0f, 1e-6f);
  const Vec3 fwd = equirect_to_direction(0.5f, 0.5f);
  EXPECT_NEAR(fwd.z, -1.0f, 1e-6f);
  const Vec2 uv_x = direction_to_equirect(make_vec3(1.0f, 0.0f, 0.0f));
  EXPECT_NEAR(uv_x.x, 0.75f, 1e-6f);
  EXPECT_NEAR(uv_x.y, 0.5f, 1e-6f);
}

TEST(KernelSampling, EquirectMapHasTheSinThetaJacobian) {
  // Uniform (u, v) mapped to directions has density 1 / (2 pi^2 sin(theta))
  // about the +y pole, the Jacobian env_pdf divides by. Bin in a frame whose
  // pole is +y so the cells line up with the map's rows.
  TestRng rng(17);
  auto to_grid = [](Vec3 d) { return make_vec3(d.z, d.x, d.y); };
  const auto r = sphere_chi_square(
      [&](Vec3* d) {
        const float v = rng.next(), u = rng.next();
        *d = to_grid(equirect_to_direction(u, v));
        return true;
      },
      [](Vec3 g) {
        return 1.0 / (2.0 * double(kPi) * double(kPi) *
                      std::sqrt(std::max(1e-30, 1.0 - double(g.z) * g.z)));
      },
      200000, 32, 64);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
}

TEST(KernelSampling, MisPowerHeuristicWeightsSumToOne) {
  TestRng rng(18);
  for (int s = 0; s < 10000; ++s) {
    const float a = std::exp(80.0f * (rng.next() - 0.5f)),
                b = std::exp(80.0f * (rng.next() - 0.5f));
    const float wa = mis_power_heuristic(a, b), wb = mis_power_heuristic(b, a);
    ASSERT_TRUE(std::isfinite(wa) && std::isfinite(wb));
    ASSERT_NEAR(wa + wb, 1.0f, 1e-5f) << a << " " << b;
    ASSERT_NEAR(wa, a * a / (double(a) * a + double(b) * b), 1e-5) << a << " " << b;
  }
  EXPECT_EQ(mis_power_heuristic(0.0f, 1.0f), 0.0f);
  EXPECT_EQ(mis_power_heuristic(1.0f, 0.0f), 1.0f);
  // Huge but finite pdfs (near-specular lobes) must not overflow to NaN.
  EXPECT_NEAR(mis_power_heuristic(3e38f, 1.0f), 1.0f, 1e-6f);
  EXPECT_NEAR(mis_power_heuristic(1.0f, 3e38f), 0.0f, 1e-6f);
}

// ---------------------------------------------------------------------------
// Alias table.

// Exact probability with which alias_sample returns each index for a uniform
// u, read off the table: slot j keeps j with probability threshold_j and
// otherwise yields alias_j.
std::vector<double> alias_table_probabilities(const std::vector<KAliasEntry>& table) {
  const size_t n = table.size();
  std::vector<double> p(n, 0.0);
  for (size_t j = 0; j < n; ++j) {
    const double keep = std::clamp(double(table[j].threshold), 0.0, 1.0);
    p[j] += keep / double(n);
    p[table[j].alias] += (1.0 - keep) / double(n);
  }
  return p;
}

std::vector<std::vector<double>> alias_weight_vectors() {
  std::vector<std::vector<double>> sets;
  sets.push_back({1.0});
  sets.push_back({1.0, 3.0});
  sets.push_back({0.0, 2.0, 0.0, 1.0, 5.0, 0.0, 0.5});
  sets.push_back({0.0, 0.0, 0.0, 4.0});                             // one non-zero entry
  sets.push_back({1.0, 1.0, 1.0, 1.0, 1.0, 1.0});                   // uniform
  sets.push_back({1e9, 1.0, 2.0, 0.0, 3.0, 1.0, 1e9 * 0.5, 0.25});  // huge weights
  std::mt19937 gen(19);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (size_t n : {64u, 1000u}) {
    std::vector<double> w(n);
    for (double& x : w)
      x = uni(gen) < 0.3 ? 0.0 : std::pow(uni(gen), 3.0) * 10.0;
    w[n / 3] = 5000.0;  // one entry holding a large share of the mass
    sets.push_back(w);
  }
  return sets;
}

TEST(KernelAlias, TableReproducesTheWeights) {
  for (const auto& w : alias_weight_vectors()) {
    const auto table = build_alias_table(w);
    ASSERT_EQ(table.size(), w.size());
    const double sum = std::accumulate(w.begin(), w.end(), 0.0);
    const auto p = alias_table_probabilities(table);
    for (size_t i = 0; i < w.size(); ++i) {
      EXPECT_NEAR(table[i].pdf, w[i] / sum, 1e-7 * std::max(1.0, w[i] / sum * 10.0)) << i;
      EXPECT_LT(table[i].alias, w.size());
      // The table's own sampling probability must equal the pdf it stores.
      EXPECT_NEAR(p[i], w[i] / sum, 1e-6 * (w[i] / sum) + 1e-7)
          << "index " << i << " of " << w.size();
      if (w[i] == 0.0) {
        EXPECT_EQ(p[i], 0.0) << "zero-weight entry " << i << " is reachable";
      }
    }
  }
}

TEST(KernelAlias, SamplesFollowTheWeights) {
  int vector_index = 0;
  for (const auto& w : alias_weight_vectors()) {
    const auto table = build_alias_table(w);
    const double sum = std::accumulate(w.begin(), w.end(), 0.0);
    const uint32_t n = uint32_t(w.size());
    constexpr int kSamples = 200000;
    std::vector<double> observed(n, 0.0), expected(n, 0.0);
    for (uint32_t i = 0; i < n; ++i)
      expected[i] = w[i] / sum * kSamples;
    TestRng rng(100 + vector_index++);
    for (int s = 0; s < kSamples; ++s) {
      float pmf = -1.0f;
      const uint32_t i = alias_sample(table.data(), n, rng.next(), &pmf);
      ASSERT_LT(i, n);
      // The pmf returned is the built pdf of the returned index.
      ASSERT_EQ(pmf, table[i].pdf);
      observed[i] += 1.0;
    }
    const auto r = chi_square_test(observed, expected);
    EXPECT_TRUE(r.passed(kAlpha)) << "weights #" << vector_index - 1 << ": " << r.summary();
  }
}

TEST(KernelAlias, ExtremeUniformNumbersStayInRange) {
  const auto table = build_alias_table({1.0, 0.0, 2.0});
  for (float u : {0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 0.99999994f, std::nextafter(1.0f, 0.0f)}) {
    float pmf = 0.0f;
    const uint32_t i = alias_sample(table.data(), 3, u, &pmf);
    ASSERT_LT(i, 3u);
    EXPECT_NE(i, 1u) << "zero-weight entry returned for u=" << u;
    EXPECT_GT(pmf, 0.0f);
  }
}

TEST(KernelAlias, AllZeroWeightsFallBackToUniform) {
  // Documented fallback of build_alias_table: a valid uniform table.
  const auto table = build_alias_table({0.0, 0.0, 0.0, 0.0});
  const auto p = alias_table_probabilities(table);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(p[i], 0.25, 1e-7);
    EXPECT_NEAR(table[i].pdf, 0.25f, 1e-7f);
  }
}

}  // namespace
}  // namespace tandem
