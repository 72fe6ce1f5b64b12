// The integrator's stages against the path-tracing loop they replaced: the
// megakernel (render_pixel_sample, a loop over the stages) must give the
// images the single loop gave, bit for bit, for the same seed. The loop is
// kept here, frozen, as the reference: it draws the same random numbers and
// adds to the radiance in the same order, which is what the stage split
// promises.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "accstruc/accel_structure.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cpu_loops/cpu_wavefront.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/integrator.h"
#include "core/render/offline_render.h"
#include "core/world/kernel_scene.h"
#include "scenes/procedural_scenes.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

template <class Tracer>
Vec3 reference_trace_path(const KernelData& kd, const Tracer& tracer, Ray ray, const PathRng& rng,
                          uint32_t* ray_count) {
  const KIntegratorParams& ip = kd.constants.integrator;
  Vec3 radiance = make_vec3(0.0f);
  Vec3 beta = make_vec3(1.0f);
  float prev_bsdf_pdf = 0.0f;                                   // 0: camera ray, no MIS on emission
  Vec3 prev_point = ray.origin, prev_normal = make_vec3(0.0f);  // where the ray left
  float eta_scale = 1.0f;  // eta^2 of the refractions so far, for the roulette
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
              ? mis_power_heuristic(prev_bsdf_pdf, triangle_light_pdf(kd, hit, sp, ray.dir, hit.t,
                                                                      prev_point, prev_normal))
              : 1.0f;
      radiance += beta * le * w;
    }
    if (bounce >= ip.max_depth) break;

    ShadingSetup sh;
    if (!setup_shading(kd, sp, wo, &sh)) break;

    // Next-event estimation; at a smooth mirror or glass of punctual and
    // directional lights only, the BSDF sample then has no MIS.
    const bool specular = bsdf_near_specular(sh.params, sh.lobes);
    LightSample ls;
    const Vec2 light_uv = rng_2d(rng, bounce_dimension(bounce, kBounceLightU));
    const Vec3 receiver = sh.params.transmission > 0.0f ? make_vec3(0.0f) : sh.ng;
    if (sample_light(kd, sp.position, receiver,
                     rng_1d(rng, bounce_dimension(bounce, kBounceLightSelect)), light_uv.x,
                     light_uv.y, &ls, specular)) {
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
    prev_bsdf_pdf = specular ? 0.0f : bs.pdf;
    ray = spawn_ray(sp, wi);
    prev_point = sp.position;
    prev_normal = receiver;

    if (bs.wi.z < 0.0f) eta_scale *= sh.params.eta * sh.params.eta;
    if (bounce + 1 >= ip.rr_start_depth) {
      // The kernel's rule, written out: q = min(1, sqrt(max throughput)) of
      // the throughput without the refractions' eta^2, no draw while q is 1.
      const float survive = min_f(sqrtf(max_f(max_component(beta * eta_scale), 0.0f)), 1.0f);
      if (survive < 1.0f) {
        if (!(rng_1d(rng, bounce_dimension(bounce, kBounceRoulette)) < survive)) break;
        beta *= 1.0f / survive;
      }
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

Vec3 reference_pixel_sample(const KernelData& kd, uint32_t x, uint32_t y, uint32_t sample,
                            uint32_t* rays) {
  const KCamera& cam = kd.constants.camera;
  const PathRng rng = make_path_rng(y * cam.width + x, sample, kd.constants.integrator.seed);
  const Vec2 jitter = rng_2d(rng, kDimPixelJitter), lens = rng_2d(rng, kDimLens);
  const Ray ray =
      generate_camera_ray(cam, float(x) + jitter.x, float(y) + jitter.y, lens.x, lens.y);
  return reference_trace_path(kd, BvhTracer{&kd}, ray, rng, rays);
}

// Every sample of a width x height image (spp each) bit for bit what the
// frozen reference loop gives, with as many rays; returns those rays.
uint32_t expect_reference_bits(const KernelData& kd, uint32_t width, uint32_t height,
                               uint32_t spp) {
  size_t same = 0, total = 0;
  uint32_t rays_new = 0, rays_ref = 0;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      for (uint32_t s = 0; s < spp; ++s) {
        const Vec3 a = render_pixel_sample(kd, BvhTracer{&kd}, x, y, s, &rays_new);
        const Vec3 b = reference_pixel_sample(kd, x, y, s, &rays_ref);
        same += std::memcmp(&a, &b, sizeof a) == 0;
        ++total;
      }
    }
  }
  EXPECT_EQ(same, total);
  EXPECT_EQ(rays_new, rays_ref);
  return rays_ref;
}

