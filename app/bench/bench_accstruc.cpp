#include "app/bench/bench_accstruc.h"

#include "app/bench/bench_report.h"

#include <embree3/rtcore.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <string>

#include "accstruc/accel_structure.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cpu/embree_tracer.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/integrator.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

// The machine is shared and timings are noisy: every figure is the best of
// a few runs (the least disturbed one).
constexpr int kRepeats = 3;

template <class F>
double best_seconds(F&& run) {
  double best = 1e300;
  for (int i = 0; i < kRepeats; ++i) {
    const auto start = Clock::now();
    run();
    best = std::min(best, seconds_since(start));
  }
  return best;
}

uint64_t unique_triangles(const KernelScene& ks) {
  uint64_t n = 0;
  for (const KMesh& m : ks.meshes)
    n += m.triangle_count;
  return n;
}

// Every BLAS from scratch with our builder (binned SAH, then the binary and
// wide layouts), as AccelStructure builds them: meshes in parallel, and in
// parallel within each mesh. No disk cache: this measures the build. The
// builder's own benchmark, so it drives AccelStructure directly, on a copy
// of the arrays (built into again and again, as a scene's full update
// would: the pages are warm after the first build).
double our_blas_seconds(const KernelScene& compiled, const AccelSettings& settings) {
  AccelSettings s = settings;
  s.cache.enabled = false;
  KernelScene ks = compiled;
  return best_seconds([&] {
    AccelStructure accel(s);
    SceneDelta full;
    full.full = true;
    accel.update(ks, full);
  });
}

// The same meshes through Embree's builder (rtcCommitScene of one scene per
// mesh, in parallel across meshes as ours), at the given build quality.
// Embree runs on the same TBB, so the same global_control limits both.
double embree_blas_seconds(const KernelScene& ks, RTCBuildQuality quality) {
  RTCDevice device = rtcNewDevice(nullptr);
  if (!device) throw std::runtime_error("cannot create an Embree device");
  const double s = best_seconds([&] {
    std::vector<RTCScene> scenes(ks.meshes.size(), nullptr);
    tbb::parallel_for(size_t(0), ks.meshes.size(), [&](size_t m) {
      const KMesh& km = ks.meshes[m];
      RTCScene scene = rtcNewScene(device);
      rtcSetSceneBuildQuality(scene, quality);
      if (km.triangle_count > 0) {
        RTCGeometry g = new_mesh_geometry(device, ks, uint32_t(m), quality);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(scene, g, 0);
        rtcReleaseGeometry(g);
      }
      rtcCommitScene(scene);
      scenes[m] = scene;
    });
    for (RTCScene sc : scenes)
      rtcReleaseScene(sc);
  });
  rtcReleaseDevice(device);
  return s;
}

// Triangle-weighted mean SAH cost of every mesh's BLAS built with `method`
// (the binary tree; costs are relative to each root's area).
double mean_sah_cost(const KernelScene& ks, const BuildSettings& settings) {
  double weighted = 0.0, weight = 0.0;
  for (uint32_t m = 0; m < ks.meshes.size(); ++m) {
    const std::vector<Aabb> boxes = triangle_boxes(mesh_geometry(ks, m));
    const BuildTree tree = build_bvh(boxes, settings);
    if (tree.empty()) continue;
    weighted += sah_cost(tree, settings.traversal_cost, settings.intersection_cost) * boxes.size();
    weight += double(boxes.size());
  }
  return weight > 0.0 ? weighted / weight : 0.0;
}

// Mrays/s of one tracer over the rays of one kind (closest hit, or any hit
// for shadow rays). The checksum keeps the compiler from dropping the work
// and lets the tracers be compared for sanity.
struct Throughput {
  double mrays = 0.0;
  uint64_t hits = 0;
};

// One pass of a tracer over the rays of one kind: seconds, and the hits.
template <class Tracer>
double trace_once(const Tracer& tracer, const std::vector<Ray>& rays, bool shadow,
                  uint64_t* hits_out) {
  std::atomic<uint64_t> hits{0};
  const auto start = Clock::now();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 1024),
                    [&](const tbb::blocked_range<size_t>& r) {
                      uint64_t h = 0;
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        h += shadow ? uint64_t(tracer.occluded(rays[i], 0))
                                    : uint64_t(hit_valid(tracer.intersect(rays[i], 0)));
                      }
                      hits += h;
                    });
  const double s = seconds_since(start);
  *hits_out = hits.load();
  return s;
}

// Passes of the traversal comparison per tracer.
constexpr int kTraversalRepeats = 5;

