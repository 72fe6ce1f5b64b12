// The parameters and results of the BSDF (bsdf.h), on their own so that
// the layers (bsdf_layers.h) and the base can share them.
#pragma once

#include "core/kernel/microfacet.h"
#include "core/kernel/sampling.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

struct BsdfParams {
  Vec3 base_color;
  float metallic;
  Vec3 specular_color;  // components in [0, 1]
  float alpha;          // GGX alpha (>= kMinGgxAlpha)
  float transmission;
  float eta;       // relative index of refraction across the surface
  float specular;  // weight of the dielectric reflection layer
  // Hemispherical average of fresnel_dielectric(., eta); < 0 means "compute
  // it here" (slow; the integrator passes the per-material precomputed value).
  float fresnel_avg = -1.0f;
  // The layers; the defaults mean "no layer".
  float clearcoat = 0.0f;                 // coat weight in [0, 1]
  float clearcoat_alpha = 1.0f;           // GGX alpha of the coat (>= kMinGgxAlpha)
  Vec3 sheen_color = {0.0f, 0.0f, 0.0f};  // components in [0, 1]
  float sheen_roughness = 0.0f;           // perceptual; sheen.h squares and clamps it
};

TANDEM_HD float bsdf_fresnel_average(const BsdfParams& p) {
  return p.fresnel_avg >= 0.0f ? p.fresnel_avg : fresnel_dielectric_average(p.eta);
}

struct BsdfEval {
  Vec3 f;     // BSDF value (no cosine)
  float pdf;  // solid-angle density of bsdf_sample producing wi
};

struct BsdfSample {
  Vec3 wi;
  Vec3 weight;  // f * |cos| / pdf
  float pdf;
};

struct BsdfLobeProbabilities {
  float reflect, diffuse, transmit;
  float sheen = 0.0f, coat = 0.0f;  // 0 without the layers
};

// Floor on the Fresnel factors of the lobe-selection weights of
// bsdf_lobe_probabilities (bsdf.h). Those
// use Fresnel at the macro normal, which can be exactly 0 (Schlick with a
// black F0 at normal incidence) or 1 (total internal reflection) while
// off-normal microfacets still reflect or transmit: without the floor such a
// lobe has f > 0 but probability 0, and bsdf_sample can never reach it (bias,
// not noise). Any positive floor keeps the estimator unbiased; 0.1 also keeps
// the weights of those samples moderate.
constexpr float kMinLobeFresnelWeight = 0.1f;

TANDEM_KERNEL_END
}  // namespace tandem
