// Unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic) between BSDF and light sampling,
// written as an explicit path state and the stages that advance it:
//
//   path_generate        the camera ray of a pixel sample
//   path_alpha_key       the stochastic-transparency key of the next ray
//   path_shade_miss      environment light (MIS), the path ends
//   path_shade_hit       emission (MIS), a light sample as a shadow-ray
//                        record, the BSDF sample that continues the path,
//                        Russian roulette
//   path_shadow_result   adds a light sample whose shadow ray was unoccluded
//   path_finish          the sample's radiance (non-finite -> 0, clamp)
//
// The megakernel (render_pixel_sample) is a loop over these stages for one
// path; the wavefront pipelines (the host backend's and the GPU's) run each
// stage over queues of many paths. Both draw the same random numbers in the
// same order and add to the radiance in the same order (a path's shadow
// result is always added before its next hit is shaded), so they give the
// same bits.
//
// Tracing is the only thing that differs between backends: the megakernel
// takes a Tracer,
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
TANDEM_KERNEL_BEGIN

// Russian roulette's survival probability for a path of this throughput:
// the square root of its largest component, at most 1. A path whose
// throughput is still >= 1 (a lossless mirror or glass chain) always
// survives: killing it gains no time worth the variance of the 1/q weight,
// and a fixed cap below 1 (such as 0.95) would end 5% of the paths through
// a chain of perfect specular bounces at every bounce. The square root keeps
// dim paths a little longer than q = throughput would, so that survivors are
// weighted by less. Unbiased for any q in (0, 1]: a survivor's weight 1/q
// times the probability q of surviving is 1. A zero or NaN throughput gives
// q = 0 and ends the path.
TANDEM_HD_INLINE float roulette_survival(const Vec3& throughput) {
  return min_f(safe_sqrt(max_component(throughput)), 1.0f);
}

struct ShadingSetup {
  BsdfParams params;
  BsdfLobeProbabilities lobes;
  Frame frame;
  Vec3 ng;  // geometric normal on the side wo is on
  Vec3 wo_local;
};

// The clear coat and sheen parameters of a material with either layer at a
// shading point (texture channels as KHR_materials_clearcoat and _sheen
// define them). Out of line from setup_shading so that materials without
// layers pay one branch.
TANDEM_HD void setup_layers(const KernelData& kd, const KMaterial& m, const Vec2 uv[2],
                            BsdfParams* p) {
  float clearcoat = m.clearcoat, coat_roughness = m.clearcoat_roughness;
  if (m.clearcoat_tex.texture >= 0) {
    clearcoat *=
        sample_texture(kd, uint32_t(m.clearcoat_tex.texture), material_uv(m.clearcoat_tex, uv)).x;
  }
  if (m.clearcoat_roughness_tex.texture >= 0) {
    coat_roughness *= sample_texture(kd, uint32_t(m.clearcoat_roughness_tex.texture),
                                     material_uv(m.clearcoat_roughness_tex, uv))
                          .y;
  }
  Vec3 sheen = m.sheen_color;
  float sheen_roughness = m.sheen_roughness;
  if (m.sheen_color_tex.texture >= 0) {
    sheen *= xyz(sample_texture(kd, uint32_t(m.sheen_color_tex.texture),
                                material_uv(m.sheen_color_tex, uv)));
  }
  if (m.sheen_roughness_tex.texture >= 0) {
    sheen_roughness *= sample_texture(kd, uint32_t(m.sheen_roughness_tex.texture),
                                      material_uv(m.sheen_roughness_tex, uv))
                           .w;
  }
  p->clearcoat = saturate(clearcoat);
  p->clearcoat_alpha = ggx_alpha_from_roughness(saturate(coat_roughness));
  p->sheen_color = {saturate(sheen.x), saturate(sheen.y), saturate(sheen.z)};
  p->sheen_roughness = saturate(sheen_roughness);
}