// Embree, our binary and our wide layout over the same rays, their passes
// interleaved (Embree, binary, wide, Embree, ...) so that a slow spell of a
// shared machine hits all three alike; the best pass of each.
template <class A, class B, class C>
std::array<Throughput, 3> trace_kind_interleaved(const A& a, const B& b, const C& c,
                                                 const std::vector<Ray>& rays, bool shadow) {
  double best[3] = {1e300, 1e300, 1e300};
  std::array<Throughput, 3> t;
  for (int rep = 0; rep < kTraversalRepeats; ++rep) {
    best[0] = std::min(best[0], trace_once(a, rays, shadow, &t[0].hits));
    best[1] = std::min(best[1], trace_once(b, rays, shadow, &t[1].hits));
    best[2] = std::min(best[2], trace_once(c, rays, shadow, &t[2].hits));
  }
  for (int i = 0; i < 3; ++i)
    t[i].mrays = double(rays.size()) / best[i] * 1e-6;
  return t;
}

// Traversal work per ray of one layout over the rays of one kind: one
// counted pass (the counting instantiation of the traversal, never the one
// that is timed).
struct PerRayCounts {
  double nodes = 0.0, boxes = 0.0, triangles = 0.0, instances = 0.0, blas_nodes = 0.0;
};

PerRayCounts count_kind(const KernelData& kd, const std::vector<Ray>& rays, bool shadow) {
  BvhCounters total;
  std::mutex merge;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 1024),
                    [&](const tbb::blocked_range<size_t>& r) {
                      BvhCounters c;
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        bvh_trace_counted<true>(kd, rays[i], 0, kd.bvh.layout, shadow, &c);
                      }
                      const std::lock_guard<std::mutex> lock(merge);
                      total.nodes += c.nodes;
                      total.boxes += c.boxes;
                      total.triangles += c.triangles;
                      total.instances += c.instances;
                      total.blas_nodes += c.blas_nodes;
                    });
  PerRayCounts p;
  if (rays.empty()) return p;
  const double n = double(rays.size());
  p.nodes = double(total.nodes) / n;
  p.boxes = double(total.boxes) / n;
  p.triangles = double(total.triangles) / n;
  p.instances = double(total.instances) / n;
  p.blas_nodes = double(total.blas_nodes) / n;
  return p;
}

JsonValue counts_json(const PerRayCounts& c) {
  return JsonValue::object()
      .set("nodes_per_ray", c.nodes)
      .set("tlas_nodes_per_ray", c.nodes - c.blas_nodes)
      .set("box_tests_per_ray", c.boxes)
      .set("triangle_tests_per_ray", c.triangles)
      .set("blas_entered_per_ray", c.instances);
}

}  // namespace

BenchRays make_bench_rays(const KernelData& kd, const CpuBackend& embree, uint32_t width,
                          uint32_t height) {
  BenchRays set;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const uint32_t pixel = y * width + x;
      PathRng rng = make_path_rng(pixel, 0, 12345);
      const Ray primary = generate_camera_ray(kd.constants.camera, float(x) + rng_1d(rng, 0),
                                              float(y) + rng_1d(rng, 1), 0.5f, 0.5f);
      set.rays.push_back(primary);
      set.kind.push_back(BenchRayKind::kPrimary);
      const Hit hit = embree.intersect(primary);
      if (!hit_valid(hit)) continue;
      const SurfacePoint sp = make_surface_point(kd, hit);
      rng = make_path_rng(pixel, 1, 777);
      const Frame frame =
          make_frame(dot(sp.geometric_normal, primary.dir) < 0.0f ? sp.geometric_normal
                                                                  : -sp.geometric_normal);
      const Vec3 d = to_world(frame, sample_cosine_hemisphere(rng_1d(rng, 2), rng_1d(rng, 3)));
      set.rays.push_back(spawn_ray(sp, d));
      set.kind.push_back(BenchRayKind::kDiffuse);
      LightSample ls;
      if (sample_light(kd, sp.position, frame.n, rng_1d(rng, 4), rng_1d(rng, 5), rng_1d(rng, 6),
                       &ls)) {
        set.rays.push_back(ls.at_infinity ? spawn_ray(sp, ls.wi) : spawn_shadow_ray(sp, ls.point));
        set.kind.push_back(BenchRayKind::kShadow);
      }
    }
  }
  return set;
}

namespace {

// A kernel Tracer that answers through Embree and appends each query to a
// BenchRays. The caller sets `camera_next` before each path: a path's first
// closest-hit query is its camera ray.
struct RecordingTracer {
  EmbreeTracer inner;
  BenchRays* out;
  mutable bool camera_next = true;

  void record(const Ray& ray, uint32_t alpha_key, BenchRayKind kind) const {
    out->rays.push_back(ray);
    out->kind.push_back(kind);
    out->alpha_key.push_back(alpha_key);
  }
  Hit intersect(const Ray& ray, uint32_t alpha_key) const {
    record(ray, alpha_key, camera_next ? BenchRayKind::kPrimary : BenchRayKind::kDiffuse);
    camera_next = false;
    return inner.intersect(ray, alpha_key);
  }
  bool occluded(const Ray& ray, uint32_t alpha_key) const {
    record(ray, alpha_key, BenchRayKind::kShadow);
    return inner.occluded(ray, alpha_key);
  }
};

}  // namespace

