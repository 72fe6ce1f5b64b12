// Tests of the GGX distribution, Smith masking, visible-normal sampling and
// the Fresnel/refraction helpers in core/kernel/microfacet.h against their
// defining integrals and closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/kernel/microfacet.h"
#include "core/kernel/sampling.h"
#include "test_stats.h"

namespace tandem {
namespace {

using test_stats::sidak_alpha;
using test_stats::TestRng;

constexpr float kAlphas[] = {0.05f, 0.25f, 0.64f, 1.0f};
constexpr float kViewDegrees[] = {0.0f, 30.0f, 60.0f, 85.0f};

Vec3 view_direction(float degrees) {
  const float t = degrees * kPi / 180.0f;
  return make_vec3(sinf(t) * cosf(0.7f), sinf(t) * sinf(0.7f), cosf(t));
}

// Integral of f over [a, b] with 4-point Gauss-Legendre on geometrically
// shrinking pieces towards a: resolves a peak of width `scale` at a without
// knowing its shape.
template <class F>
double integrate_towards(const F& f, double a, double b, double scale) {
  std::vector<double> breaks = {b};
  for (double x = scale * 64.0; x > scale * 1e-4; x *= 0.5) {
    if (a + x < b) breaks.push_back(a + x);
  }
  breaks.push_back(a);
  std::sort(breaks.begin(), breaks.end());
  double sum = 0.0;
  for (size_t i = 0; i + 1 < breaks.size(); ++i) {
    // Each piece split into 16 so smooth but wide pieces are exact too.
    const double lo = breaks[i], width = (breaks[i + 1] - lo) / 16.0;
    for (int k = 0; k < 16; ++k) {
      const double c = lo + (k + 0.5) * width, h = 0.5 * width;
      for (int g = 0; g < 4; ++g)
        sum += test_stats::kGaussW[g] * h * f(c + h * test_stats::kGaussX[g]);
    }
  }
  return sum;
}

TEST(KernelGgx, DistributionIsNormalized) {
  // Projected microfacet area equals the macro surface: int D(m) m.z dm = 1.
  for (float alpha : {kMinGgxAlpha, 0.05f, 0.25f, 0.64f, 1.0f}) {
    for (double phi : {0.0, 0.3, 2.5}) {
      const double integral = integrate_towards(
          [&](double theta) {
            const Vec3 m = test_stats::spherical_direction(theta, phi);
            return 2.0 * double(kPi) * double(ggx_d(m, alpha)) * std::cos(theta) * std::sin(theta);
          },
          0.0, double(kPi) / 2.0, alpha);
      EXPECT_NEAR(integral, 1.0, 1e-4) << "alpha=" << alpha << " phi=" << phi;
    }
    EXPECT_NEAR(ggx_d(make_vec3(0, 0, 1), alpha), 1.0f / (kPi * alpha * alpha),
                1e-4f / (kPi * alpha * alpha));
    EXPECT_EQ(ggx_d(make_vec3(0, 0, -1), alpha), 0.0f);
  }
}

TEST(KernelGgx, SmithMaskingMatchesClosedForm) {
  for (float alpha : {kMinGgxAlpha, 0.05f, 0.25f, 0.64f, 1.0f}) {
    for (float deg : {0.0f, 10.0f, 45.0f, 80.0f, 89.0f}) {
      const Vec3 w = view_direction(deg);
      const double tan2 = (1.0 - double(w.z) * w.z) / (double(w.z) * w.z);
      const double g1 = 2.0 / (1.0 + std::sqrt(1.0 + double(alpha) * alpha * tan2));
      EXPECT_NEAR(ggx_g1(w, alpha), g1, 1e-5 * g1) << alpha << " " << deg;
      for (float deg2 : {5.0f, 50.0f, 85.0f}) {
        const Vec3 v = view_direction(deg2);
        const float g2 = ggx_g2(w, v, alpha);
        // Height-correlated G2 lies between the uncorrelated product and the
        // smaller of the two G1.
        EXPECT_LE(g2, std::min(ggx_g1(w, alpha), ggx_g1(v, alpha)) * (1.0f + 1e-6f));
        EXPECT_GE(g2, ggx_g1(w, alpha) * ggx_g1(v, alpha) * (1.0f - 1e-6f));
      }
    }
  }
}

TEST(KernelGgx, VisibleNormalDensityIntegratesToOne) {
  // int G1(wo) max(0, wo.m) D(m) / wo.z dm = 1 is the definition of G1 for
  // Smith masking; it checks D, Lambda and ggx_visible_pdf together.
  for (float alpha : kAlphas) {
    for (float deg : {0.0f, 30.0f, 60.0f, 85.0f, 89.0f}) {
      const Vec3 wo = view_direction(deg);
      constexpr int kTheta = 64, kPhi = 32;
      double total = 0.0;
      for (int i = 0; i < kTheta; ++i) {
        for (int j = 0; j < kPhi; ++j) {
          total += test_stats::integrate_cell(
              [&](Vec3 m) { return ggx_visible_pdf(wo, m, alpha); }, i * double(kPi) / 2.0 / kTheta,
              (i + 1) * double(kPi) / 2.0 / kTheta, j * 2.0 * double(kPi) / kPhi,
              (j + 1) * 2.0 * double(kPi) / kPhi, 1e8);
        }
      }
      EXPECT_NEAR(total, 1.0, 1e-3) << "alpha=" << alpha << " wo=" << deg << "deg";
    }
  }
}

TEST(KernelGgx, VisibleNormalSamplingFollowsItsPdf) {
  const double alpha_level = sidak_alpha(test_stats::kFamilySignificance, 16);
  int seed = 300;
  for (float alpha : kAlphas) {
    for (float deg : kViewDegrees) {
      const Vec3 wo = view_direction(deg);
      TestRng rng(uint32_t(seed++));
      bool hidden = false;
      const auto r = test_stats::sphere_chi_square(
          [&](Vec3* m) {
            const float u2 = rng.next(), u1 = rng.next();
            *m = ggx_sample_visible_normal(wo, alpha, u1, u2);
            // Visible normals face wo (up to rounding).
            if (dot(*m, wo) < -1e-5f || m->z <= 0.0f) hidden = true;
            return true;
          },
          [&](Vec3 m) { return ggx_visible_pdf(wo, m, alpha); }, 100000, 32, 64, double(kPi) / 2.0);
      EXPECT_TRUE(r.passed(alpha_level)) << "alpha=" << alpha << " wo=" << deg << "deg\n"
                                         << r.summary();
      EXPECT_FALSE(hidden) << "sampled a back-facing normal, alpha=" << alpha << " wo=" << deg;
    }
  }
}

TEST(KernelGgx, AlphaFromRoughness) {
  EXPECT_EQ(ggx_alpha_from_roughness(0.0f), kMinGgxAlpha);
  EXPECT_FLOAT_EQ(ggx_alpha_from_roughness(0.5f), 0.25f);
  EXPECT_FLOAT_EQ(ggx_alpha_from_roughness(1.0f), 1.0f);
}

// ---------------------------------------------------------------------------
// Fresnel and refraction.

// Unpolarised Fresnel reflectance in double precision from Snell's law.
// `cos_t2_offset` perturbs cos^2 of the refracted angle, to measure how much
// float rounding of that quantity moves F (without bound at the critical
// angle, where cos_t -> 0).
double reference_fresnel(double cos_i, double eta, double cos_t2_offset = 0.0) {
  const double cos_t2 = 1.0 - (1.0 - cos_i * cos_i) / (eta * eta) + cos_t2_offset;
  if (cos_t2 <= 0.0) return 1.0;
  const double cos_t = std::sqrt(cos_t2);
  const double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  return 0.5 * (rs * rs + rp * rp);
}

constexpr float kEtas[] = {1.1f,        1.33f,        1.5f,        2.4f,
                           1.0f / 1.1f, 1.0f / 1.33f, 1.0f / 1.5f, 1.0f / 2.4f};

TEST(KernelFresnel, NormalIncidence) {
  for (float eta : kEtas) {
    const double f0 = std::pow((double(eta) - 1.0) / (double(eta) + 1.0), 2.0);
    EXPECT_NEAR(fresnel_dielectric(1.0f, eta), f0, 1e-6) << eta;
  }
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
}

TEST(KernelFresnel, TotalInternalReflectionBeyondCriticalAngle) {
  for (float eta : kEtas) {
    if (eta >= 1.0f) continue;
    const double cos_critical = std::sqrt(1.0 - double(eta) * eta);
    for (int i = 0; i <= 100; ++i) {
      const float cos_i = float(cos_critical * (1.0 - 1e-4) * i / 100.0);
      EXPECT_EQ(fresnel_dielectric(cos_i, eta), 1.0f) << "eta=" << eta << " cos=" << cos_i;
    }
    // Just inside the critical angle light is partly transmitted.
    const float inside = float(cos_critical + 0.01 * (1.0 - cos_critical));
    EXPECT_LT(fresnel_dielectric(inside, eta), 1.0f) << eta;
  }
}

TEST(KernelFresnel, InUnitIntervalAndMatchesReference) {
  for (float eta : {0.2f, 0.5f, 0.9f, 0.999f, 1.001f, 1.2f, 1.5f, 3.0f, 5.0f}) {
    float previous = 2.0f;
    for (int i = 0; i <= 1000; ++i) {
      const float cos_i = float(i) / 1000.0f;
      const float f = fresnel_dielectric(cos_i, eta);
      ASSERT_TRUE(f >= 0.0f && f <= 1.0f) << "F=" << f << " eta=" << eta << " cos=" << cos_i;
      const double ref = reference_fresnel(cos_i, eta);
      // Allowed error: float rounding of cos_t^2 (a few ulps of 1).
      const double conditioning = std::fabs(reference_fresnel(cos_i, eta, 4e-7) - ref) +
                                  std::fabs(reference_fresnel(cos_i, eta, -4e-7) - ref);
      ASSERT_NEAR(f, ref, 2e-5 + conditioning) << "eta=" << eta << " cos=" << cos_i;
      // External reflection off glass-like media never grows as incidence
      // gets closer to normal. (Not a law in general: internal reflection and
      // very dense media have a shallow dip near Brewster's angle.)
      if (eta > 1.0f && eta <= 1.5f) {
        ASSERT_LE(f, previous + 1e-6f) << "eta=" << eta << " cos=" << cos_i;
      }
      previous = f;
    }
    // Grazing incidence reflects everything.
    EXPECT_NEAR(fresnel_dielectric(0.0f, eta), 1.0f, 1e-6f) << eta;
  }
  // Out-of-range cosines are clamped, not extrapolated.
  EXPECT_EQ(fresnel_dielectric(1.5f, 1.5f), fresnel_dielectric(1.0f, 1.5f));
  EXPECT_EQ(fresnel_dielectric(-0.5f, 1.5f), fresnel_dielectric(0.0f, 1.5f));
}

TEST(KernelFresnel, SameFromBothSides) {
  // Transmittance is reciprocal: F(cos_i, eta) = F(cos_t, 1 / eta).
  for (float eta : {1.33f, 1.5f, 2.4f}) {
    for (int i = 1; i <= 100; ++i) {
      const float cos_i = float(i) / 100.0f;
      const float cos_t = sqrtf(1.0f - (1.0f - cos_i * cos_i) / (eta * eta));
      // Float rounding of cos_t matters near grazing, where dF/dcos is large.
      EXPECT_NEAR(fresnel_dielectric(cos_i, eta), fresnel_dielectric(cos_t, 1.0f / eta), 1e-4f)
          << eta << " " << cos_i;
    }
  }
}

TEST(KernelFresnel, SchlickEndpoints) {
  const Vec3 f0 = make_vec3(0.9f, 0.5f, 0.04f);
  const Vec3 at_normal = fresnel_schlick(f0, 1.0f), at_grazing = fresnel_schlick(f0, 0.0f);
  EXPECT_FLOAT_EQ(at_normal.x, 0.9f);
  EXPECT_FLOAT_EQ(at_normal.z, 0.04f);
  EXPECT_FLOAT_EQ(at_grazing.y, 1.0f);
  EXPECT_FLOAT_EQ(at_grazing.z, 1.0f);
}

TEST(KernelFresnel, RefractionObeysSnell) {
  TestRng rng(61);
  for (float eta : kEtas) {
    for (int s = 0; s < 2000; ++s) {
      const float uy = rng.next(), ux = rng.next();
      const Vec3 m = normalize(make_vec3(0.3f * (ux - 0.5f), 0.3f * (uy - 0.5f), 1.0f));
      const float u2 = rng.next(), u1 = rng.next();
      const Vec3 w = sample_uniform_sphere(0.5f * u1, u2);  // upper hemisphere
      const float cos_i = dot(w, m);
      if (cos_i <= 1e-3f) continue;
      Vec3 t = make_vec3(0.0f);
      const bool ok = refract_dir(w, m, eta, &t);
      // refract_dir fails exactly when Fresnel reports total reflection.
      const bool tir = (1.0f - cos_i * cos_i) / (eta * eta) >= 1.0f;
      ASSERT_EQ(ok, !tir) << eta << " " << cos_i;
      if (!ok) {
        ASSERT_EQ(fresnel_dielectric(cos_i, eta), 1.0f);
        continue;
      }
      ASSERT_NEAR(length(t), 1.0f, 1e-4f);
      ASSERT_LT(dot(t, m), 0.0f);  // crosses the interface
      // Snell: eta sin_t = sin_i, and t stays in the plane of w and m.
      const float sin_i = length(cross(w, m)), sin_t = length(cross(t, m));
      ASSERT_NEAR(eta * sin_t, sin_i, 2e-4f) << eta;
      ASSERT_NEAR(dot(cross(w, m), t), 0.0f, 2e-4f);
      ASSERT_GT(dot(cross(w, m), cross(-t, m)), -1e-4f);  // same side of m
    }
  }
}

}  // namespace
}  // namespace tandem
