#include "backends/cpu/cpu_backend.h"

#include <stdexcept>

#include "backends/cpu/embree_tracer.h"
#include "backends/cpu_loops/cpu_features.h"
#include "backends/cpu_loops/cpu_tile_loop.h"
#include "backends/cpu_loops/cpu_wavefront.h"
#include "core/kernel/bvh_traverse.h"

namespace tandem {

CpuBackend::CpuBackend(CpuTraversal traversal, CudaKernelVariant kernel)
    : traversal_(traversal), kernel_(kernel) {
  if (traversal_ == CpuTraversal::kEmbree) embree_ = std::make_unique<EmbreeScene>();
}

CpuBackend::~CpuBackend() = default;

std::string CpuBackend::name() const {
  return traversal_ == CpuTraversal::kEmbree ? "cpu" : "host";
}

BackendTraits CpuBackend::traits() const {
  // The host's wide loop (bvh_wide_host.h) beats its binary one on every
  // measured scene (docs/performance/log/host_traversal.md).
  return {.needs_bvh = traversal_ == CpuTraversal::kTandemBvh,
          .bvh_layout = kBvhLayoutWide,
          .uses_host_cores = true};
}

void CpuBackend::sync(const KernelScene& scene, const SceneDelta& delta) {
  if (embree_) {
    embree_->sync(scene, delta);
  } else {
    // Nothing to copy: the BVH lives in the KernelScene's own arrays, which
    // AccelStructure has already brought up to date for this delta.
    check_bvh_present(scene, "host backend");
  }
  kd_ = scene.view();
}

EmbreeTracer CpuBackend::embree_tracer() const {
  if (!embree_)
    throw std::logic_error("embree_tracer(): the CPU backend does not trace with Embree");
  return EmbreeTracer{embree_->top_level(), &kd_};
}

bool CpuBackend::render_features(const FeaturePass& pass, PixelFeatures* out,
                                 const PassStop& stop) {
  if (embree_) {
    render_features_on_cpu(kd_, embree_tracer(), pass, out, stop);
  } else {
    render_features_on_cpu(kd_, BvhTracer{&kd_}, pass, out, stop);
  }
  return true;
}

BackendStats CpuBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  if (kernel_ == CudaKernelVariant::kWavefront) {
    if (!wavefront_) wavefront_ = std::make_unique<CpuWavefrontStorage>();
    // Embree answers the pipeline's extend and connect queues in packets.
    if (embree_) {
      return render_tiles_wavefront_on_cpu(kd_, EmbreePacketTracer{embree_tracer()}, pass, tiles,
                                           film, *wavefront_);
    }
    return render_tiles_wavefront_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film, *wavefront_);
  }
  // The camera rays of a tile in Embree packets (render_tiles_on_cpu).
  if (embree_) {
    return render_tiles_on_cpu(kd_, EmbreePacketTracer{embree_tracer()}, pass, tiles, film);
  }
  return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
}

Hit CpuBackend::intersect(const Ray& ray, uint32_t alpha_key) const {
  if (embree_) return embree_tracer().intersect(ray, alpha_key);
  return BvhTracer{&kd_}.intersect(ray, alpha_key);
}

bool CpuBackend::occluded(const Ray& ray, uint32_t alpha_key) const {
  if (embree_) return embree_tracer().occluded(ray, alpha_key);
  return BvhTracer{&kd_}.occluded(ray, alpha_key);
}

}  // namespace tandem