// Evaluates textures and orients the shading frame towards wo. Returns
// false when the surface cannot scatter towards wo at all.
TANDEM_HD bool setup_shading(const KernelData& kd, const SurfacePoint& sp, const Vec3& wo,
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
  // The frame make_surface_point built, mirrored for the back side
  // (make_frame(-n, t) is {t, -b, -n}): orthonormalising it again per hit
  // cost a square root and a division for nothing.
  s->frame = front ? Frame{sp.tangent, sp.bitangent, sp.shading_normal}
                   : Frame{sp.tangent, -sp.bitangent, -sp.shading_normal};
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
  if (m.clearcoat > 0.0f || !is_black(m.sheen_color)) setup_layers(kd, m, sp.uv, &p);
  s->lobes = bsdf_lobe_probabilities(p, s->wo_local);
  return true;
}

// A sampled direction must leave on the geometric side its lobe implies,
// otherwise shading normals would let light leak through surfaces.
TANDEM_HD bool consistent_side(Vec3 wi_world, Vec3 wi_local, Vec3 ng) {
  return (wi_local.z > 0.0f) == (dot(wi_world, ng) > 0.0f);
}

// The state of one path between stages. POD: the wavefront keeps arrays
// of it in device memory.
enum PathFlags : uint32_t {
  kPathAlive = 1u << 0,      // has a ray to trace
  kPathAlphaKeys = 1u << 1,  // the scene has alpha-tested meshes: rays carry alpha keys
};

struct PathState {
  Ray ray;          // the next ray to trace (when alive)
  Vec3 throughput;  // product of BSDF weights so far (beta)
  Vec3 radiance;    // accumulated so far
  PathRng rng;      // keyed by (pixel, sample, seed)
  uint32_t x, y, sample;
  uint32_t bounce;  // scattering events so far
  float bsdf_pdf;   // pdf of the BSDF sample that made `ray`; 0: camera ray (no MIS)
  float eta_scale;  // product of eta^2 over the refractions so far (Russian roulette)
  uint32_t flags;   // PathFlags
  uint32_t rays;    // rays traced for this path (closest hit and shadow)
  // The shading point `ray` left and the receiver normal the light tree
  // chose the light sample there with, so that MIS at the light `ray` finds
  // recomputes the same choice's probability.
  Vec3 origin_point;
  Vec3 origin_normal;
};

// A light sample waiting for its shadow ray: `contribution` (already MIS
// weighted) is added to the path's radiance if the ray is unoccluded.
struct ShadowRay {
  Ray ray;
  Vec3 contribution;
  uint32_t alpha_key;
};

TANDEM_HD bool path_alive(const PathState& p) {
  return (p.flags & kPathAlive) != 0;
}

// The camera ray and the initial state of a path whose rng is set. The lens
// pair is drawn only for a thin-lens camera: a pinhole ignores it, and it is
// about 1% of a Cornell-box sample. Templated on the generator so that the
// CPU tile loop's cached one (CachedPathRng) gives the same numbers.
template <class Rng>
TANDEM_HD void path_start(const KernelData& kd, uint32_t x, uint32_t y, uint32_t sample,
                          const Rng& rng, PathState* p) {
  const KCamera& cam = kd.constants.camera;
  const Vec2 jitter = rng_jitter_2d(rng);
  const Vec2 lens = cam.aperture_radius > 0.0f && cam.type != kCameraOrthographic
                        ? rng_lens_2d(rng)
                        : make_vec2(0.0f, 0.0f);
  p->ray = generate_camera_ray(cam, float(x) + jitter.x, float(y) + jitter.y, lens.x, lens.y);
  p->throughput = make_vec3(1.0f);
  p->radiance = make_vec3(0.0f);
  p->x = x;
  p->y = y;
  p->sample = sample;
  p->bounce = 0;
  p->bsdf_pdf = 0.0f;
  p->eta_scale = 1.0f;
  p->flags = kPathAlive | ((kd.constants.scene_flags & kSceneHasAlphaTest) ? kPathAlphaKeys : 0u);
  p->rays = 0;
  p->origin_point = p->ray.origin;  // unread: a camera ray has no MIS (bsdf_pdf 0)
  p->origin_normal = make_vec3(0.0f);
}

TANDEM_HD void path_generate(const KernelData& kd, uint32_t x, uint32_t y, uint32_t sample,
                             PathState* p) {
  p->rng = make_path_rng(y * kd.constants.camera.width + x, sample, kd.constants.integrator.seed);
  path_start(kd, x, y, sample, p->rng, p);
}

