// Statistical and analytic tests of the glTF BSDF (core/kernel/bsdf.h) over a
// grid of materials and view angles: bsdf_sample must draw directions with
// exactly the density bsdf_eval reports, return weight = f |cos| / pdf, and
// conserve energy. Reciprocity and support checks catch asymmetric or
// unreachable lobes.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "core/kernel/bsdf.h"
#include "test_stats.h"
#include "tests/kernel_bsdf_test_util.h"

namespace tandem {
namespace {

using bsdf_test::describe;
using bsdf_test::sample_moments;
using bsdf_test::upper_normal_quantile;
using bsdf_test::view_direction;
using test_stats::MeanAccumulator;
using test_stats::sidak_alpha;
using test_stats::TestRng;

// Perceptual roughness values; alpha = roughness^2 gives 0.05, 0.25, 0.64, 1.
constexpr float kRoughness[] = {0.2236068f, 0.5f, 0.8f, 1.0f};
constexpr float kViewDegrees[] = {0.0f, 30.0f, 60.0f, 85.0f};

// Every distinct material of the grid metallic {0, .5, 1} x transmission
// {0, .5, 1} x eta {1.5, 1/1.5} x specular {0, .5, 1} x specular colour
// {white, coloured} x base {white, coloured, black}, with alpha left unset.
// Combinations that cannot differ are dropped (a full metal ignores the
// dielectric parameters; specular colour needs specular > 0; eta < 1 occurs
// only on the inside of transmissive materials).
std::vector<BsdfParams> distinct_materials() {
  const Vec3 bases[] = {make_vec3(1.0f), make_vec3(0.9f, 0.5f, 0.2f), make_vec3(0.0f)};
  const Vec3 spec_colors[] = {make_vec3(1.0f), make_vec3(0.9f, 0.6f, 0.3f)};
  std::vector<BsdfParams> out;
  for (const Vec3& base : bases) {
    for (float metallic : {0.0f, 0.5f, 1.0f}) {
      for (float transmission : {0.0f, 0.5f, 1.0f}) {
        for (float eta : {1.5f, 1.0f / 1.5f}) {
          for (float specular : {0.0f, 0.5f, 1.0f}) {
            for (int sc = 0; sc < 2; ++sc) {
              const bool dielectric_varies =
                  transmission != 0.0f || eta != 1.5f || specular != 0.0f || sc != 0;
              if (metallic == 1.0f && dielectric_varies) continue;
              if (specular == 0.0f && sc != 0) continue;
              // Opaque surfaces always see air on the outside: setup_shading
              // only inverts eta when leaving a transmissive object.
              if (transmission == 0.0f && eta != 1.5f) continue;
              BsdfParams p;
              p.base_color = base;
              p.metallic = metallic;
              p.specular_color = spec_colors[sc];
              p.alpha = 1.0f;
              p.transmission = transmission;
              p.eta = eta;
              p.specular = specular;
              out.push_back(p);
            }
          }
        }
      }
    }
  }
  return out;
}

struct BsdfCase {
  BsdfParams p;
  Vec3 wo;
};

// Every material x roughness x view angle; `smooth` adds roughness 0
// (alpha clamped to kMinGgxAlpha), which only the moment tests can handle.
std::vector<BsdfCase> full_grid(bool smooth) {
  std::vector<float> roughness(std::begin(kRoughness), std::end(kRoughness));
  if (smooth) roughness.insert(roughness.begin(), 0.0f);
  std::vector<BsdfCase> out;
  for (const BsdfParams& m : distinct_materials()) {
    for (float r : roughness) {
      for (float deg : kViewDegrees) {
        BsdfCase c{m, view_direction(deg)};
        c.p.alpha = ggx_alpha_from_roughness(r);
        out.push_back(c);
      }
    }
  }
  return out;
}

// The chi-square subset: every material once, cycling through the 16
// (roughness, view angle) pairs so each pair is covered ~14 times, plus the
// full metal with every pair. The complete grid (2832 cases) would cost
// over a minute; the cheap per-sample checks below do run on all of it.
std::vector<BsdfCase> chi_square_cases() {
  std::vector<BsdfCase> out;
  int k = 0;
  for (const BsdfParams& m : distinct_materials()) {
    const int pairs = m.metallic == 1.0f ? 16 : 1;
    for (int i = 0; i < pairs; ++i, ++k) {
      BsdfCase c{m, view_direction(kViewDegrees[k % 4])};
      c.p.alpha = ggx_alpha_from_roughness(kRoughness[(k / 4) % 4]);
      out.push_back(c);
    }
  }
  return out;
}

const std::vector<BsdfCase> kChiSquareCases = chi_square_cases();
// One family for every chi-square test in this file.
const double kChiSquareAlpha =
    sidak_alpha(test_stats::kFamilySignificance, int(kChiSquareCases.size()));

// ---------------------------------------------------------------------------
// (1) bsdf_sample follows bsdf_eval's pdf, including its total mass.

TEST(KernelBsdf, SampledDirectionsFollowEvalPdf) {
  std::vector<test_stats::SphereTestResult> results(kChiSquareCases.size());
  test_stats::parallel_for(int(kChiSquareCases.size()), [&](int index) {
    const BsdfCase& c = kChiSquareCases[size_t(index)];
    results[size_t(index)] =
        bsdf_test::sampled_directions_chi_square(c.p, c.wo, 1000 + uint32_t(index));
  });
  for (size_t i = 0; i < results.size(); ++i) {
    const BsdfCase& c = kChiSquareCases[i];
    const auto& r = results[i];
    EXPECT_TRUE(r.passed(kChiSquareAlpha)) << describe(c.p, c.wo) << "\n" << r.summary();
    // Mass the sampler produces == integral of the pdf (the chi-square's
    // failure cell tests this too; this states it directly). 1e5 samples give
    // a binomial standard error of at most 0.0016.
    EXPECT_NEAR(r.success_fraction, r.pdf_integral, 0.01) << describe(c.p, c.wo);
  }
}

// ---------------------------------------------------------------------------
// (2) Per-sample consistency, (3) energy conservation, over the full grid.

// Whether a Lambertian base sits under the dielectric specular layer. The
// glTF model weights that base by 1 - F(wo.h) per direction (the spec's
// fresnel_mix) rather than by the layer's directional albedo, which is not
// energy conserving at grazing angles; such cases are tested separately so
// the failure is reported as what it is.
bool diffuse_under_specular_layer(const BsdfParams& p) {
  return p.metallic < 1.0f && p.specular > 0.0f && p.transmission < 1.0f && !is_black(p.base_color);
}

constexpr int kMomentSamples = 4096;
const std::vector<BsdfCase> kFullGrid = full_grid(/*smooth=*/true);
// Sidak over every (case, channel) upper bound of the energy tests.
const double kAlbedoZ =
    upper_normal_quantile(sidak_alpha(test_stats::kFamilySignificance, int(kFullGrid.size()) * 3));

// Runs every case of the full grid matching `filter`, reports samples that
// disagree with bsdf_eval and albedos above 1 + statistical margin (1e-5
// absorbs float rounding of weights that are exactly 1, e.g. smooth glass).
void check_albedo(bool (*filter)(const BsdfParams&)) {
  std::vector<size_t> picked;
  for (size_t i = 0; i < kFullGrid.size(); ++i) {
    if (filter(kFullGrid[i].p)) picked.push_back(i);
  }
  ASSERT_FALSE(picked.empty());
  std::vector<bsdf_test::SampleMoments> results(picked.size());
  test_stats::parallel_for(int(picked.size()), [&](int k) {
    const BsdfCase& c = kFullGrid[picked[size_t(k)]];
    results[size_t(k)] =
        sample_moments(c.p, c.wo, 50000 + uint32_t(picked[size_t(k)]), kMomentSamples);
  });
  int inconsistent = 0, too_bright = 0;
  for (size_t k = 0; k < picked.size(); ++k) {
    const BsdfCase& c = kFullGrid[picked[k]];
    if (!results[k].error.empty() && inconsistent++ < 10) ADD_FAILURE() << results[k].error;
    for (int ch = 0; ch < 3; ++ch) {
      const MeanAccumulator& a = results[k].albedo[ch];
      if (a.mean() > 1.0 + kAlbedoZ * a.std_error() + 1e-5 && too_bright++ < 30) {
        ADD_FAILURE() << "flux albedo[" << ch << "] = " << a.mean() << " +- " << a.std_error()
                      << " > 1 for " << describe(c.p, c.wo);
      }
    }
  }
  EXPECT_EQ(inconsistent, 0) << "cases where bsdf_sample disagrees with bsdf_eval";
  EXPECT_EQ(too_bright, 0) << "(case, channel) pairs whose albedo exceeds 1, of "
                           << picked.size() * 3;
}

TEST(KernelBsdf, SampleAgreesWithEvalAndAlbedoAtMostOne) {
  check_albedo([](const BsdfParams& p) { return !diffuse_under_specular_layer(p); });
}

// The diffuse base under the dielectric layer is normalised by the layer's
// hemispherical Fresnel average (bsdf.h). glTF's fresnel_mix(VdotH) weighting
// failed this test by up to 1.5x at grazing view.
TEST(KernelBsdf, DiffuseUnderSpecularLayerAlbedoAtMostOne) {
  check_albedo([](const BsdfParams& p) { return diffuse_under_specular_layer(p); });
}

TEST(KernelBsdf, LambertianAlbedoEqualsBaseColor) {
  for (const BsdfCase& c : full_grid(true)) {
    if (c.p.metallic != 0.0f || c.p.specular != 0.0f || c.p.transmission != 0.0f) continue;
    TestRng rng(7);
    for (int s = 0; s < 256; ++s) {
      BsdfSample bs;
      const bool black = is_black(c.p.base_color);
      const float u2 = rng.next(), u1 = rng.next(), ul = rng.next();
      const bool ok = bsdf_sample(c.p, c.wo, ul, u1, u2, &bs);
      if (black) {
        // Nothing to sample: a black Lambertian surface absorbs everything.
        ASSERT_FALSE(ok && !is_black(bs.weight)) << describe(c.p, c.wo);
        continue;
      }
      ASSERT_TRUE(ok) << describe(c.p, c.wo);
      // Cosine sampling of f = base / pi makes every weight the base colour.
      ASSERT_NEAR(bs.weight.x, c.p.base_color.x, 1e-5f) << describe(c.p, c.wo);
      ASSERT_NEAR(bs.weight.y, c.p.base_color.y, 1e-5f) << describe(c.p, c.wo);
      ASSERT_NEAR(bs.weight.z, c.p.base_color.z, 1e-5f) << describe(c.p, c.wo);
      ASSERT_NEAR(bs.pdf, bs.wi.z / kPi, 1e-5f) << describe(c.p, c.wo);
    }
  }
}

// Only materials whose every lobe is GGX at the smallest alpha count as
// near-specular (the integrator samples no area light there).
TEST(KernelBsdf, NearSpecularOnlyForSmoothMirrorsGlassAndCoats) {
  const Vec3 wo = view_direction(30.0f);
  auto near_specular = [&](const BsdfParams& p) {
    return bsdf_near_specular(p, bsdf_lobe_probabilities(p, wo));
  };
  BsdfParams mirror{};  // zero but for what is set
  mirror.base_color = make_vec3(0.9f);
  mirror.metallic = 1.0f;
  mirror.alpha = ggx_alpha_from_roughness(0.0f);
  mirror.eta = 1.5f;
  EXPECT_TRUE(near_specular(mirror));
  BsdfParams rough = mirror;
  rough.alpha = ggx_alpha_from_roughness(0.1f);
  EXPECT_FALSE(near_specular(rough));
  BsdfParams glass{};
  glass.base_color = make_vec3(1.0f);
  glass.metallic = 0.0f;
  glass.specular = 1.0f;
  glass.specular_color = make_vec3(1.0f);
  glass.transmission = 1.0f;
  glass.eta = 1.5f;
  glass.alpha = ggx_alpha_from_roughness(0.0f);
  EXPECT_TRUE(near_specular(glass));
  BsdfParams plastic = glass;  // smooth coat over a diffuse base
  plastic.transmission = 0.0f;
  EXPECT_FALSE(near_specular(plastic));
  BsdfParams lambert{};
  lambert.base_color = make_vec3(0.5f);
  lambert.metallic = 0.0f;
  lambert.specular = 0.0f;
  lambert.alpha = 1.0f;
  EXPECT_FALSE(near_specular(lambert));
}

TEST(KernelBsdf, SmoothDielectricConservesEnergyAndSplitsByFresnel) {
  // Roughness 0 glass (alpha = kMinGgxAlpha) with the full dielectric layer:
  // reflected + transmitted flux must be 1, and the reflected share must be
  // the Fresnel reflectance of the interface.
  constexpr int kSamples = 20000;
  for (float eta : {1.5f, 1.0f / 1.5f}) {
    for (float deg : {0.0f, 20.0f, 40.0f, 45.0f, 60.0f, 85.0f}) {
      BsdfParams p;
      p.base_color = make_vec3(1.0f);
      p.metallic = 0.0f;
      p.specular_color = make_vec3(1.0f);
      p.alpha = ggx_alpha_from_roughness(0.0f);
      p.transmission = 1.0f;
      p.eta = eta;
      p.specular = 1.0f;
      const Vec3 wo = view_direction(deg);
      TestRng rng(31);
      MeanAccumulator total, reflected;
      int off_direction = 0;
      for (int s = 0; s < kSamples; ++s) {
        BsdfSample bs;
        double w = 0.0, r = 0.0;
        const float u2 = rng.next(), u1 = rng.next(), ul = rng.next();
        if (bsdf_sample(p, wo, ul, u1, u2, &bs)) {
          const bool transmit = bs.wi.z < 0.0f;
          w = luminance(bs.weight) * (transmit ? eta * eta : 1.0f);
          r = transmit ? 0.0 : luminance(bs.weight);
          // Directions: the mirror direction, or Snell's law. GGX's long
          // tails put a few samples further off even at alpha = 1e-3.
          const float sin_i = sqrtf(1.0f - wo.z * wo.z), sin_o = sqrtf(1.0f - bs.wi.z * bs.wi.z);
          if (fabsf(transmit ? sin_o * eta - sin_i : bs.wi.z - wo.z) > 0.05f) ++off_direction;
        }
        total.add(w);
        reflected.add(r);
      }
      EXPECT_LT(off_direction, kSamples / 100) << describe(p, wo);
      EXPECT_NEAR(total.mean(), 1.0, 6.0 * total.std_error() + 2e-3) << describe(p, wo);
      const double fresnel = fresnel_dielectric(wo.z, eta);
      EXPECT_NEAR(reflected.mean(), fresnel, 6.0 * reflected.std_error() + 2e-3) << describe(p, wo);
    }
  }
}

// ---------------------------------------------------------------------------
// (4) Reciprocity and support.

TEST(KernelBsdf, ReflectionIsReciprocal) {
  // Every term of the reflection branch (D, height-correlated G2, Fresnel at
  // wo.h = wi.h, the diffuse layer weight) is symmetric, so f(wo, wi) must be
  // f(wi, wo) for every material, including the metal and diffuse-only ones.
  TestRng rng(41);
  for (const BsdfCase& c : full_grid(false)) {
    for (int s = 0; s < 16; ++s) {
      // Two random upper-hemisphere directions (u1 < 0.5 gives z > 0).
      const float wa_u2 = rng.next(), wa_u1 = rng.next();
      const Vec3 wa = sample_uniform_sphere(0.4995f * wa_u1, wa_u2);
      const float wb_u2 = rng.next(), wb_u1 = rng.next();
      const Vec3 wb = sample_uniform_sphere(0.4995f * wb_u1, wb_u2);
      const Vec3 f1 = bsdf_eval(c.p, wa, wb).f;
      const Vec3 f2 = bsdf_eval(c.p, wb, wa).f;
      for (int k = 0; k < 3; ++k) {
        const float x = component(f1, k), y = component(f2, k);
        ASSERT_NEAR(x, y, 1e-4f * std::max(x, y) + 1e-6f) << describe(c.p, c.wo);
      }
    }
  }
}

TEST(KernelBsdf, TransmissionObeysGeneralizedReciprocity) {
  // For a radiance-form BTDF, f(wo, wi; eta) * eta^2 = f(-wi, -wo; 1 / eta)
  // (Veach 1997, sec. 5.2): swapping the roles of the two sides.
  TestRng rng(42);
  int evaluated = 0, nonzero = 0;
  for (const BsdfCase& c : full_grid(false)) {
    if (c.p.transmission == 0.0f || c.p.metallic == 1.0f) continue;
    BsdfParams back = c.p;
    back.eta = 1.0f / c.p.eta;
    for (int s = 0; s < 64; ++s) {
      const float u2 = rng.next(), u1 = rng.next();
      const Vec3 wi = sample_uniform_sphere(0.5f + 0.5f * u1, u2);  // lower hemisphere
      if (!(wi.z < -1e-3f)) continue;
      const Vec3 f1 = bsdf_eval(c.p, c.wo, wi).f;
      const Vec3 f2 = bsdf_eval(back, -wi, -c.wo).f;
      ++evaluated;
      if (!is_black(f1)) ++nonzero;
      for (int k = 0; k < 3; ++k) {
        const float x = component(f1, k) * c.p.eta * c.p.eta, y = component(f2, k);
        // What is left is float rounding: the forward and the reverse
        // evaluation form the half vector and the Fresnel term from
        // differently rounded inputs. Measured over 20000 directions per
        // case (seed 4242, 480 cases per view angle), 1e-3 * max + 1e-6
        // was exceeded 868 times in 2.0M nonzero components at 85 deg
        // (about 3 expected in this test's 64 directions: it passed by the
        // luck of the draw), 72 times at 30 deg and 6 at 60 deg. Two kinds:
        // near the edge of the refraction cone one side cuts off to 0 where
        // the other is still positive (up to 2e-6 at 30 deg, 5e-5 at
        // 85 deg), and at 85 deg the two differ by up to 6e-2 of the value
        // (both positive, above 1e-3). With 1e-3 * max + 1e-5, and
        // 1e-1 * max + 1e-4 for grazing views, 60000 directions per case
        // under three seeds used at most 62% (30 deg) and 83% (85 deg) of
        // the tolerance. A wrong factor (eta^2, a cosine) is far larger.
        const bool grazing = c.wo.z < 0.17f;
        const float rel = grazing ? 1e-1f : 1e-3f, abs_floor = grazing ? 1e-4f : 1e-5f;
        ASSERT_NEAR(x, y, rel * std::max(x, y) + abs_floor)
            << describe(c.p, c.wo) << " wi.z=" << wi.z;
      }
    }
  }
  // Not vacuous. Uniform wi mostly miss the refraction cone (for eta = 1.5
  // it spans only 1 - cos(41.8 deg) of the hemisphere), and a third of the
  // cases have a black base, so about 1 pair in 6 carries light.
  EXPECT_GT(nonzero, evaluated / 10) << nonzero << " of " << evaluated;
}

TEST(KernelBsdf, SamplerCoversTheBsdfSupport) {
  // A direction with f > 0 but pdf == 0 can never be produced by
  // bsdf_sample, so paths through it are missing from every BSDF-sampled
  // estimate (an energy loss, not noise).
  TestRng rng(43);
  int reported = 0;
  for (const BsdfCase& c : full_grid(false)) {
    for (int s = 0; s < 256; ++s) {
      const float u2 = rng.next(), u1 = rng.next();
      const Vec3 wi = sample_uniform_sphere(u1, u2);
      const BsdfEval e = bsdf_eval(c.p, c.wo, wi);
      if (max_component(e.f) > 0.0f && !(e.pdf > 0.0f) && reported++ < 20) {
        ADD_FAILURE() << "f=(" << e.f.x << "," << e.f.y << "," << e.f.z << ") but pdf=" << e.pdf
                      << " at wi=(" << wi.x << "," << wi.y << "," << wi.z << ") for "
                      << describe(c.p, c.wo);
      }
    }
  }
}

}  // namespace
}  // namespace tandem