BenchRays record_path_rays(const KernelData& kd, const CpuBackend& embree) {
  const uint32_t width = kd.constants.camera.width, height = kd.constants.camera.height;
  const uint64_t pixels = uint64_t(width) * height;
  const uint32_t row_step = uint32_t((pixels + kMaxRecordedPaths - 1) / kMaxRecordedPaths);
  BenchRays set;
  const RecordingTracer tracer{embree.embree_tracer(), &set};
  PixelRngCache cache;
  uint32_t rays = 0;
  for (uint32_t y = 0; y < height; y += row_step) {
    for (uint32_t x = 0; x < width; ++x) {
      pixel_rng_cache_reset(&cache, y * width + x, kd.constants.integrator.seed);
      tracer.camera_next = true;
      render_pixel_sample_cached(kd, tracer, x, y, 0, &cache, &rays);
    }
  }
  return set;
}

std::array<std::vector<Ray>, 3> rays_by_kind(const BenchRays& set) {
  std::array<std::vector<Ray>, 3> by_kind;
  for (size_t i = 0; i < set.rays.size(); ++i)
    by_kind[size_t(set.kind[i])].push_back(set.rays[i]);
  return by_kind;
}

double embree_kind_mrays(const CpuBackend& embree, const std::vector<Ray>& rays, bool shadow) {
  const EmbreeTracer tracer = embree.embree_tracer();
  uint64_t hits = 0;
  return double(rays.size()) / best_seconds([&] { trace_once(tracer, rays, shadow, &hits); }) *
         1e-6;
}

