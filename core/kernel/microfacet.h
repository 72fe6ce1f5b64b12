// GGX (Trowbridge-Reitz) microfacet distribution, Smith masking, visible
// normal sampling, and Fresnel terms. All directions are in the local shading
// frame (z = normal).
#pragma once

#include "core/kernel/math.h"
#include "core/kernel/trig.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Smallest GGX alpha we evaluate. Below this, glTF "roughness 0" surfaces are
// treated as near-perfect mirrors/glass by the same code path (angular blur
// ~1e-3 rad, invisible), which keeps one set of formulas for every lobe.
constexpr float kMinGgxAlpha = 1e-3f;

TANDEM_HD float ggx_alpha_from_roughness(float roughness) {
  return max_f(roughness * roughness, kMinGgxAlpha);
}

// D(m). Written in terms of sin^2 = x^2 + y^2 instead of 1 - cos^2 so that
// tiny alphas do not suffer catastrophic cancellation.
TANDEM_HD float ggx_d(Vec3 m, float alpha) {
  if (m.z <= 0.0f) return 0.0f;
  const float a2 = alpha * alpha;
  const float sin2 = m.x * m.x + m.y * m.y;
  const float k = m.z * m.z + sin2 / a2;
  return 1.0f / (kPi * a2 * k * k);
}

// Smith Lambda for GGX.
TANDEM_HD float ggx_lambda(Vec3 w, float alpha) {
  const float z2 = w.z * w.z;
  if (z2 <= 0.0f) return 0.0f;
  const float tan2 = (w.x * w.x + w.y * w.y) / z2;
  return 0.5f * (sqrtf(1.0f + alpha * alpha * tan2) - 1.0f);
}
TANDEM_HD float ggx_g1(Vec3 w, float alpha) {
  return 1.0f / (1.0f + ggx_lambda(w, alpha));
}
// Height-correlated masking-shadowing.
TANDEM_HD float ggx_g2(Vec3 wo, Vec3 wi, float alpha) {
  return 1.0f / (1.0f + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
}

// Density of visible normals D_wo(m) = G1(wo) max(0, wo.m) D(m) / wo.z.
TANDEM_HD float ggx_visible_pdf(Vec3 wo, Vec3 m, float alpha) {
  const float wo_m = dot(wo, m);
  if (wo.z <= 0.0f || wo_m <= 0.0f) return 0.0f;
  return ggx_g1(wo, alpha) * wo_m * ggx_d(m, alpha) / wo.z;
}

// Samples a visible normal for wo (wo.z > 0) following Heitz 2018: stretch
// wo to the hemisphere configuration, sample the projected disk, unstretch.
TANDEM_HD Vec3 ggx_sample_visible_normal(Vec3 wo, float alpha, float u1, float u2) {
  const Vec3 vh = normalize(make_vec3(alpha * wo.x, alpha * wo.y, wo.z));
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0.0f ? make_vec3(-vh.y, vh.x, 0.0f) * (1.0f / sqrtf(len2))
                              : make_vec3(1.0f, 0.0f, 0.0f);
  const Vec3 t2 = cross(vh, t1);
  const float r = sqrtf(u1);
  const SinCos phi = sincos_pi(2.0f * u2);  // phi = 2 pi u2
  const float p1 = r * phi.cos;
  float p2 = r * phi.sin;
  const float s = 0.5f * (1.0f + vh.z);
  p2 = (1.0f - s) * safe_sqrt(1.0f - p1 * p1) + s * p2;
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * safe_sqrt(1.0f - p1 * p1 - p2 * p2);
  return normalize(make_vec3(alpha * nh.x, alpha * nh.y, max_f(nh.z, 1e-7f)));
}

// Unpolarised Fresnel reflectance of a dielectric interface. cos_i is the
// cosine on the incident side (>= 0); eta = n_transmitted / n_incident.
TANDEM_HD float fresnel_dielectric(float cos_i, float eta) {
  cos_i = clamp_f(cos_i, 0.0f, 1.0f);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return 1.0f;  // total internal reflection
  const float cos_t = safe_sqrt(1.0f - sin2_t);
  const float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5f * (r_par * r_par + r_perp * r_perp);
}

// Cosine-weighted hemispherical average of fresnel_dielectric,
// 2 * integral_0^1 F(mu) mu dmu = integral_0^1 F(sqrt(x)) dx, by the midpoint
// rule in x (F is continuous; its kink at the critical angle costs O(h^2)).
// Hosts precompute it per material; the kernel only calls it as a fallback.
TANDEM_HD float fresnel_dielectric_average(float eta) {
  constexpr int kSteps = 256;
  float sum = 0.0f;
  for (int i = 0; i < kSteps; ++i)
    sum += fresnel_dielectric(sqrtf((float(i) + 0.5f) / float(kSteps)), eta);
  return sum / float(kSteps);
}

TANDEM_HD Vec3 fresnel_schlick(Vec3 f0, float cos_theta) {
  const float m = saturate(1.0f - cos_theta);
  const float m5 = (m * m) * (m * m) * m;
  return f0 + (make_vec3(1.0f) - f0) * m5;
}

// Refracts w (pointing away from the surface, on m's side) through the
// microfacet normal m with relative index eta = n_t / n_i. Returns false on
// total internal reflection.
TANDEM_HD bool refract_dir(Vec3 w, Vec3 m, float eta, Vec3* out) {
  const float cos_i = dot(w, m);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return false;
  const float cos_t = sqrtf(1.0f - sin2_t);
  *out = -w * (1.0f / eta) + m * (cos_i / eta - cos_t);
  return true;
}

TANDEM_KERNEL_END
}  // namespace tandem