// path_generate with the pixel's cache (pixel_rng_cache_reset for this pixel
// and seed): the same path.
TANDEM_HD void path_generate_cached(const KernelData& kd, uint32_t x, uint32_t y, uint32_t sample,
                                    PixelRngCache* cache, PathState* p) {
  p->rng = {cache->key, sample, reverse_bits_u32(sample)};
  path_start(kd, x, y, sample, CachedPathRng{p->rng, cache}, p);
}

// Only alpha-tested triangles read the key, so scenes without any skip the
// hashing (two keys per bounce: about 2% of a Cornell-box sample). The
// keys of scenes with alpha tests are unchanged.
TANDEM_HD uint32_t path_alpha_key(const PathState& p) {
  return (p.flags & kPathAlphaKeys) ? bounce_rng_bits(p.rng, p.bounce, kBounceAlpha) : 0u;
}

// The ray left the scene. The map coordinates of the direction are computed
// once for both the radiance and the MIS pdf (env_radiance and
// environment_light_pdf would each derive them: four atan2f per miss
// instead of two, 2% of FlightHelmet's instructions, where many paths end
// in a miss; docs/performance/log/cpu_path_tracing_rounds_4_10.md).
TANDEM_HD void path_shade_miss(const KernelData& kd, PathState* p) {
  const Vec3 dir = p->ray.dir;
  const Vec2 uv = env_map_uv(kd, dir);
  const Vec3 le = env_radiance_at(kd, uv);
  if (!is_black(le)) {
    const float w = p->bsdf_pdf > 0.0f
                        ? mis_power_heuristic(p->bsdf_pdf, environment_light_pdf_at(kd, dir, uv))
                        : 1.0f;
    p->radiance += p->throughput * le * w;
  }
  p->flags &= ~kPathAlive;
}

