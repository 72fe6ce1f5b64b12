#include "backends/host/host_backend.h"

#include <chrono>
#include <vector>

#include "core/kernel/bvh_traverse.h"
#include "core/render/cpu_features.h"
#include "core/render/cpu_tile_loop.h"
#include "core/render/cpu_wavefront.h"

namespace tandem {

HostBackend::HostBackend(CudaKernelVariant kernel) : kernel_(kernel) {}
HostBackend::~HostBackend() = default;

void HostBackend::sync(const KernelScene& scene, const SceneDelta& /*delta*/) {
  // Nothing to copy: the BVH lives in the KernelScene's own arrays, which
  // AccelStructure has already brought up to date for this delta.
  check_bvh_present(scene, "host backend");
  kd_ = scene.view();
}

bool HostBackend::render_features(const FeaturePass& pass, PixelFeatures* out) {
  render_features_on_cpu(kd_, BvhTracer{&kd_}, pass, out);
  return true;
}

BackendStats HostBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  if (kernel_ == CudaKernelVariant::kWavefront) return render_wavefront(pass, tiles, film);
  return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
}

BackendStats HostBackend::render_wavefront(const RenderPass& pass, TileSource& tiles, Film& film) {
  if (!wavefront_) wavefront_ = std::make_unique<CpuWavefrontStorage>();
  return render_tiles_wavefront_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film, *wavefront_);
}

}  // namespace tandem
