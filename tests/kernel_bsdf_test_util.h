// What the BSDF tests (kernel_bsdf_test, kernel_layers_test) share: the view
// directions, a readable name for a failing case, the chi-square of a
// sampler against its pdf, and the per-sample check that also accumulates
// the flux albedo. One copy, so the layered material is held to exactly the
// checks the base lobes are.
#pragma once

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/kernel/bsdf.h"
#include "test_stats.h"

namespace tandem::bsdf_test {

constexpr float kViewPhi = 0.7f;  // keeps wo off the frame's axes

inline Vec3 view_direction(float degrees) {
  const float t = degrees * kPi / 180.0f;
  return make_vec3(sinf(t) * cosf(kViewPhi), sinf(t) * sinf(kViewPhi), cosf(t));
}

inline std::string describe(const BsdfParams& p, Vec3 wo) {
  std::ostringstream s;
  s << "base=(" << p.base_color.x << "," << p.base_color.y << "," << p.base_color.z
    << ") metallic=" << p.metallic << " alpha=" << p.alpha << " transmission=" << p.transmission
    << " eta=" << p.eta << " specular=" << p.specular << " specular_color=(" << p.specular_color.x
    << "," << p.specular_color.y << "," << p.specular_color.z << ")";
  if (p.clearcoat > 0.0f) s << " clearcoat=" << p.clearcoat << " coat_alpha=" << p.clearcoat_alpha;
  if (!is_black(p.sheen_color)) {
    s << " sheen=(" << p.sheen_color.x << "," << p.sheen_color.y << "," << p.sheen_color.z
      << ") sheen_roughness=" << p.sheen_roughness;
  }
  s << " wo_theta=" << acosf(wo.z) * 180.0f / kPi << "deg";
  return s.str();
}

// One-sided z threshold with tail probability p (bisection on erfc).
inline double upper_normal_quantile(double p) {
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return hi;
}

// bsdf_sample's directions against bsdf_eval's pdf over the sphere.
inline test_stats::SphereTestResult sampled_directions_chi_square(const BsdfParams& p, Vec3 wo,
                                                                  uint32_t seed) {
  test_stats::TestRng rng(seed);
  return test_stats::sphere_chi_square(
      [&](Vec3* d) {
        BsdfSample s;
        const float ul = rng.next(), u1 = rng.next(), u2 = rng.next();
        if (!bsdf_sample(p, wo, ul, u1, u2, &s)) return false;
        *d = s.wi;
        return true;
      },
      [&](Vec3 d) { return bsdf_eval(p, wo, d).pdf; }, 100000, 32, 32);
}

struct SampleMoments {
  test_stats::MeanAccumulator albedo[3];  // flux albedo per channel
  std::string error;                      // first per-sample inconsistency
};

// Draws samples, checks each against bsdf_eval (unit direction, the same
// pdf, a positive eval pdf, weight == f |cos| / pdf) and accumulates the
// directional albedo in flux terms.
inline SampleMoments sample_moments(const BsdfParams& p, Vec3 wo, uint32_t seed, int samples) {
  SampleMoments m;
  test_stats::TestRng rng(seed);
  for (int s = 0; s < samples; ++s) {
    BsdfSample bs;
    const float ul = rng.next(), u1 = rng.next(), u2 = rng.next();
    float w[3] = {0.0f, 0.0f, 0.0f};
    if (bsdf_sample(p, wo, ul, u1, u2, &bs)) {
      const BsdfEval e = bsdf_eval(p, wo, bs.wi);
      const Vec3 expect = e.f * (fabsf(bs.wi.z) / e.pdf);
      std::ostringstream err;
      if (!(fabsf(length(bs.wi) - 1.0f) < 1e-4f)) err << "wi not unit: " << length(bs.wi);
      if (bs.pdf != e.pdf) err << "sample pdf " << bs.pdf << " != eval pdf " << e.pdf;
      if (!(e.pdf > 0.0f)) err << "eval pdf " << e.pdf << " for a sampled direction";
      for (int k = 0; k < 3; ++k) {
        const float got = component(bs.weight, k), want = component(expect, k);
        if (!(got >= 0.0f) || !(fabsf(got - want) <= 1e-5f * std::max(1.0f, want))) {
          err << " weight[" << k << "]=" << got << " but f|cos|/pdf=" << want;
        }
      }
      if (m.error.empty() && !err.str().empty()) m.error = err.str() + " for " + describe(p, wo);
      // Albedo in flux terms: the BTDF is in radiance form and carries the
      // (n_wo / n_wi)^2 = 1 / eta^2 factor of radiance crossing the
      // interface, which is not an energy gain; undo it for transmission.
      const float scale = bs.wi.z < 0.0f ? p.eta * p.eta : 1.0f;
      for (int k = 0; k < 3; ++k)
        w[k] = component(bs.weight, k) * scale;
    }
    for (int k = 0; k < 3; ++k)
      m.albedo[k].add(w[k]);
  }
  return m;
}

}  // namespace tandem::bsdf_test
