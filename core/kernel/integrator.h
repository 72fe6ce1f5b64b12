// Unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic) between BSDF and light sampling.
//
// The integrator is a template over a Tracer, the only thing that differs
// between backends:
//   Hit  tracer.intersect(const Ray&, uint32_t alpha_key) const;  // closest hit
//   bool tracer.occluded(const Ray&, uint32_t alpha_key) const;   // any hit
// alpha_key seeds the stochastic transparency test (see alpha_test_opaque)
// so that it too is a pure function of the path, not of traversal order.
#pragma once

#include "core/kernel/alpha.h"
#include "core/kernel/bsdf.h"
#include "core/kernel/camera.h"
#include "core/kernel/lights.h"
#include "core/kernel/rng.h"

namespace tandem {

struct ShadingSetup {
  BsdfParams params;
  BsdfLobeProbabilities lobes;
  Frame frame;
  Vec3 ng;  // geometric normal on the side wo is on
  Vec3 wo_local;
};

// Evaluates textures and orients the shading frame towards wo. Returns
// false when the surface cannot scatter towards wo at all.
TANDEM_HD bool setup_shading(const KernelData& kd, const SurfacePoint& sp, Vec3 wo,
                             ShadingSetup* s) {
  const KMaterial& m = kd.materials[sp.material];
  const Vec4 base = material_base_color(kd, m, sp.uv);
  float metallic = m.metallic, roughness = m.roughness, transmission = m.transmission;
  if (m.metallic_roughness_tex.texture >= 0) {
    const Vec4 t = sample_texture(kd, uint32_t(m.metallic_roughness_tex.texture),
                                  material_uv(m.metallic_roughness_tex, sp.uv));
    roughness *= t.y;  // glTF: roughness in G, metalness in B
    metallic *= t.z;
  }
  if (m.transmission_tex.texture >= 0) {
    transmission *= sample_texture(kd, uint32_t(m.transmission_tex.texture),
                                   material_uv(m.transmission_tex, sp.uv))
                        .x;
  }
  const bool front = dot(wo, sp.geometric_normal) >= 0.0f;
  s->ng = front ? sp.geometric_normal : -sp.geometric_normal;
  s->frame = make_frame(front ? sp.shading_normal : -sp.shading_normal, sp.tangent);
  s->wo_local = to_local(s->frame, wo);
  if (s->wo_local.z <= 1e-6f) {
    // Interpolated normal faces away from the viewer: shade with the true one.
    s->frame = make_frame(s->ng, sp.tangent);
    s->wo_local = to_local(s->frame, wo);
    if (s->wo_local.z <= 0.0f) return false;
  }
  BsdfParams& p = s->params;
  p.base_color = xyz(base);
  p.metallic = saturate(metallic);
  p.alpha = ggx_alpha_from_roughness(saturate(roughness));
  p.transmission = saturate(transmission);
  p.specular = m.specular;
  p.specular_color = m.specular_color;
  // Leaving a transmissive object the relative index inverts. Opaque
  // materials are two-sided: both faces see air outside.
  const bool leaving = p.transmission > 0.0f && !front;
  p.eta = leaving ? 1.0f / m.ior : m.ior;
  p.fresnel_avg = leaving ? m.fresnel_avg_leave : m.fresnel_avg_enter;
  s->lobes = bsdf_lobe_probabilities(p, s->wo_local);
  return true;
}

// A sampled direction must leave on the geometric side its lobe implies,
// otherwise shading normals would let light leak through surfaces.
TANDEM_HD bool consistent_side(Vec3 wi_world, Vec3 wi_local, Vec3 ng) {
  return (wi_local.z > 0.0f) == (dot(wi_world, ng) > 0.0f);
}

template <class Tracer>
TANDEM_HD Vec3 trace_path(const KernelData& kd, const Tracer& tracer, Ray ray, const PathRng& rng,
                          uint32_t* ray_count) {
  const KIntegratorParams& ip = kd.constants.integrator;
  Vec3 radiance = make_vec3(0.0f);
  Vec3 beta = make_vec3(1.0f);
  float prev_bsdf_pdf = 0.0f;  // 0: camera ray, no MIS on emission
  uint32_t rays = 0;

  for (uint32_t bounce = 0;; ++bounce) {
    const uint32_t alpha_key = rng_bits(rng, bounce_dimension(bounce, kBounceAlpha));
    const Hit hit = tracer.intersect(ray, alpha_key);
    ++rays;
    if (!hit_valid(hit)) {
      const Vec3 le = env_radiance(kd, ray.dir);
      if (!is_black(le)) {
        const float w = prev_bsdf_pdf > 0.0f
                            ? mis_power_heuristic(prev_bsdf_pdf, environment_light_pdf(kd, ray.dir))
                            : 1.0f;
        radiance += beta * le * w;
      }
      break;
    }

    const SurfacePoint sp = make_surface_point(kd, hit);
    const KMaterial& mat = kd.materials[sp.material];
    const Vec3 wo = -ray.dir;

    if (!is_black(mat.emission) && emits_towards(mat, sp, wo)) {
      const Vec3 le = material_emission(kd, mat, sp.uv);
      const float w =
          prev_bsdf_pdf > 0.0f
              ? mis_power_heuristic(prev_bsdf_pdf, triangle_light_pdf(kd, sp, ray.dir, hit.t))
              : 1.0f;
      radiance += beta * le * w;
    }
    if (bounce >= ip.max_depth) break;

    ShadingSetup sh;
    if (!setup_shading(kd, sp, wo, &sh)) break;

    // Next-event estimation.
    LightSample ls;
    const Vec2 light_uv = rng_2d(rng, bounce_dimension(bounce, kBounceLightU));
    if (sample_light(kd, sp.position, rng_1d(rng, bounce_dimension(bounce, kBounceLightSelect)),
                     light_uv.x, light_uv.y, &ls)) {
      const Vec3 wi_local = to_local(sh.frame, ls.wi);
      if (consistent_side(ls.wi, wi_local, sh.ng)) {
        const BsdfEval e = bsdf_eval_lobes(sh.params, sh.lobes, sh.wo_local, wi_local);
        const Vec3 contrib = beta * e.f * ls.radiance * (fabsf(wi_local.z) / ls.pdf);
        if (!is_black(contrib) && is_finite(contrib)) {
          const float w = ls.is_delta ? 1.0f : mis_power_heuristic(ls.pdf, e.pdf);
          const uint32_t shadow_key = rng_bits(rng, bounce_dimension(bounce, kBounceShadowAlpha));
          const Ray shadow = ls.at_infinity ? spawn_ray(sp, ls.wi) : spawn_shadow_ray(sp, ls.point);
          ++rays;
          if (!tracer.occluded(shadow, shadow_key)) radiance += contrib * w;
        }
      }
    }

    // Continue the path by sampling the BSDF.
    BsdfSample bs;
    const Vec2 bsdf_uv = rng_2d(rng, bounce_dimension(bounce, kBounceBsdfU));
    if (!bsdf_sample_lobes(sh.params, sh.lobes, sh.wo_local,
                           rng_1d(rng, bounce_dimension(bounce, kBounceLobe)), bsdf_uv.x, bsdf_uv.y,
                           &bs)) {
      break;
    }
    const Vec3 wi = normalize(to_world(sh.frame, bs.wi));
    if (!consistent_side(wi, bs.wi, sh.ng)) break;
    beta *= bs.weight;
    prev_bsdf_pdf = bs.pdf;
    ray = spawn_ray(sp, wi);

    if (bounce + 1 >= ip.rr_start_depth) {
      const float survive = min_f(max_component(beta), 0.95f);
      if (!(rng_1d(rng, bounce_dimension(bounce, kBounceRoulette)) < survive)) break;
      beta *= 1.0f / survive;
    }
  }
  *ray_count += rays;
  if (!is_finite(radiance)) return make_vec3(0.0f);
  if (ip.radiance_clamp > 0.0f) {
    const float m = max_component(radiance);
    if (m > ip.radiance_clamp) radiance *= ip.radiance_clamp / m;
  }
  return radiance;
}

// One camera sample of pixel (x, y). The pixel's paths depend only on
// (x, y, sample, seed): this is what makes images independent of the tile
// split and of which backend rendered them.
template <class Tracer>
TANDEM_HD Vec3 render_pixel_sample(const KernelData& kd, const Tracer& tracer, uint32_t x,
                                   uint32_t y, uint32_t sample, uint32_t* ray_count) {
  const KCamera& cam = kd.constants.camera;
  const PathRng rng = make_path_rng(y * cam.width + x, sample, kd.constants.integrator.seed);
  const Vec2 jitter = rng_2d(rng, kDimPixelJitter), lens = rng_2d(rng, kDimLens);
  const Ray ray =
      generate_camera_ray(cam, float(x) + jitter.x, float(y) + jitter.y, lens.x, lens.y);
  return trace_path(kd, tracer, ray, rng, ray_count);
}

}  // namespace tandem
