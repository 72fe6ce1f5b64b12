// The integrator's shortcuts must give what the general code gives: the
// unpaired 1-D draw the same numbers as rng_1d, a single-lobe BSDF the same
// sample whatever the lobe number, and the Lambertian evaluation the
// Lambertian value and pdf.
#include <gtest/gtest.h>

#include <cstring>

#include "core/kernel/bsdf.h"
#include "core/kernel/rng.h"

namespace tandem {
namespace {

bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(KernelFastPaths, UnpairedDrawIsRng1d) {
  for (uint32_t pixel : {0u, 7u, 123456u}) {
    for (uint32_t sample = 0; sample < 64; ++sample) {
      const PathRng r = make_path_rng(pixel, sample, 3);
      for (uint32_t bounce = 0; bounce < 20; ++bounce) {
        for (uint32_t which : {kBounceLightSelect, kBounceLobe, kBounceRoulette}) {
          const uint32_t dim = bounce_dimension(bounce, which);
          ASSERT_TRUE(same_bits(rng_1d_unpaired(r, dim), rng_1d(r, dim)))
              << "pixel " << pixel << " sample " << sample << " dimension " << dim;
        }
      }
    }
  }
}

BsdfParams lambertian() {
  BsdfParams p{};
  p.base_color = {0.7f, 0.5f, 0.3f};
  p.metallic = 0.0f;
  p.specular_color = {1.0f, 1.0f, 1.0f};
  p.alpha = 0.25f;
  p.transmission = 0.0f;
  p.eta = 1.5f;
  p.specular = 0.0f;
  return p;
}

TEST(KernelFastPaths, SingleLobeBsdfsAreRecognised) {
  const Vec3 wo = normalize(make_vec3(0.3f, -0.2f, 0.9f));
  BsdfParams p = lambertian();
  EXPECT_TRUE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p.metallic = 1.0f;  // a conductor: reflection only
  EXPECT_TRUE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p = lambertian();
  p.specular = 0.5f;  // plastic: diffuse and reflection
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p.transmission = 1.0f;  // glass: reflection and transmission
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p = lambertian();
  p.clearcoat = 0.5f;  // a coat over diffuse
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
}

// For a single-lobe BSDF, u_lobe = 0 (what the integrator passes) samples
// exactly what any other u_lobe samples.
TEST(KernelFastPaths, SingleLobeSampleDoesNotDependOnTheLobeNumber) {
  BsdfParams mirror = lambertian();
  mirror.metallic = 1.0f;
  mirror.alpha = 0.05f;
  for (const BsdfParams& p : {lambertian(), mirror}) {
    for (uint32_t i = 0; i < 256; ++i) {
      const PathRng r = make_path_rng(i, i, 11);
      const Vec2 d = rng_2d(r, 4);
      const Vec3 wo = sample_cosine_hemisphere(d.x, d.y);
      if (wo.z <= 1e-3f) continue;
      const BsdfLobeProbabilities prob = bsdf_lobe_probabilities(p, wo);
      ASSERT_TRUE(bsdf_single_lobe(prob));
      const Vec2 u = rng_2d(r, 6);
      const float u_lobe = rng_1d(r, 8) * 0.999f;
      BsdfSample a, b;
      const bool ok_a = bsdf_sample_lobes(p, prob, wo, 0.0f, u.x, u.y, &a);
      const bool ok_b = bsdf_sample_lobes(p, prob, wo, u_lobe, u.x, u.y, &b);
      ASSERT_EQ(ok_a, ok_b) << "sample " << i;
      if (!ok_a) continue;
      EXPECT_TRUE(same_bits(a.wi.x, b.wi.x) && same_bits(a.wi.y, b.wi.y) &&
                  same_bits(a.wi.z, b.wi.z) && same_bits(a.pdf, b.pdf) &&
                  same_bits(a.weight.x, b.weight.x))
          << "sample " << i;
    }
  }
}

TEST(KernelFastPaths, LambertianEvalIsBaseColourOverPi) {
  BsdfParams p = lambertian();
  p.transmission = 0.25f;  // still no specular layer: the diffuse share shrinks
  const Vec3 wo = normalize(make_vec3(0.3f, -0.2f, 0.9f));
  const Vec3 wi = normalize(make_vec3(-0.6f, 0.1f, 0.4f));
  const BsdfLobeProbabilities prob = bsdf_lobe_probabilities(p, wo);
  const BsdfEval e = bsdf_eval_lobes(p, prob, wo, wi);
  const float w = 0.75f * kInvPi;
  EXPECT_FLOAT_EQ(e.f.x, 0.7f * w);
  EXPECT_FLOAT_EQ(e.f.y, 0.5f * w);
  EXPECT_FLOAT_EQ(e.f.z, 0.3f * w);
  EXPECT_FLOAT_EQ(e.pdf, prob.diffuse * wi.z * kInvPi);
  EXPECT_GT(prob.transmit, 0.0f);
}

}  // namespace
}  // namespace tandem
