// The glTF metallic-roughness BSDF (with KHR_materials_transmission, _ior
// and _specular) as three lobes sharing one GGX roughness:
//
//   reflection   metallic * Schlick(baseColor) + (1 - metallic) * specular *
//                specularColor * Fresnel_dielectric(ior), times GGX D G / 4|cos cos|
//   diffuse      (1 - metallic)(1 - transmission) baseColor / pi *
//                (1 - kF(wo))(1 - kF(wi)) / (1 - k F_avg),  k = specular * max(specularColor)
//   transmission (1 - metallic) transmission (1 - specular F) baseColor *
//                Walter et al. 2007 rough dielectric BTDF (smooth glass as alpha -> 0)
//
// The diffuse term sees the light the specular layer lets through on the way
// in and on the way out, normalised by the layer's hemispherical average
// (Kelemen & Szirmay-Kalos 2001): reciprocal, and the total albedo is at most
// k F(wo) + (1 - k F(wo)) baseColor <= 1, exactly 1 for a white smooth
// plastic. glTF's fresnel_mix(VdotH) form instead creates up to 50% energy
// at grazing angles. Conductors use Schlick's approximation with F0 = baseColor as glTF does; the
// dielectric layer uses the exact Fresnel equations so glass gets total
// internal reflection right. Sampling picks a lobe by its estimated albedo and
// always returns the mixture pdf, so bsdf_sample and bsdf_eval agree exactly
// (which the chi-square tests check).
//
// Two optional layers go over that base (bsdf_layers.h has the details):
// the sheen (KHR_materials_sheen, a Charlie microfiber lobe) directly on
// it, and the clear coat (KHR_materials_clearcoat, a colourless GGX
// dielectric with F0 = 0.04) over both:
//
//   f = coat + T_coat (sheen + T_sheen base)
//
// where T_coat and T_sheen dim what lies underneath by what the layer above
// reflected, the glTF spec's energy bookkeeping. Materials without layers
// skip every term of them and give the same bits as before the layers
// existed.
//
// All directions are local (z = shading normal) with wo.z > 0: the caller
// flips the frame for back-side hits and passes eta = n(wi side) / n(wo side).
#pragma once

#include "core/kernel/bsdf_layers.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

TANDEM_HD BsdfLobeProbabilities bsdf_lobe_probabilities(const BsdfParams& p, Vec3 wo) {
  const float f_dielectric = p.specular > 0.0f ? fresnel_dielectric(wo.z, p.eta) : 0.0f;
  const float dielectric = 1.0f - p.metallic;
  const float metal = p.metallic > 0.0f
                          ? p.metallic * max_f(luminance(fresnel_schlick(p.base_color, wo.z)),
                                               kMinLobeFresnelWeight)
                          : 0.0f;
  const float reflect =
      metal + dielectric * p.specular * f_dielectric * luminance(p.specular_color);
  const float base =
      dielectric * max_f(kMinLobeFresnelWeight,
                         1.0f - p.specular * f_dielectric * max_component(p.specular_color));
  const float albedo = luminance(p.base_color);
  float diffuse = base * (1.0f - p.transmission) * albedo;
  float transmit = base * p.transmission * albedo;
  if (!bsdf_has_layers(p)) {
    const float sum = reflect + diffuse + transmit;
    if (!(sum > 0.0f)) return {0.0f, 0.0f, 0.0f};
    const float inv = 1.0f / sum;
    return {reflect * inv, diffuse * inv, transmit * inv};
  }
  const LayerWeights w = layer_lobe_weights(p, wo.z);
  const float r = reflect * w.base, d = diffuse * w.base, t = transmit * w.base;
  const float sum = r + d + t + w.sheen + w.coat;
  if (!(sum > 0.0f)) return {0.0f, 0.0f, 0.0f};
  const float inv = 1.0f / sum;
  return {r * inv, d * inv, t * inv, w.sheen * inv, w.coat * inv};
}

// Whether at most one lobe can be picked: then bsdf_sample_lobes picks it
// whatever u_lobe is, and the caller need not draw one.
TANDEM_HD bool bsdf_single_lobe(const BsdfLobeProbabilities& prob) {
  const int lobes = (prob.reflect > 0.0f) + (prob.diffuse > 0.0f) + (prob.transmit > 0.0f) +
                    (prob.sheen > 0.0f) + (prob.coat > 0.0f);
  return lobes <= 1;
}

