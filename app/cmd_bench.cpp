// `tandem bench`: throughput of the path tracer measured against a peer in
// the same run. The peer for the CPU backend is a plain Embree ray-casting
// loop (rtcIntersect1 / rtcOccluded1 with no shading) over the rays the path
// tracer casts (recorded from one sample per pixel) and over the first
// bounce's ray mix, so the ratio shows what shading and sampling cost on top
// of Embree itself. With --accstruc it also measures Tandem's own
// BVH against Embree (app/bench/bench_accstruc.h) and path traces on the host
// backend. With --gpu it measures the CUDA backend on the device instead
// (app/bench/bench_gpu.h). Every mode can write its figures as JSON (--json).
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "app/backend_list.h"
#include "app/bench/bench_accstruc.h"
#include "app/bench/bench_deform.h"
#include "app/bench/bench_denoise.h"
#include "app/bench/bench_hetero.h"
#include "app/bench/bench_light_sampling.h"
#include "app/bench/bench_report.h"
#include "app/bench/bench_scene_update.h"
#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/commands.h"
#include "app/distributed.h"
#include "app/scene_setup.h"
#include "app/view/bench_frames.h"
#include "backends/backend_factory.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cpu/embree_tracer.h"
#include "core/kernel/integrator.h"
#include "core/render/offline_render.h"
#include "core/util/errors.h"
#include "sync/scene_sync.h"

#include "app/bench/bench_gpu.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& bench_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      image_size_options("512", "512"),
      {{"spp", true, "samples per pixel of the path-tracing run", "N", "16"},
       {"repeat", true,
        "measure the plain loops and the path tracing this many times, interleaved, and report "
        "each one's median (single runs on a busy machine can differ by a fifth)",
        "N", "1"}},
      path_depth_options("8"),
      light_sampler_options(),
      thread_options(),
      scene_options(),
      environment_options(),
      {
          {"accstruc", false,
           "also measure Tandem's BVH against Embree: build, SAH cost, traversal; and the host "
           "backend"},
          {"hetero", true,
           "also run the core tracer with each backend of LIST (e.g. cpu+host, cuda+cpu) alone "
           "and all together",
           "LIST"},
          {"hetero-frames", true, "frames of 1 spp for --hetero", "N", "16"},
          {"gpu", false,
           "measure the CUDA backend on the device instead: the same rays as the Embree loop "
           "(camera, shadow, diffuse) with both BVH layouts, and path tracing at 1920x1080, 1 "
           "spp, max depth 4 with both kernels and both layouts"},
          {"gpu-frames", true, "timed path-tracing frames per kernel and layout for --gpu", "N",
           "10"},
          {"kernel", true,
           "megakernel | wavefront (mega, wave): the kernel of the cuda and host backends for "
           "--hetero and --accstruc (default megakernel); with --gpu, measure only this kernel",
           "K"},
      },
      json_report_options(),
      help_options(),
  });
  return specs;
}

using Clock = std::chrono::steady_clock;

// The Embree peer loop: rtcIntersect1 / rtcOccluded1 with no shading. It
// goes through EmbreeTracer because the CPU backend's alpha-test filter
// reads the tracer's extended ray context (a bare RTCIntersectContext would
// hand it garbage on scenes with alpha-tested meshes).
double embree_loop_mrays(const CpuBackend& backend, const BenchRays& set, int repeats) {
  const EmbreeTracer tracer = backend.embree_tracer();
  const auto start = Clock::now();
  for (int r = 0; r < repeats; ++r) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.rays.size(), 1024),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const uint32_t key = set.alpha_key.empty() ? 0 : set.alpha_key[i];
                          if (set.kind[i] == BenchRayKind::kShadow) {
                            tracer.occluded(set.rays[i], key);
                          } else {
                            tracer.intersect(set.rays[i], key);
                          }
                        }
                      });
  }
  return double(set.rays.size()) * repeats / seconds_since(start) * 1e-6;
}

}  // namespace