struct Compiled {
  Scene scene;
  SceneSync sync{SceneSyncSettings{.bvh = true, .accel = no_cache()}};
  const KernelScene& ks = sync.kernel_scene();
  static AccelSettings no_cache() {
    AccelSettings as;
    as.cache.enabled = false;
    return as;
  }
  Compiled(Scene s, uint32_t width, uint32_t height, uint32_t seed) : scene(std::move(s)) {
    RenderSettings rs;
    rs.width = width;
    rs.height = height;
    rs.seed = seed;
    rs.radiance_clamp = 20.0f;  // the clamp is part of what must agree
    if (!scene.has_camera())
      scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, float(width) / float(height)));
    sync.update(scene, rs);
  }
};

// builtin:NAME, or "procedural"; the sky-plane gets a sky to be lit by.
Scene test_scene(const std::string& spec) {
  Scene scene = spec == "procedural" ? make_procedural_scene(20000, 2) : load_scene(spec);
  if (spec == "builtin:sky-plane") scene.edit_environment().color = glm::vec3(0.8f);
  return scene;
}

TEST(RenderIntegrator, StagesGiveTheSingleLoopsImagesBitForBit) {
  const uint32_t width = 40, height = 30;
  for (const char* spec :
       {"builtin:cornell", "builtin:cornell-spheres", "builtin:sky-plane", "builtin:furnace"}) {
    SCOPED_TRACE(spec);
    Scene scene = load_scene(spec);
    if (std::string(spec) == "builtin:sky-plane") scene.edit_environment().color = glm::vec3(0.8f);
    Compiled c(std::move(scene), width, height, 11);
    const uint32_t rays = expect_reference_bits(c.ks.view(), width, height, 3);
    EXPECT_GT(rays, width * height * 3);  // the scenes do scatter
  }
}

// The CPU tile loop's megakernel with the pixel's seed cache gives the
// plain megakernel's bits and rays, also for paths deeper than the cache
// (max depth 40 between the mirror and the glass sphere).
TEST(RenderIntegrator, PixelRngCacheGivesThePlainMegakernelsBits) {
  const uint32_t width = 24, height = 16, spp = 4;
  for (const char* spec : {"builtin:cornell", "builtin:cornell-spheres", "builtin:sky-plane"}) {
    for (uint32_t max_depth : {8u, 40u}) {
      SCOPED_TRACE(std::string(spec) + " max depth " + std::to_string(max_depth));
      Compiled c(test_scene(spec), width, height, 3);
      KernelData kd = c.ks.view();
      kd.constants.integrator.max_depth = max_depth;
      PixelRngCache cache;
      size_t same = 0;
      uint32_t rays_plain = 0, rays_cached = 0;
      for (uint32_t y = 0; y < height; ++y) {
        for (uint32_t x = 0; x < width; ++x) {
          pixel_rng_cache_reset(&cache, y * width + x, kd.constants.integrator.seed);
          for (uint32_t s = 7; s < 7 + spp; ++s) {
            const Vec3 a = render_pixel_sample(kd, BvhTracer{&kd}, x, y, s, &rays_plain);
            const Vec3 b =
                render_pixel_sample_cached(kd, BvhTracer{&kd}, x, y, s, &cache, &rays_cached);
            same += std::memcmp(&a, &b, sizeof a) == 0;
          }
        }
      }
      EXPECT_EQ(same, size_t(width) * height * spp);
      EXPECT_EQ(rays_plain, rays_cached);
    }
  }
}

// The wavefront queues with few slots (each regenerated many times, paths
// of every length in flight together) compute each item's radiance exactly
// as the megakernel does, and count the same rays.
TEST(RenderIntegrator, WavefrontQueuesGiveTheMegakernelsBits) {
  const uint32_t width = 24, height = 16, spp = 3;
  Compiled c(load_scene("builtin:cornell-spheres"), width, height, 5);
  const KernelData kd = c.ks.view();
  std::vector<DeviceTile> tiles = {{0, 0, 24, 8, 0}, {0, 8, 24, 16, 24 * 8}};
  TileBatch batch;
  batch.tiles = tiles.data();
  batch.tile_count = 2;
  batch.pixel_count = width * height;
  batch.sample_begin = 4;
  batch.sample_count = spp;
  for (uint32_t slots : {1u, 7u, 100u, 5000u}) {
    SCOPED_TRACE("slots " + std::to_string(slots));
    CpuWavefrontStorage storage;
    std::vector<Vec3> wave(batch.items());
    const uint64_t rays =
        run_wavefront_on_cpu(kd, BvhTracer{&kd}, batch, slots, storage, wave.data());
    uint32_t mega_rays = 0;
    size_t same = 0;
    for (uint64_t item = 0; item < batch.items(); ++item) {
      uint32_t x, y, sample;
      batch_item(batch, item, &x, &y, &sample);
      const Vec3 m = render_pixel_sample(kd, BvhTracer{&kd}, x, y, sample, &mega_rays);
      same += std::memcmp(&m, &wave[item], sizeof m) == 0;
    }
    EXPECT_EQ(same, batch.items());
    EXPECT_EQ(rays, mega_rays);
  }
}

