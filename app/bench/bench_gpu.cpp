#include "app/bench/bench_gpu.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "app/bench/bench_report.h"
#include "backends/cuda/cuda_backend.h"
#include "core/render/film.h"
#include "core/render/tiles.h"
#include "core/util/errors.h"
#include "sync/scene_sync.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

const char* layout_name(KBvhLayout layout) {
  return layout == kBvhLayoutWide ? "wide" : "binary";
}

// `scene` compiled under `settings` with its BVH in both layouts, and a
// CUDA backend synced to it.
struct GpuScene {
  SceneSync sync;
  CudaBackend cuda;
  GpuScene(Scene& scene, const RenderSettings& settings)
      : sync([] {
          SceneSyncSettings s;
          s.accel.cache.enabled = false;  // measure without touching the user's BVH cache
          return s;
        }()) {
    sync.update(scene, settings);
    cuda.sync(sync.kernel_scene(), sync.changes_since(0));
  }
  // Switches to `layout`: both layouts are always built, so only the
  // layout constant changes and goes to the device.
  void use_layout(Scene& scene, const RenderSettings& settings, KBvhLayout layout) {
    const uint64_t before = sync.generation();
    sync.set_bvh_layout(layout);
    sync.update(scene, settings);
    cuda.sync(sync.kernel_scene(), sync.changes_since(before));
  }
};

// Mrays/s of CudaBackend::trace_rays, best of three after a warm-up call.
// The figure includes copying the rays to the device and the hits back:
// that is what the public query costs.
double gpu_mrays(CudaBackend& cuda, const std::vector<Ray>& rays, bool any_hit) {
  if (rays.empty()) return 0.0;
  const std::vector<uint32_t> keys(rays.size(), 0u);  // as the Embree loop: alpha key 0
  cuda.trace_rays(rays, keys, any_hit);
  double best = 1e300;
  for (int i = 0; i < 3; ++i) {
    const auto start = Clock::now();
    const std::vector<Hit> hits = cuda.trace_rays(rays, keys, any_hit);
    best = std::min(best, seconds_since(start));
    if (hits.size() != rays.size()) throw std::logic_error("trace_rays returned a short answer");
  }
  return double(rays.size()) / best * 1e-6;
}

GpuFrameFigures time_frames(CudaBackend& cuda, const GpuBenchConfig& c) {
  Film film(c.frame_width, c.frame_height);
  const std::vector<Tile> grid = make_tile_grid(c.frame_width, c.frame_height, 32);
  std::vector<double> frame_seconds;
  double seconds = 0.0;
  uint64_t samples = 0, rays = 0;
  for (uint32_t f = 0; f < c.warmup_frames + c.timed_frames; ++f) {
    TileQueue tiles(grid);
    RenderPass pass;
    pass.sample_begin = f * c.spp;
    pass.sample_count = c.spp;
    const auto start = Clock::now();
    const BackendStats st = cuda.render(pass, tiles, film);
    const double s = seconds_since(start);
    if (f < c.warmup_frames) continue;
    frame_seconds.push_back(s);
    seconds += s;
    samples += st.samples;
    rays += st.rays;
  }
  GpuFrameFigures out;
  out.ms_per_frame_median = median(frame_seconds) * 1e3;
  out.samples_per_second = seconds > 0.0 ? double(samples) / seconds : 0.0;
  out.mrays_per_second = seconds > 0.0 ? double(rays) / seconds * 1e-6 : 0.0;
  return out;
}

}  // namespace

GpuBenchFigures measure_gpu_bench(Scene& scene, const std::string& scene_name,
                                  const CpuBackend& embree, const BenchRays& rays,
                                  const RenderSettings& ray_settings, int embree_threads,
                                  bool frame_camera_from_bounds, const GpuBenchConfig& config) {
  GpuBenchFigures f;
  f.scene = scene_name;
  f.embree_threads = embree_threads;
  f.ray_width = ray_settings.width;
  f.ray_height = ray_settings.height;
  f.frame_width = config.frame_width;
  f.frame_height = config.frame_height;
  f.spp = config.spp;
  f.max_depth = config.max_depth;
  f.warmup_frames = config.warmup_frames;
  f.timed_frames = config.timed_frames;

  // --- The Embree comparison's rays, kind by kind.
  {
    GpuScene gpu(scene, ray_settings);
    CudaBackend& cuda = gpu.cuda;
    f.device = cuda.device_name();
    const std::array<std::vector<Ray>, 3> by_kind = rays_by_kind(rays);
    struct Kind {
      const char* name;
      BenchRayKind kind;
    };
    for (const Kind k :
         {Kind{"camera", BenchRayKind::kPrimary}, Kind{"shadow", BenchRayKind::kShadow},
          Kind{"diffuse", BenchRayKind::kDiffuse}}) {
      GpuRayFigures r;
      r.kind = k.name;
      r.any_hit = k.kind == BenchRayKind::kShadow;
      const std::vector<Ray>& set = by_kind[size_t(k.kind)];
      r.rays = set.size();
      r.embree_mrays = embree_kind_mrays(embree, set, r.any_hit);
      gpu.use_layout(scene, ray_settings, kBvhLayoutBinary);
      r.gpu_binary_mrays = gpu_mrays(cuda, set, r.any_hit);
      gpu.use_layout(scene, ray_settings, kBvhLayoutWide);
      r.gpu_wide_mrays = gpu_mrays(cuda, set, r.any_hit);
      f.rays.push_back(r);
    }
  }

  // --- Path tracing frames at the frame resolution.
  RenderSettings settings;
  settings.width = config.frame_width;
  settings.height = config.frame_height;
  settings.max_depth = config.max_depth;
  if (frame_camera_from_bounds) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  GpuScene gpu(scene, settings);
  CudaBackend& cuda = gpu.cuda;
  for (const CudaKernelVariant kernel : config.kernels) {
    cuda.set_variant(kernel);
    for (const KBvhLayout layout : {kBvhLayoutBinary, kBvhLayoutWide}) {
      gpu.use_layout(scene, settings, layout);
      GpuFrameFigures p = time_frames(cuda, config);
      p.kernel = kernel_variant_name(kernel);
      p.layout = layout_name(layout);
      f.frames.push_back(p);
    }
  }
  return f;
}

}  // namespace tandem
