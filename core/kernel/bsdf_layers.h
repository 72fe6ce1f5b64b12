// The clear coat and sheen layers over the glTF base BSDF (bsdf.h):
//
//   f = coat + T_coat (sheen + T_sheen base)
//
// coat     clearcoat * F(wo.h) D G2 / (4 cos_o cos_i): GGX with its own
//          roughness and Schlick's Fresnel with F0 = 0.04 (ior 1.5), as the
//          KHR_materials_clearcoat spec defines it. The coat shares the base's
//          shading normal (clearcoatNormalTexture is not read).
// T_coat   1 - clearcoat * min(1, kCoatFresnelBound * F(min(cos_o, cos_i))):
//          the spec's base * (1 - clearcoat * F(N.V)), made reciprocal by
//          taking the more grazing of the two directions. F(N.V) is slightly
//          smaller than what a rough coat really reflects (microfacets tilted
//          towards the viewer see more Fresnel: up to 2.7% more at roughness
//          0.3 and 50 degrees), so the bound factor dims the base by that
//          much more and coat + base stays at most 1.
// sheen    sheenColor * Charlie(D, G2) / max(1, E(cos_o), E(cos_i)) (sheen.h)
//          where E is the white lobe's directional albedo (sheen_albedo.h).
//          The Estevez-Kulla masking fit lets a smooth sheen reflect up to
//          2.7x what it receives at grazing angles; the symmetric division
//          keeps the lobe reciprocal and its albedo at most min(1, E(cos_o)).
// T_sheen  1 - max(sheenColor) * max(min(1, E(cos_o)), min(1, E(cos_i))): the
//          spec's albedo scaling (which takes the smaller of the two
//          1 - max(sheenColor) E terms), with E clamped like the lobe.
//
// Per channel the sum is then at most 1 for every wo: the coat reflects at
// most clearcoat * kCoatFresnelBound * F(cos_o), the sheen at most
// max(sheenColor) min(1, E(cos_o)), and each T removes at least that much.
// Transmission through the base is dimmed by the same T factors, with |cos_i|,
// so the generalised reciprocity of the BTDF is kept.
#pragma once

#include "core/kernel/bsdf_params.h"
#include "core/kernel/sheen_albedo.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

constexpr float kCoatF0 = 0.04f;  // ior 1.5, fixed by the extension
constexpr float kCoatFresnelBound = 1.05f;

TANDEM_HD bool bsdf_has_layers(const BsdfParams& p) {
  return p.clearcoat > 0.0f || !is_black(p.sheen_color);
}

TANDEM_HD float coat_fresnel(float cos_theta) {
  const float m = saturate(1.0f - cos_theta);
  const float m5 = (m * m) * (m * m) * m;
  return kCoatF0 + (1.0f - kCoatF0) * m5;
}

// What the coat lets through to the layers below, seen from directions with
// cosines cos_a and cos_b (pass the same one twice for one direction).
TANDEM_HD float coat_transmittance(const BsdfParams& p, float cos_a, float cos_b) {
  if (!(p.clearcoat > 0.0f)) return 1.0f;
  return 1.0f - p.clearcoat * min_f(1.0f, kCoatFresnelBound * coat_fresnel(min_f(cos_a, cos_b)));
}

// The white sheen lobe's directional albedo, and that clamped to 1.
TANDEM_HD float sheen_layer_albedo(const BsdfParams& p, float cos_theta) {
  return sheen_albedo(cos_theta, p.sheen_roughness);
}

// The selection weights of the layers' lobes for wo, and the factor the base
// lobes' weights take (bsdf_lobe_probabilities).
struct LayerWeights {
  float base, sheen, coat;
};

TANDEM_HD LayerWeights layer_lobe_weights(const BsdfParams& p, float cos_o) {
  LayerWeights w = {coat_transmittance(p, cos_o, cos_o), 0.0f, 0.0f};
  if (!is_black(p.sheen_color)) {
    const float e = min_f(1.0f, sheen_layer_albedo(p, cos_o));
    // A floor like kMinLobeFresnelWeight's: the tabulated albedo is tiny for
    // a smooth sheen seen head-on while the lobe is not exactly 0.
    w.sheen = w.base * luminance(p.sheen_color) * max_f(e, kMinLobeFresnelWeight);
    w.base *= 1.0f - max_component(p.sheen_color) * e;
  }
  if (p.clearcoat > 0.0f) w.coat = p.clearcoat * coat_fresnel(cos_o);
  return w;
}

// Dims the base's value (already in *out) by the layers and adds the layers'
// lobes. wo.z > 0, wi.z != 0.
TANDEM_HD void add_layers(const BsdfParams& p, const BsdfLobeProbabilities& prob, const Vec3& wo,
                          const Vec3& wi, BsdfEval* out) {
  const float cos_i = fabsf(wi.z);
  const float t_coat = coat_transmittance(p, wo.z, cos_i);
  float t_sheen = 1.0f;
  float e_o = 0.0f, e_i = 0.0f;
  const bool sheen = !is_black(p.sheen_color);
  if (sheen) {
    e_o = sheen_layer_albedo(p, wo.z);
    e_i = sheen_layer_albedo(p, cos_i);
    t_sheen = 1.0f - max_component(p.sheen_color) * max_f(min_f(1.0f, e_o), min_f(1.0f, e_i));
  }
  out->f *= t_coat * max_f(0.0f, t_sheen);
  if (wi.z < 0.0f) return;  // both layers only reflect
  if (sheen) {
    const float alpha = sheen_alpha_from_roughness(p.sheen_roughness);
    const float lobe = sheen_brdf(wo, wi, alpha) / max_f(1.0f, max_f(e_o, e_i));
    out->f += p.sheen_color * (t_coat * lobe);
    out->pdf += prob.sheen * pdf_cosine_hemisphere(wi.z);
  }
  if (p.clearcoat > 0.0f) {
    const Vec3 h = normalize(wo + wi);
    const float wo_h = dot(wo, h);
    if (wo_h > 0.0f) {
      const float d = ggx_d(h, p.clearcoat_alpha);
      const float g = ggx_g2(wo, wi, p.clearcoat_alpha);
      out->f += make_vec3(p.clearcoat * coat_fresnel(wo_h) * d * g / (4.0f * wo.z * wi.z));
      out->pdf += prob.coat * ggx_visible_pdf(wo, h, p.clearcoat_alpha) / (4.0f * wo_h);
    }
  }
}

TANDEM_KERNEL_END
}  // namespace tandem