int run_bench(const std::vector<std::string>& argv) {
  if (std::find(argv.begin(), argv.end(), "--distributed") != argv.end())
    return run_distributed_bench(argv);
  if (is_denoise_quality_bench(argv)) return run_denoise_quality_bench(argv);
  if (is_light_sampling_bench(argv)) return run_light_sampling_bench(argv);
  // Before the frame loop: --deform takes --frames too.
  if (is_deform_bench(argv)) return run_deform_bench(argv);
  if (is_frame_bench(argv)) return run_frame_bench(argv);  // the frame loop
  if (is_scene_update_bench(argv)) return run_scene_update_bench(argv);
  const ParsedArgs args("bench", bench_options(), argv);
  if (args.has("help")) {
    std::printf(
        "usage: tandem bench [SCENE] [options]\n"
        "       tandem bench --gpu [SCENE] [options]\n"
        "       tandem bench [SCENE] --frames N [options]   (or --scene SCENE)\n"
        "       tandem bench [SCENE...] --scene-update [options]  (see --scene-update --help)\n"
        "       tandem bench [SCENE...] --deform [options]  (see --deform --help)\n"
        "       tandem bench [SCENE] --light-sampling [options]  (see --light-sampling --help)\n"
        "       mpirun -np N tandem bench --distributed [SCENE] [options]  (see bench "
        "--distributed --help)\n\n"
        "Measures path-tracing throughput against a plain Embree ray-casting loop on the same "
        "scene;\nwith --gpu, the CUDA backend on the device beside Embree; with --frames, the "
        "interactive\nframe loop of tandem-view along its scripted camera path (default scene "
        "builtin:arena).\n\n%s\nFrame-loop mode (--frames N):\n%s",
        format_options_help(bench_options()).c_str(),
        format_options_help(frame_bench_options()).c_str());
    return 0;
  }
  if (args.positionals().size() > 1) throw UsageError("bench: expected at most one SCENE argument");
  const std::string spec = args.positionals().empty() ? "builtin:cornell" : args.positionals()[0];
  // Usage errors first, then the output path and the device, all before
  // anything is measured.
  const bool gpu = args.has("gpu");
  if (gpu && (args.has("accstruc") || args.has("hetero"))) {
    throw UsageError(
        "bench --gpu is a mode of its own: it cannot be combined with --accstruc or "
        "--hetero");
  }
  if (gpu && (args.has("spp") || args.has("max-depth"))) {
    throw UsageError(
        "bench --gpu path traces with 1 spp and max depth 4; --spp and --max-depth "
        "do not apply");
  }
  if (gpu && args.has("repeat")) {
    throw UsageError("bench --gpu times its own frames (--gpu-frames); --repeat does not apply");
  }
  if (!gpu && args.has("gpu-frames")) throw UsageError("--gpu-frames needs --gpu");
  std::vector<BackendKind> kernel_users;  // the backends --kernel would apply to
  if (auto list = args.value("hetero")) kernel_users = parse_backend_list(*list);
  if (args.has("accstruc")) kernel_users.push_back(BackendKind::kHost);
  if (gpu) kernel_users.push_back(BackendKind::kCuda);
  const BackendOptions backend_options = parse_kernel_option(args.value("kernel"), kernel_users);
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  std::optional<tbb::global_control> limit;
  if (threads) limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  RenderSettings settings;
  settings.width = args.get_u32("width", 1, 16384);
  settings.height = args.get_u32("height", 1, 16384);
  settings.max_depth = args.get_u32("max-depth", 0, 1024);
  settings.light_sampler = parse_light_sampler(args);
  const uint32_t spp = args.get_u32("spp", 1, 1u << 16);
  const uint32_t repeat = args.get_u32("repeat", 1, 1, 1000);
  [[maybe_unused]] const uint32_t gpu_frames = args.get_u32("gpu-frames", 1, 100000);
  const SceneRequest scene_request = parse_scene_request(args, spec);
  const std::optional<std::string> json_path = args.value("json");
  if (json_path) check_json_output_path(*json_path);
  if (gpu) {
    std::string reason;
    if (!cuda_device_available(&reason)) throw InputError("bench --gpu: " + reason);
  }

  Scene scene = load_requested_scene(scene_request, "tandem");
  [[maybe_unused]] const bool camera_from_bounds = !scene.has_camera();  // for --gpu
  if (!scene.has_camera()) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  // The scene's kernel arrays; with --accstruc also Tandem's BVH, in the
  // layout the host backend traces, for its path tracing at the end.
  SceneSyncSettings sync_settings;
  sync_settings.bvh = args.has("accstruc");
  sync_settings.accel.cache.enabled = false;  // measure without the user's BVH cache
  sync_settings.accel.layout = CpuBackend(CpuTraversal::kTandemBvh).traits().bvh_layout;
  SceneSync scene_sync(sync_settings);
  scene_sync.update(scene, settings);
  const KernelScene& ks = scene_sync.kernel_scene();
  CpuBackend backend{CpuTraversal::kEmbree};
  const auto build_start = Clock::now();
  backend.sync(ks, scene_sync.changes_since(0));
  const double build_s = seconds_since(build_start);
  const KernelData kd = ks.view();

  const int workers = threads ? int(threads) : tbb::info::default_concurrency();
  if (!gpu) {
    std::printf("scene %s: %zu triangles, %ux%u, %u spp, max depth %u, %d threads\n", spec.c_str(),
                scene.triangle_count_instanced(), settings.width, settings.height, spp,
                settings.max_depth, workers);
  }
  std::printf("embree build:           %8.3f s\n", build_s);

  const BenchRays rays = make_bench_rays(kd, backend, settings.width, settings.height);
  if (gpu) {
    GpuBenchConfig config;
    config.timed_frames = gpu_frames;
    if (args.has("kernel")) config.kernels = {backend_options.kernel};
    const GpuBenchFigures figures = measure_gpu_bench(scene, spec, backend, rays, settings, workers,
                                                      camera_from_bounds, config);
    std::printf("%s", format_gpu_bench_table(figures).c_str());
    JsonValue report = bench_report("gpu", workers);
    add_gpu_bench_json(report, figures);
    report.set("triangles", uint64_t(scene.triangle_count_instanced()));
    report.set("embree_build_seconds", build_s);
    write_json_report(json_path, report);
    return 0;
  }
  // Two peers: the first bounce's ray mix (make_bench_rays, the figure
  // earlier rounds were measured against) and the path tracer's own rays
  // replayed (record_path_rays): the same mix of camera, bounce and shadow
  // rays the path tracing below casts, so their ratio is what shading and
  // sampling cost on top of exactly those rays.
  const BenchRays path_rays = record_path_rays(kd, backend);
  uint64_t path_ray_kinds[3] = {0, 0, 0};
  for (BenchRayKind k : path_rays.kind)
    ++path_ray_kinds[size_t(k)];
  embree_loop_mrays(backend, rays, 1);  // warm-up
  embree_loop_mrays(backend, path_rays, 1);
  OfflineRenderOptions options;
  options.spp = spp;
  // Each run measures the three one after the other, so that a slow
  // minute of a shared machine slows all three of that run.
  std::vector<double> raw_runs, raw_path_runs, pt_runs, samples_runs, seconds_runs;
  uint64_t pt_rays = 0;
  for (uint32_t r = 0; r < repeat; ++r) {
    raw_runs.push_back(embree_loop_mrays(backend, rays, 3));
    raw_path_runs.push_back(embree_loop_mrays(backend, path_rays, 3));
    const OfflineRenderResult result =
        render_offline(backend, settings.width, settings.height, options);
    pt_runs.push_back(double(result.stats.rays) / result.seconds * 1e-6);
    samples_runs.push_back(double(result.stats.samples) / result.seconds);
    seconds_runs.push_back(result.seconds);
    pt_rays = result.stats.rays;
  }
  const double raw = median(raw_runs), raw_path = median(raw_path_runs), pt_mrays = median(pt_runs);
  if (repeat > 1) std::printf("medians of %u interleaved runs:\n", repeat);
  std::printf("plain embree loop:      %8.2f Mrays/s (%zu rays: camera, diffuse, shadow)\n", raw,
              rays.rays.size());
  std::printf(
      "plain loop, path rays:  %8.2f Mrays/s (%zu rays of 1 spp: %llu camera, %llu bounce, %llu "
      "shadow)\n",
      raw_path, path_rays.rays.size(), static_cast<unsigned long long>(path_ray_kinds[0]),
      static_cast<unsigned long long>(path_ray_kinds[1]),
      static_cast<unsigned long long>(path_ray_kinds[2]));
  std::printf("path tracing (cpu):     %8.2f Mrays/s, %.3f M samples/s, %.2f s\n", pt_mrays,
              median(samples_runs) * 1e-6, median(seconds_runs));
  std::printf("ratio path/plain:       %8.2f (first-bounce rays), %.2f (the path's own rays)\n",
              pt_mrays / raw, pt_mrays / raw_path);
  if (repeat > 1) {
    auto range = [](const std::vector<double>& v) {
      const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
      return std::make_pair(*lo, *hi);
    };
    const auto [raw_lo, raw_hi] = range(raw_runs);
    const auto [path_lo, path_hi] = range(raw_path_runs);
    const auto [pt_lo, pt_hi] = range(pt_runs);
    std::printf(
        "min-max of the %u runs, Mrays/s: plain %.2f-%.2f, path rays %.2f-%.2f, path tracing "
        "%.2f-%.2f\n",
        repeat, raw_lo, raw_hi, path_lo, path_hi, pt_lo, pt_hi);
  }
  JsonValue report = bench_report("path", workers);
  set_render_facts(report, spec, settings.width, settings.height, spp, settings.max_depth);
  report.set("triangles", uint64_t(scene.triangle_count_instanced()));
  report.set("embree_build_seconds", build_s);
  report.set("bench_rays", uint64_t(rays.rays.size()));
  report.set("plain_embree_mrays_per_second", raw);
  report.set("plain_embree_path_rays", JsonValue::object()
                                           .set("rays", uint64_t(path_rays.rays.size()))
                                           .set("camera", path_ray_kinds[0])
                                           .set("bounce", path_ray_kinds[1])
                                           .set("shadow", path_ray_kinds[2])
                                           .set("mrays_per_second", raw_path));
  report.set("path_tracing_cpu", JsonValue::object()
                                     .set("mrays_per_second", pt_mrays)
                                     .set("samples_per_second", median(samples_runs))
                                     .set("rays", pt_rays)
                                     .set("seconds", median(seconds_runs)));
  report.set("ratio_path_over_plain", pt_mrays / raw);
  report.set("ratio_path_over_plain_path_rays", pt_mrays / raw_path);
  report.set("repeat", repeat);
  report.set("runs_mrays_per_second",
             JsonValue::object()
                 .set("plain_embree", json_number_list(raw_runs))
                 .set("plain_embree_path_rays", json_number_list(raw_path_runs))
                 .set("path_tracing_cpu", json_number_list(pt_runs)));

  if (args.has("accstruc")) {
    report.set("accstruc", run_accstruc_bench(scene_sync, backend, rays, workers));
    // The same path tracing on the host backend: our BVH (in the layout the
    // host backend traces) under the same kernels.
    CpuBackend host{CpuTraversal::kTandemBvh};
    host.sync(ks, scene_sync.changes_since(0));
    const OfflineRenderResult h = render_offline(host, settings.width, settings.height, options);
    const double host_mrays = double(h.stats.rays) / h.seconds * 1e-6;
    std::printf("path tracing (host):    %8.2f Mrays/s, %.3f M samples/s, %.2f s (host/cpu %.2f)\n",
                host_mrays, double(h.stats.samples) / h.seconds * 1e-6, h.seconds,
                host_mrays / pt_mrays);
    report.set("path_tracing_host",
               JsonValue::object()
                   .set("mrays_per_second", host_mrays)
                   .set("samples_per_second", double(h.stats.samples) / h.seconds)
                   .set("seconds", h.seconds)
                   .set("host_vs_cpu", host_mrays / pt_mrays));
  }
  if (auto list = args.value("hetero")) {
    report.set("hetero",
               run_hetero_bench(scene, settings, args.get_u32("hetero-frames", 1, 1u << 20), *list,
                                backend_options));
  }
  write_json_report(json_path, report);
  return 0;
}

}  // namespace tandem
