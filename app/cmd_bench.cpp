// `tandem bench`: throughput of the path tracer measured against a peer in
// the same run. The peer for the CPU backend is a plain Embree ray-casting
// loop (rtcIntersect1 / rtcOccluded1 with no shading) over rays of the same
// kinds the path tracer casts, so the ratio shows what shading and sampling
// cost on top of Embree itself.
#include <embree3/rtcore.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cstdio>

#include "app/cli_args.h"
#include "app/commands.h"
#include "backends/backend_factory.h"
#include "backends/cpu/embree_backend.h"
#include "core/kernel/integrator.h"
#include "core/render/renderer.h"
#include "core/util/errors.h"
#include "scenes/scene_loader.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& bench_options() {
  static const std::vector<OptionSpec> specs = {
      {"width", true, "image width (default 512)", "W"},
      {"height", true, "image height (default 512)", "H"},
      {"spp", true, "samples per pixel of the path-tracing run (default 16)", "N"},
      {"max-depth", true, "maximum scattering events (default 8)", "D"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"env-color", true, "constant environment radiance (default 0; 1 for glTF files)", "X"},
      {"help", false, "show this help"},
  };
  return specs;
}

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

struct RaySet {
  std::vector<Ray> rays;
  std::vector<uint8_t> is_shadow;
};

// Builds the ray mix of the first bounce: camera rays, cosine-distributed
// rays from their hit points, and shadow rays from the hit points to points
// on the lights (the same sampling code the integrator uses).
RaySet make_ray_set(const KernelData& kd, const EmbreeBackend& backend, uint32_t width,
                    uint32_t height) {
  RaySet set;
  std::vector<Ray> primary;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const PathRng rng = make_path_rng(y * width + x, 0, 12345);
      primary.push_back(generate_camera_ray(kd.constants.camera, float(x) + rng_1d(rng, 0),
                                            float(y) + rng_1d(rng, 1), 0.5f, 0.5f));
    }
  }
  for (size_t i = 0; i < primary.size(); ++i) {
    set.rays.push_back(primary[i]);
    set.is_shadow.push_back(0);
    const Hit hit = backend.intersect(primary[i]);
    if (!hit_valid(hit)) continue;
    const SurfacePoint sp = make_surface_point(kd, hit);
    const PathRng rng = make_path_rng(uint32_t(i), 1, 777);
    const Frame frame =
        make_frame(dot(sp.geometric_normal, primary[i].dir) < 0.0f ? sp.geometric_normal
                                                                   : -sp.geometric_normal);
    const Vec3 d = to_world(frame, sample_cosine_hemisphere(rng_1d(rng, 2), rng_1d(rng, 3)));
    set.rays.push_back(spawn_ray(sp, d));
    set.is_shadow.push_back(0);
    LightSample ls;
    if (sample_light(kd, sp.position, rng_1d(rng, 4), rng_1d(rng, 5), rng_1d(rng, 6), &ls)) {
      set.rays.push_back(ls.at_infinity ? spawn_ray(sp, ls.wi) : spawn_shadow_ray(sp, ls.point));
      set.is_shadow.push_back(1);
    }
  }
  return set;
}

// Plain Embree: no filters, no shading, default context.
double embree_loop_mrays(RTCScene scene, const RaySet& set, int repeats) {
  const auto start = Clock::now();
  for (int r = 0; r < repeats; ++r) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.rays.size(), 1024),
                      [&](const tbb::blocked_range<size_t>& range) {
                        RTCIntersectContext ctx;
                        rtcInitIntersectContext(&ctx);
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const Ray& in = set.rays[i];
                          RTCRayHit rh;
                          rh.ray.org_x = in.origin.x;
                          rh.ray.org_y = in.origin.y;
                          rh.ray.org_z = in.origin.z;
                          rh.ray.dir_x = in.dir.x;
                          rh.ray.dir_y = in.dir.y;
                          rh.ray.dir_z = in.dir.z;
                          rh.ray.tnear = in.tmin;
                          rh.ray.tfar = in.tmax;
                          rh.ray.time = 0.0f;
                          rh.ray.mask = 0xffffffffu;
                          rh.ray.id = 0;
                          rh.ray.flags = 0;
                          if (set.is_shadow[i]) {
                            rtcOccluded1(scene, &ctx, &rh.ray);
                          } else {
                            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                            rtcIntersect1(scene, &ctx, &rh);
                          }
                        }
                      });
  }
  return double(set.rays.size()) * repeats / seconds_since(start) * 1e-6;
}

}  // namespace

int run_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", bench_options(), argv);
  if (args.has("help")) {
    std::printf(
        "usage: tandem bench [SCENE] [options]\n\nMeasures path-tracing throughput against a plain "
        "Embree ray-casting loop on the same scene.\n\n%s",
        format_options_help(bench_options()).c_str());
    return 0;
  }
  if (args.positionals().size() > 1) throw UsageError("bench: expected at most one SCENE argument");
  const std::string spec = args.positionals().empty() ? "builtin:cornell" : args.positionals()[0];
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  std::optional<tbb::global_control> limit;
  if (threads) limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  RenderSettings settings;
  settings.width = args.get_u32("width", 512, 1, 16384);
  settings.height = args.get_u32("height", 512, 1, 16384);
  settings.max_depth = args.get_u32("max-depth", 8, 0, 1024);
  const uint32_t spp = args.get_u32("spp", 16, 1, 1u << 16);

  Scene scene = load_scene(spec);
  const bool is_file = spec.rfind("builtin:", 0) != 0;
  const float env = args.get_float("env-color", is_file ? 1.0f : 0.0f, 0.0f, 1e9f);
  if (env > 0.0f) scene.edit_environment().color = glm::vec3(env);
  if (!scene.has_camera()) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  KernelScene ks;
  SceneCompiler compiler;
  const SceneDelta delta = compiler.compile(scene, settings, ks);
  EmbreeBackend backend;
  const auto build_start = Clock::now();
  backend.sync(ks, delta);
  const double build_s = seconds_since(build_start);
  const KernelData kd = ks.view();

  const int workers = threads ? int(threads) : tbb::info::default_concurrency();
  std::printf("scene %s: %zu triangles, %ux%u, %u spp, max depth %u, %d threads\n", spec.c_str(),
              scene.triangle_count_instanced(), settings.width, settings.height, spp,
              settings.max_depth, workers);
  std::printf("embree build:           %8.3f s\n", build_s);

  const RaySet rays = make_ray_set(kd, backend, settings.width, settings.height);
  embree_loop_mrays(backend.top_level(), rays, 1);  // warm-up
  const double raw = embree_loop_mrays(backend.top_level(), rays, 3);

  OfflineRenderOptions options;
  options.spp = spp;
  const OfflineRenderResult result =
      render_offline(backend, settings.width, settings.height, options);
  const double pt_mrays = double(result.stats.rays) / result.seconds * 1e-6;
  std::printf("plain embree loop:      %8.2f Mrays/s (%zu rays: camera, diffuse, shadow)\n", raw,
              rays.rays.size());
  std::printf("path tracing (cpu):     %8.2f Mrays/s, %.3f M samples/s, %.2f s\n", pt_mrays,
              double(result.stats.samples) / result.seconds * 1e-6, result.seconds);
  std::printf("ratio path/plain:       %8.2f\n", pt_mrays / raw);
  return 0;
}

}  // namespace tandem
