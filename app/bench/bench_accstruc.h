// `tandem bench --accstruc`: Tandem's own BVH (accstruc/) measured
// against Embree on the same meshes and the same rays in the same run; and
// the ray mix both benchmarks trace.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "app/json_writer.h"
#include "core/world/kernel_scene.h"
#include "sync/scene_sync.h"

namespace tandem {

class CpuBackend;

enum class BenchRayKind : uint8_t { kPrimary, kDiffuse, kShadow };

// The ray mix of a path's first bounce: one camera ray per pixel, a
// cosine-distributed ray from each camera hit, and a shadow ray from each hit
// to a point sampled on the lights (the integrator's own sampling code).
struct BenchRays {
  std::vector<Ray> rays;
  std::vector<BenchRayKind> kind;
  std::vector<uint32_t> alpha_key;  // one per ray, or empty: every key 0
};
BenchRays make_bench_rays(const KernelData& kd, const CpuBackend& embree, uint32_t width,
                          uint32_t height);

// The rays the path tracer itself casts, in the order it casts them and
// with the alpha key it gives each: for one sample per pixel, the camera ray
// (kPrimary), then at each bounce the light sample's shadow ray (kShadow)
// and the scattered ray (kDiffuse, whatever the lobe). This is the peer's
// ray mix that `make_bench_rays` only approximates: deeper bounces, and as
// many bounce and shadow rays per camera ray as the paths really have.
// Traced through the CPU backend's Embree tracer on one thread, pixel by
// pixel in raster order; images of more than kMaxRecordedPaths pixels are
// recorded on every k-th row only, to bound the memory.
constexpr uint64_t kMaxRecordedPaths = 512 * 512;
BenchRays record_path_rays(const KernelData& kd, const CpuBackend& embree);

// The rays of `set` grouped by kind, indexed by BenchRayKind.
std::array<std::vector<Ray>, 3> rays_by_kind(const BenchRays& set);

// Mrays/s of the CPU backend's Embree tracer over `rays` on all threads
// (closest hits; any hits with `shadow`), best of a few runs.
double embree_kind_mrays(const CpuBackend& embree, const std::vector<Ray>& rays, bool shadow);

// Prints BLAS build throughput (ours vs Embree's builder), the SAH cost of
// our BLAS (vs a median-split build), and closest-hit / any-hit throughput
// of our two layouts vs Embree for primary, diffuse and shadow rays, on one
// thread and on `threads` threads. `scene_sync` holds the scene with its
// BVH; `embree` must be synced to it. Returns the printed figures for the
// JSON report.
JsonValue run_accstruc_bench(const SceneSync& scene_sync, const CpuBackend& embree,
                             const BenchRays& rays, int threads);

}  // namespace tandem