// The ray hit `hit`. Returns true when it also produced a light sample in
// `*shadow` whose shadow ray must be traced (path_shadow_result) before the
// path's next hit is shaded. Afterwards the path is either alive with its
// next ray or finished.
// `rng` draws the numbers of p->rng (p->rng itself, or CachedPathRng).
template <class Rng>
TANDEM_HD bool path_shade_hit_rng(const KernelData& kd, const Hit& hit, PathState* p,
                                  ShadowRay* shadow, const Rng& rng) {
  const KIntegratorParams& ip = kd.constants.integrator;
  const uint32_t bounce = p->bounce;
  const SurfacePoint sp = make_surface_point(kd, hit);
  const KMaterial& mat = kd.materials[sp.material];
  const Vec3 wo = -p->ray.dir;
  p->flags &= ~kPathAlive;  // until a next ray exists

  if (!is_black(mat.emission) && emits_towards(mat, sp, wo)) {
    const Vec3 le = material_emission(kd, mat, sp.uv);
    const float w = p->bsdf_pdf > 0.0f
                        ? mis_power_heuristic(p->bsdf_pdf,
                                              triangle_light_pdf(kd, hit, sp, p->ray.dir, hit.t,
                                                                 p->origin_point, p->origin_normal))
                        : 1.0f;
    p->radiance += p->throughput * le * w;
  }
  if (bounce >= ip.max_depth) return false;

  ShadingSetup sh;
  if (!setup_shading(kd, sp, wo, &sh)) return false;

  // Next-event estimation. At a smooth mirror, glass or coat
  // (bsdf_near_specular) only of punctual and directional lights: MIS would
  // weigh an area light's sample by about 1e-9 there, so the BSDF sample
  // that reaches an area light takes the full weight (bsdf_pdf 0 below) and
  // the light's BSDF evaluation and shadow ray are saved. Unbiased either
  // way, the noise unchanged.
  bool has_shadow = false;
  const bool specular = bsdf_near_specular(sh.params, sh.lobes);
  const auto brng = rng_at_bounce(rng, bounce);  // this bounce's draws
  LightSample ls;
  const Vec2 light_uv = bounce_rng_2d(brng, kBounceLightU);
  // The side light can arrive from, for the light tree: the geometric
  // normal towards wo (a reflection's lobes stay on that side,
  // consistent_side), or every side where light can pass through.
  const Vec3 receiver = sh.params.transmission > 0.0f ? make_vec3(0.0f) : sh.ng;
  if (sample_light(kd, sp.position, receiver, bounce_rng_1d(brng, kBounceLightSelect), light_uv.x,
                   light_uv.y, &ls, specular)) {
    const Vec3 wi_local = to_local(sh.frame, ls.wi);
    if (consistent_side(ls.wi, wi_local, sh.ng)) {
      const BsdfEval e = bsdf_eval_lobes(sh.params, sh.lobes, sh.wo_local, wi_local);
      const Vec3 contrib = p->throughput * e.f * ls.radiance * (fabsf(wi_local.z) / ls.pdf);
      if (!is_black(contrib) && is_finite(contrib)) {
        const float w = ls.is_delta ? 1.0f : mis_power_heuristic(ls.pdf, e.pdf);
        shadow->alpha_key =
            (p->flags & kPathAlphaKeys) ? bounce_rng_bits(brng, kBounceShadowAlpha) : 0u;
        shadow->ray = ls.at_infinity ? spawn_ray(sp, ls.wi) : spawn_shadow_ray(sp, ls.point);
        shadow->contribution = contrib * w;
        has_shadow = true;
      }
    }
  }

  // Continue the path by sampling the BSDF.
  BsdfSample bs;
  const Vec2 bsdf_uv = bounce_rng_2d(brng, kBounceBsdfU);
  // With at most one lobe any u_lobe picks it (u_lobe = 0 too), so the draw
  // is skipped: it is most hits (Lambertian walls, mirrors).
  const float u_lobe = bsdf_single_lobe(sh.lobes) ? 0.0f : bounce_rng_1d(brng, kBounceLobe);
  if (!bsdf_sample_lobes(sh.params, sh.lobes, sh.wo_local, u_lobe, bsdf_uv.x, bsdf_uv.y, &bs)) {
    return has_shadow;
  }
  const Vec3 wi = normalize(to_world(sh.frame, bs.wi));
  if (!consistent_side(wi, bs.wi, sh.ng)) return has_shadow;
  p->throughput *= bs.weight;
  p->bsdf_pdf = specular ? 0.0f : bs.pdf;  // 0: no area-light sample to weigh against
  p->ray = spawn_ray(sp, wi);
  p->origin_point = sp.position;
  p->origin_normal = receiver;

  // A refraction scales radiance by eta^2, which the throughput carries as
  // 1 / eta^2 into glass and undoes on the way out; roulette sees the
  // throughput without it (pbrt's etaScale), so that a path inside a glass
  // object is not culled for a factor that leaving it cancels. Cycles'
  // refraction has no such factor at all. Unbiased for any survival q.
  if (bs.wi.z < 0.0f) p->eta_scale *= sh.params.eta * sh.params.eta;
  if (bounce + 1 >= ip.rr_start_depth) {
    const float survive = roulette_survival(p->throughput * p->eta_scale);
    if (survive < 1.0f) {
      if (!(bounce_rng_1d(brng, kBounceRoulette) < survive)) return has_shadow;
      p->throughput *= 1.0f / survive;
    }
  }
  p->bounce = bounce + 1;
  p->flags |= kPathAlive;
  return has_shadow;
}

TANDEM_HD bool path_shade_hit(const KernelData& kd, const Hit& hit, PathState* p,
                              ShadowRay* shadow) {
  return path_shade_hit_rng(kd, hit, p, shadow, p->rng);
}

TANDEM_HD void path_shadow_result(const ShadowRay& shadow, bool occluded, PathState* p) {
  if (!occluded) p->radiance += shadow.contribution;
}

TANDEM_HD Vec3 path_finish(const KernelData& kd, const PathState& p) {
  const KIntegratorParams& ip = kd.constants.integrator;
  Vec3 radiance = p.radiance;
  if (!is_finite(radiance)) return make_vec3(0.0f);
  if (ip.radiance_clamp > 0.0f) {
    const float m = max_component(radiance);
    if (m > ip.radiance_clamp) radiance *= ip.radiance_clamp / m;
  }
  return radiance;
}

