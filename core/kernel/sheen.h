// The KHR_materials_sheen lobe: the "Charlie" microfiber distribution with
// the Estevez & Kulla 2017 ("Production Friendly Microfacet Sheen BRDF")
// height-correlated masking. Its directional albedo is tabulated in
// sheen_albedo.h.
//
// All directions are local (z = shading normal), both in the upper
// hemisphere.
#pragma once

#include "core/kernel/exp_log.h"
#include "core/kernel/math.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Sheen roughness below this is clamped: the distribution sin^(1/alpha)
// becomes a spike at the horizon that no sampler or table can resolve, and
// Estevez & Kulla fitted their masking term only down to about this value.
constexpr float kMinSheenRoughness = 0.07f;

// alpha = roughness^2, as the glTF spec defines it.
TANDEM_HD float sheen_alpha_from_roughness(float roughness) {
  const float r = max_f(roughness, kMinSheenRoughness);
  return r * r;
}

// D(m) = (2 + 1/alpha) sin(theta_m)^(1/alpha) / (2 pi): normalised so the
// projected microfiber area is 1.
TANDEM_HD float charlie_d(Vec3 m, float alpha) {
  const float inv_alpha = 1.0f / alpha;
  const float sin2 = m.x * m.x + m.y * m.y;
  return (2.0f + inv_alpha) * pow_f(sin2, 0.5f * inv_alpha) * kInv2Pi;
}

// Estevez & Kulla's fit of the Charlie distribution's Lambda: l(x) below,
// with coefficients blended between their alpha = 1 and alpha = 0 fits by
// (1 - alpha)^2; Lambda(mu) = exp(l(mu)) for mu < 1/2 and the mirrored
// exp(2 l(1/2) - l(1 - mu)) above, which keeps it smooth at mu = 1/2.
TANDEM_HD float charlie_l(float x, float alpha) {
  const float t = (1.0f - alpha) * (1.0f - alpha);
  const float a = lerp_f(21.5473f, 25.3245f, t);
  const float b = lerp_f(3.82987f, 3.32435f, t);
  const float c = lerp_f(0.19823f, 0.16801f, t);
  const float d = lerp_f(-1.97760f, -1.27393f, t);
  const float e = lerp_f(-4.32054f, -4.85967f, t);
  return a / (1.0f + b * pow_f(x, c)) + d * x + e;
}

TANDEM_HD float charlie_lambda(float cos_theta, float alpha) {
  const float mu = fabsf(cos_theta);
  if (mu < 0.5f) return exp_f(charlie_l(mu, alpha));
  return exp_f(2.0f * charlie_l(0.5f, alpha) - charlie_l(1.0f - mu, alpha));
}

// The white sheen BRDF, D G2 / (4 cos_o cos_i) with the height-correlated
// G2 = 1 / (1 + Lambda(wo) + Lambda(wi)). Symmetric in wo and wi.
TANDEM_HD float sheen_brdf(Vec3 wo, Vec3 wi, float alpha) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
  const Vec3 h = normalize(wo + wi);
  const float g2 = 1.0f / (1.0f + charlie_lambda(wo.z, alpha) + charlie_lambda(wi.z, alpha));
  return charlie_d(h, alpha) * g2 / (4.0f * wo.z * wi.z);
}

TANDEM_KERNEL_END
}  // namespace tandem