// Whether every lobe sampling can pick is a GGX lobe at the smallest alpha
// (roughness <= sqrt(kMinGgxAlpha): a smooth mirror, glass or coat). At such
// a point a light sample of an emissive triangle or the environment only
// ever adds the lobe's GGX tail, weighted by about (light pdf / BSDF pdf)^2
// ~ 1e-9 by MIS, yet costs a BSDF evaluation and a shadow ray; the
// integrator samples only punctual and directional lights there and gives
// the BSDF sample that reaches an area light the full weight instead.
TANDEM_HD bool bsdf_near_specular(const BsdfParams& p, const BsdfLobeProbabilities& prob) {
  if (prob.diffuse > 0.0f || prob.sheen > 0.0f) return false;
  if (prob.coat > 0.0f && p.clearcoat_alpha > kMinGgxAlpha) return false;
  if ((prob.reflect > 0.0f || prob.transmit > 0.0f) && p.alpha > kMinGgxAlpha) return false;
  return prob.reflect > 0.0f || prob.transmit > 0.0f || prob.coat > 0.0f;
}

// The base's three lobes (f and their share of the mixture pdf), without
// the layers.
TANDEM_HD BsdfEval bsdf_eval_base(const BsdfParams& p, const BsdfLobeProbabilities& prob,
                                  const Vec3& wo, const Vec3& wi) {
  BsdfEval out = {make_vec3(0.0f), 0.0f};
  if (wo.z <= 0.0f || wi.z == 0.0f) return out;
  const float dielectric = 1.0f - p.metallic;
  const float spec_max = max_component(p.specular_color);

  if (wi.z > 0.0f) {
    if (!(p.metallic > 0.0f || p.specular > 0.0f)) {
      // Pure Lambertian (no metal, no specular layer, so no Fresnel
      // normalisation either): no half vector needed. wo_h > 0 holds for
      // any two directions above the surface.
      out.f = p.base_color * ((dielectric * (1.0f - p.transmission)) * kInvPi);
      out.pdf = prob.diffuse * pdf_cosine_hemisphere(wi.z);
      return out;
    }
    const Vec3 h = normalize(wo + wi);
    const float wo_h = dot(wo, h);
    if (wo_h <= 0.0f) return out;
    const float f_dielectric = p.specular > 0.0f ? fresnel_dielectric(wo_h, p.eta) : 0.0f;
    float diffuse_w = dielectric * (1.0f - p.transmission);
    const float k = p.specular * spec_max;
    if (k > 0.0f && diffuse_w > 0.0f) {
      const float in = 1.0f - k * fresnel_dielectric(wo.z, p.eta);
      const float out_w = 1.0f - k * fresnel_dielectric(wi.z, p.eta);
      diffuse_w *=
          max_f(0.0f, in) * max_f(0.0f, out_w) / max_f(1e-6f, 1.0f - k * bsdf_fresnel_average(p));
    }
    out.f = p.base_color * (diffuse_w * kInvPi);
    out.pdf = prob.diffuse * pdf_cosine_hemisphere(wi.z);
    const Vec3 fresnel = p.metallic * fresnel_schlick(p.base_color, wo_h) +
                         (dielectric * p.specular * f_dielectric) * p.specular_color;
    const float d = ggx_d(h, p.alpha);
    const float g = ggx_g2(wo, wi, p.alpha);
    out.f += fresnel * (d * g / (4.0f * wo.z * wi.z));
    out.pdf += prob.reflect * ggx_visible_pdf(wo, h, p.alpha) / (4.0f * wo_h);
    return out;
  }

  if (p.transmission <= 0.0f || dielectric <= 0.0f) return out;
  // Generalised half vector of a refraction, on the wo side.
  Vec3 h = normalize(wo + wi * p.eta);
  if (h.z < 0.0f) h = -h;
  const float wo_h = dot(wo, h), wi_h = dot(wi, h);
  if (wo_h <= 0.0f || wi_h >= 0.0f) return out;
  const float f_dielectric = fresnel_dielectric(wo_h, p.eta);
  const float denom = p.eta * wi_h + wo_h;
  const float denom2 = denom * denom;
  if (!(denom2 > 0.0f)) return out;
  const float d = ggx_d(h, p.alpha);
  const float g = ggx_g2(wo, wi, p.alpha);
  const float weight =
      dielectric * p.transmission * max_f(0.0f, 1.0f - p.specular * spec_max * f_dielectric);
  // Radiance form: includes the 1/eta^2 compression of radiance entering a
  // denser medium.
  const float btdf = d * g * fabsf(wi_h) * wo_h / (fabsf(wi.z) * wo.z * denom2);
  out.f = p.base_color * (weight * btdf);
  out.pdf = prob.transmit * ggx_visible_pdf(wo, h, p.alpha) * p.eta * p.eta * fabsf(wi_h) / denom2;
  return out;
}