// The host backend's two kernels give the same image, bit for bit.
TEST(RenderIntegrator, HostBackendWavefrontMatchesItsMegakernel) {
  const uint32_t width = 48, height = 32;
  for (const char* spec : {"builtin:cornell", "builtin:sky-plane", "procedural"}) {
    SCOPED_TRACE(spec);
    Compiled c(test_scene(spec), width, height, 9);
    CpuBackend mega(CpuTraversal::kTandemBvh),
        wave(CpuTraversal::kTandemBvh, CudaKernelVariant::kWavefront);
    mega.sync(c.ks, SceneDelta::everything());
    wave.sync(c.ks, SceneDelta::everything());
    OfflineRenderOptions options;
    options.spp = 5;
    options.tile_size = 16;
    const OfflineRenderResult a = render_offline(mega, width, height, options);
    const OfflineRenderResult b = render_offline(wave, width, height, options);
    EXPECT_EQ(
        std::memcmp(a.image.rgb.data(), b.image.rgb.data(), a.image.rgb.size() * sizeof(float)), 0);
    EXPECT_EQ(a.stats.rays, b.stats.rays);
    EXPECT_EQ(a.stats.samples, b.stats.samples);
  }
}

// Embree's packets in the wavefront pipeline trace the same paths as its
// single rays up to the traversal's own rounding: same seed, same pixels
// but for a few.
TEST(RenderIntegrator, EmbreePacketWavefrontMatchesItsRayLoop) {
  const uint32_t width = 48, height = 32;
  for (const char* spec : {"builtin:cornell", "procedural"}) {
    SCOPED_TRACE(spec);
    Compiled c(test_scene(spec), width, height, 9);
    CpuBackend rays(CpuTraversal::kEmbree),
        packets(CpuTraversal::kEmbree, CudaKernelVariant::kWavefront);
    rays.sync(c.ks, SceneDelta::everything());
    packets.sync(c.ks, SceneDelta::everything());
    OfflineRenderOptions options;
    options.spp = 2;
    const ImageRGB a = render_offline(rays, width, height, options).image;
    const ImageRGB b = render_offline(packets, width, height, options).image;
    size_t same = 0;
    for (size_t i = 0; i < size_t(width) * height; ++i)
      same += std::memcmp(&a.rgb[3 * i], &b.rgb[3 * i], 12) == 0;
    EXPECT_GE(double(same), 0.97 * width * height);
  }
}

// Rays carry alpha keys only in scenes with alpha-tested meshes; there the
// keys are the ones the frozen loop draws, so stochastic transparency (the
// procedural scene's BLEND leaves) gives its images bit for bit.
TEST(RenderIntegrator, AlphaKeysOnlyWhereSomeMeshIsAlphaTested) {
  const uint32_t width = 32, height = 24;
  Compiled box(load_scene("builtin:cornell"), width, height, 4);
  EXPECT_EQ(box.ks.constants.scene_flags & kSceneHasAlphaTest, 0u);
  Compiled leaves(test_scene("procedural"), width, height, 4);
  EXPECT_NE(leaves.ks.constants.scene_flags & kSceneHasAlphaTest, 0u);

  const KernelData box_kd = box.ks.view(), leaves_kd = leaves.ks.view();
  PathState p;
  path_generate(box_kd, 3, 5, 2, &p);
  EXPECT_EQ(path_alpha_key(p), 0u);
  path_generate(leaves_kd, 3, 5, 2, &p);
  EXPECT_EQ(path_alpha_key(p), rng_bits(p.rng, bounce_dimension(0, kBounceAlpha)));
  EXPECT_NE(path_alpha_key(p), 0u);

  expect_reference_bits(leaves_kd, width, height, 2);
}

}  // namespace
}  // namespace tandem

// Russian roulette never ends a path whose throughput is still >= 1 (a
// lossless mirror or glass chain), and below 1 keeps it with probability
// sqrt(max component), which the 1/q weight makes unbiased.
TEST(RenderIntegrator, RouletteKeepsLosslessPathsAndSqrtBelow) {
  EXPECT_EQ(tandem::roulette_survival(tandem::make_vec3(1.0f)), 1.0f);
  EXPECT_EQ(tandem::roulette_survival(tandem::make_vec3(3.0f, 0.0f, 0.0f)), 1.0f);
  EXPECT_EQ(tandem::roulette_survival(tandem::make_vec3(0.25f, 0.01f, 0.0f)), 0.5f);
  EXPECT_NEAR(tandem::roulette_survival(tandem::make_vec3(0.0f, 0.0f, 0.04f)), 0.2f, 1e-7f);
  EXPECT_EQ(tandem::roulette_survival(tandem::make_vec3(0.0f)), 0.0f);
}