JsonValue run_accstruc_bench(const SceneSync& scene_sync, const CpuBackend& embree,
                             const BenchRays& rays, int threads) {
  const KernelScene& ks = scene_sync.kernel_scene();
  const uint64_t tris = unique_triangles(ks);
  std::printf(
      "\naccstruc: %zu meshes, %llu unique triangles, best of %d builds and of %d interleaved "
      "traversal passes\n",
      ks.meshes.size(), static_cast<unsigned long long>(tris), kRepeats, kTraversalRepeats);

  // --- BLAS builds, same meshes, same threads.
  const AccelSettings settings;
  const double ours = our_blas_seconds(ks, settings);
  const double emb_medium = embree_blas_seconds(ks, RTC_BUILD_QUALITY_MEDIUM);
  const double emb_high = embree_blas_seconds(ks, RTC_BUILD_QUALITY_HIGH);
  auto mtris = [&](double s) { return double(tris) / s * 1e-6; };
  std::printf("BLAS build, %d threads (Mtris/s; ours = binned SAH + binary & wide layouts):\n",
              threads);
  std::printf(
      "  ours %8.2f | embree medium %8.2f (ours/embree %.2f) | embree high %8.2f "
      "(ours/embree %.2f)\n",
      mtris(ours), mtris(emb_medium), emb_medium / ours, mtris(emb_high), emb_high / ours);
  JsonValue json = JsonValue::object();
  json.set("meshes", uint64_t(ks.meshes.size()))
      .set("unique_triangles", tris)
      .set("best_of_runs", kRepeats)
      .set("traversal_best_of_interleaved_passes", kTraversalRepeats)
      .set("blas_build", JsonValue::object()
                             .set("threads", threads)
                             .set("ours_mtris_per_second", mtris(ours))
                             .set("embree_medium_mtris_per_second", mtris(emb_medium))
                             .set("embree_high_mtris_per_second", mtris(emb_high))
                             .set("ours_vs_embree_medium", emb_medium / ours)
                             .set("ours_vs_embree_high", emb_high / ours));

  // --- SAH cost of our BLAS (binary and wide, as stored) vs a median split.
  if (!scene_sync.accel()) throw std::logic_error("run_accstruc_bench: the scene has no BVH");
  const AccelStructure& accel = *scene_sync.accel();
  double sah = 0.0, wide_sah = 0.0, weight = 0.0;
  for (uint32_t m = 0; m < accel.blas_count(); ++m) {
    const double w = ks.meshes[m].triangle_count;
    sah += accel.blas(m).sah_cost * w;
    wide_sah += accel.blas(m).wide_sah_cost * w;
    weight += w;
  }
  BuildSettings median = settings.blas;
  median.method = SplitMethod::kMedian;
  const double median_sah = mean_sah_cost(ks, median);
  if (weight > 0.0) {
    sah /= weight;
    wide_sah /= weight;
  }
  std::printf("SAH cost (C_trav = C_isect = 1, triangle-weighted mean over BLAS):\n");
  std::printf("  binned SAH binary %.2f, wide %.2f | median split binary %.2f (median/SAH %.2f)\n",
              sah, wide_sah, median_sah, sah > 0.0 ? median_sah / sah : 0.0);
  json.set("sah_cost", JsonValue::object()
                           .set("binary", sah)
                           .set("wide", wide_sah)
                           .set("median_split_binary", median_sah)
                           .set("median_over_sah", sah > 0.0 ? median_sah / sah : 0.0));
  JsonValue traversal = JsonValue::array();

  // --- Traversal of the same rays.
  const std::array<std::vector<Ray>, 3> by_kind = rays_by_kind(rays);
  KernelData binary = ks.view(), wide = ks.view();
  binary.bvh.layout = kBvhLayoutBinary;
  wide.bvh.layout = kBvhLayoutWide;
  const BvhTracer ours_binary{&binary}, ours_wide{&wide};
  // Embree through the backend's own tracer (its alpha filter needs the
  // extended context), the exact query the CPU backend renders with.
  const EmbreeTracer emb = embree.embree_tracer();
  const char* kinds[3] = {"primary", "diffuse", "shadow"};
  double embree_mrays[3] = {0.0, 0.0, 0.0};  // of the last (widest) thread count
  for (const int t : {1, threads}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(t));
    std::printf(
        "traversal, %d thread%s (Mrays/s; ratio ours/embree; the host backend traces %s):\n", t,
        t == 1 ? "" : "s", ks.bvh.layout == kBvhLayoutWide ? "wide" : "binary");
    JsonValue kinds_json = JsonValue::array();
    for (int k = 0; k < 3; ++k) {
      const bool shadow = k == 2;
      const auto [e, b, w] =
          trace_kind_interleaved(emb, ours_binary, ours_wide, by_kind[k], shadow);
      embree_mrays[k] = e.mrays;
      std::printf(
          "  %-7s %7zu rays: embree %7.2f | binary %7.2f (%.2f) | wide %7.2f (%.2f)"
          "   hits %llu/%llu/%llu\n",
          kinds[k], by_kind[k].size(), e.mrays, b.mrays, b.mrays / e.mrays, w.mrays,
          w.mrays / e.mrays, static_cast<unsigned long long>(e.hits),
          static_cast<unsigned long long>(b.hits), static_cast<unsigned long long>(w.hits));
      kinds_json.push(JsonValue::object()
                          .set("kind", kinds[k])
                          .set("rays", uint64_t(by_kind[k].size()))
                          .set("embree_mrays_per_second", e.mrays)
                          .set("binary_mrays_per_second", b.mrays)
                          .set("wide_mrays_per_second", w.mrays)
                          .set("binary_vs_embree", b.mrays / e.mrays)
                          .set("wide_vs_embree", w.mrays / e.mrays)
                          .set("embree_hits", e.hits)
                          .set("binary_hits", b.hits)
                          .set("wide_hits", w.hits));
    }
    traversal.push(JsonValue::object().set("threads", t).set("kinds", std::move(kinds_json)));
    if (threads == 1) break;
  }
  json.set("traversal", std::move(traversal));
  json.set("host_backend_layout", ks.bvh.layout == kBvhLayoutWide ? "wide" : "binary");

  // --- Traversal work per ray (Embree's throughput beside it for reference;
  // Embree does not expose its own counts).
  std::printf(
      "traversal work per ray (nodes visited (TLAS part) / box tests / triangle tests / BLAS "
      "entered), "
      "beside embree's Mrays/s on %d threads:\n",
      threads);
  JsonValue work = JsonValue::array();
  for (int k = 0; k < 3; ++k) {
    const bool shadow = k == 2;
    const PerRayCounts b = count_kind(binary, by_kind[k], shadow);
    const PerRayCounts w = count_kind(wide, by_kind[k], shadow);
    std::printf(
        "  %-7s embree %6.2f | binary %6.1f (%5.1f) / %6.1f / %6.1f / %4.1f | wide %6.1f (%5.1f) / "
        "%6.1f / %6.1f / %4.1f\n",
        kinds[k], embree_mrays[k], b.nodes, b.nodes - b.blas_nodes, b.boxes, b.triangles,
        b.instances, w.nodes, w.nodes - w.blas_nodes, w.boxes, w.triangles, w.instances);
    work.push(JsonValue::object()
                  .set("kind", kinds[k])
                  .set("rays", uint64_t(by_kind[k].size()))
                  .set("embree_mrays_per_second", embree_mrays[k])
                  .set("binary", counts_json(b))
                  .set("wide", counts_json(w)));
  }
  json.set("traversal_work", std::move(work));
  return json;
}

}  // namespace tandem