// The megakernel's loop over the stages for one path whose state
// path_generate or path_generate_cached set up, from the hit of its first
// ray (traced by the caller: the CPU tile loop traces a batch of camera rays
// in one Embree packet); `rng` draws p->rng's numbers (p->rng itself, or
// CachedPathRng over it). One loop for every caller and both generators, so
// the megakernels cannot drift apart.
template <class Tracer, class Rng>
TANDEM_HD_INLINE Vec3 render_path_from_hit(const KernelData& kd, const Tracer& tracer, PathState& p,
                                           const Rng& rng, Hit hit, uint32_t* ray_count) {
  for (;;) {
    ++p.rays;
    if (!hit_valid(hit)) {
      path_shade_miss(kd, &p);
      break;
    }
    ShadowRay shadow{};
    if (path_shade_hit_rng(kd, hit, &p, &shadow, rng)) {
      ++p.rays;
      path_shadow_result(shadow, tracer.occluded(shadow.ray, shadow.alpha_key), &p);
    }
    if (!path_alive(p)) break;
    hit = tracer.intersect(p.ray, path_alpha_key(p));
  }
  *ray_count += p.rays;
  return path_finish(kd, p);
}

// render_path_from_hit with the first ray traced here.
template <class Tracer, class Rng>
TANDEM_HD_INLINE Vec3 render_path(const KernelData& kd, const Tracer& tracer, PathState& p,
                                  const Rng& rng, uint32_t* ray_count) {
  return render_path_from_hit(kd, tracer, p, rng, tracer.intersect(p.ray, path_alpha_key(p)),
                              ray_count);
}

// One camera sample of pixel (x, y), the megakernel way: the stages in a
// loop for one path. The pixel's paths depend only on (x, y, sample, seed):
// this is what makes images independent of the tile split and of which
// backend rendered them.
template <class Tracer>
TANDEM_HD Vec3 render_pixel_sample(const KernelData& kd, const Tracer& tracer, uint32_t x,
                                   uint32_t y, uint32_t sample, uint32_t* ray_count) {
  PathState p;
  path_generate(kd, x, y, sample, &p);
  return render_path(kd, tracer, p, p.rng, ray_count);
}

// render_pixel_sample with one call of the tracer per step of the path,
// which alternates between the path's next ray and its shadow ray (the
// stages in the wavefront's order): the same radiance and ray count, bit for
// bit. The GPU's megakernel runs this form: its compiler inlines the
// traversal once instead of twice (closest hit and occlusion), and at 128
// registers the two copies spilled where one does not. `tracer.trace(ray,
// alpha_key, any_hit)` is a closest-hit query, or an occlusion query whose
// hit is valid when occluded.
template <class Tracer>
TANDEM_HD Vec3 render_pixel_sample_one_trace_site(const KernelData& kd, const Tracer& tracer,
                                                  uint32_t x, uint32_t y, uint32_t sample,
                                                  uint32_t* ray_count) {
  PathState p;
  path_generate(kd, x, y, sample, &p);
  ShadowRay shadow;
  bool tracing_shadow = false;
  for (;;) {
    const Hit hit =
        tracer.trace(tracing_shadow ? shadow.ray : p.ray,
                     tracing_shadow ? shadow.alpha_key : path_alpha_key(p), tracing_shadow);
    ++p.rays;
    if (tracing_shadow) {
      path_shadow_result(shadow, hit_valid(hit), &p);
      tracing_shadow = false;
      if (!path_alive(p)) break;
      continue;
    }
    if (!hit_valid(hit)) {
      path_shade_miss(kd, &p);
      break;
    }
    tracing_shadow = path_shade_hit(kd, hit, &p, &shadow);
    if (!tracing_shadow && !path_alive(p)) break;
  }
  *ray_count += p.rays;
  return path_finish(kd, p);
}

// render_pixel_sample with the pixel's cache of sample-independent seeds
// (pixel_rng_cache_reset once per pixel, then any of its samples): the same
// radiance, for the CPU tile loop that renders a pixel's samples in a row.
template <class Tracer>
TANDEM_HD Vec3 render_pixel_sample_cached(const KernelData& kd, const Tracer& tracer, uint32_t x,
                                          uint32_t y, uint32_t sample, PixelRngCache* cache,
                                          uint32_t* ray_count) {
  PathState p;
  path_generate_cached(kd, x, y, sample, cache, &p);
  return render_path(kd, tracer, p, CachedPathRng{p.rng, cache}, ray_count);
}

TANDEM_KERNEL_END
}  // namespace tandem