// bsdf_eval with the lobe probabilities for this wo already computed (the
// integrator evaluates and samples the same wo, so it computes them once).
TANDEM_HD BsdfEval bsdf_eval_lobes(const BsdfParams& p, const BsdfLobeProbabilities& prob,
                                   const Vec3& wo, const Vec3& wi) {
  BsdfEval out = bsdf_eval_base(p, prob, wo, wi);
  if (!bsdf_has_layers(p) || wo.z <= 0.0f || wi.z == 0.0f) return out;
  add_layers(p, prob, wo, wi, &out);
  return out;
}

TANDEM_HD BsdfEval bsdf_eval(const BsdfParams& p, Vec3 wo, Vec3 wi) {
  return bsdf_eval_lobes(p, bsdf_lobe_probabilities(p, wo), wo, wi);
}

// Picks a lobe with u_lobe and samples it with (u1, u2). Returns false when
// the sample carries no energy (below the horizon, total internal
// reflection in the transmission lobe, or a black material).
TANDEM_HD bool bsdf_sample_lobes(const BsdfParams& p, const BsdfLobeProbabilities& prob,
                                 const Vec3& wo, float u_lobe, float u1, float u2,
                                 BsdfSample* out) {
  if (wo.z <= 0.0f) return false;
  Vec3 wi;
  // The layers' lobes come first: without them both bounds are 0 and the
  // base's thresholds below are the same numbers as before they existed.
  const float below_sheen = prob.coat, below_base = below_sheen + prob.sheen;
  if (u_lobe < below_sheen) {
    const Vec3 m = ggx_sample_visible_normal(wo, p.clearcoat_alpha, u1, u2);
    wi = reflect(wo, m);
    if (wi.z <= 0.0f) return false;
  } else if (u_lobe < below_base) {
    // Cosine-weighted: the Charlie lobe has no practical inverse, and it is
    // broad enough that the cosine's variance stays moderate.
    wi = sample_cosine_hemisphere(u1, u2);
    if (wi.z <= 0.0f) return false;
  } else if (u_lobe < below_base + prob.reflect) {
    const Vec3 m = ggx_sample_visible_normal(wo, p.alpha, u1, u2);
    wi = reflect(wo, m);
    if (wi.z <= 0.0f) return false;
  } else if (u_lobe < below_base + prob.reflect + prob.diffuse) {
    wi = sample_cosine_hemisphere(u1, u2);
    if (wi.z <= 0.0f) return false;
  } else if (prob.transmit > 0.0f) {
    const Vec3 m = ggx_sample_visible_normal(wo, p.alpha, u1, u2);
    if (!refract_dir(wo, m, p.eta, &wi) || wi.z >= 0.0f) return false;
  } else {
    return false;
  }
  const BsdfEval e = bsdf_eval_lobes(p, prob, wo, wi);
  if (!(e.pdf > 0.0f) || !is_finite(e.pdf)) return false;
  out->wi = wi;
  out->pdf = e.pdf;
  out->weight = e.f * (fabsf(wi.z) / e.pdf);
  return is_finite(out->weight);
}

TANDEM_HD bool bsdf_sample(const BsdfParams& p, Vec3 wo, float u_lobe, float u1, float u2,
                           BsdfSample* out) {
  return bsdf_sample_lobes(p, bsdf_lobe_probabilities(p, wo), wo, u_lobe, u1, u2, out);
}

TANDEM_KERNEL_END
}  // namespace tandem
