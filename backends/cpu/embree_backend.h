// CPU backend: Embree 3 for ray queries, TBB for parallelism, and the shared
// kernel integrator for everything else.
//
// One Embree BLAS (RTCScene) per mesh, one instance geometry per scene
// instance in a top-level scene whose geometry IDs equal instance indices.
// Vertex and index buffers are shared with KernelScene (no copies), and alpha
// testing runs the kernel's alpha_test_opaque from an intersection filter.
#pragma once

#include <embree3/rtcore.h>

#include <memory>
#include <vector>

#include "backends/kernel_variant.h"
#include "core/render/backend.h"

namespace tandem {

class CpuWavefrontStorage;

class EmbreeBackend final : public Backend {
 public:
  // kWavefront: the wavefront pipeline with Embree's 16-ray packets instead
  // of the per-pixel loop with single rays.
  explicit EmbreeBackend(CudaKernelVariant kernel = CudaKernelVariant::kMegakernel);
  ~EmbreeBackend() override;
  EmbreeBackend(const EmbreeBackend&) = delete;
  EmbreeBackend& operator=(const EmbreeBackend&) = delete;

  std::string name() const override { return "cpu"; }
  BackendTraits traits() const override { return {.uses_host_cores = true}; }
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;
  bool render_features(const FeaturePass& pass, PixelFeatures* out) override;

  // Single-ray queries, for tests and benchmarks (thread-safe after sync).
  Hit intersect(const Ray& ray, uint32_t alpha_key = 0) const;
  bool occluded(const Ray& ray, uint32_t alpha_key = 0) const;
  RTCScene top_level() const { return top_; }
  const KernelData& kernel_data() const { return kd_; }

 private:
  void release_scenes();
  void build_all(const KernelScene& scene);

  CudaKernelVariant kernel_;
  std::unique_ptr<CpuWavefrontStorage> wavefront_;
  RTCDevice device_ = nullptr;
  RTCScene top_ = nullptr;
  std::vector<RTCScene> blas_;
  KernelData kd_{};
};

// A triangle geometry over mesh `mesh` of `ks`, sharing its vertex and index
// arrays (no copies), with the given build quality; not yet committed, so
// callers can add filters first. Used by the backend and by the builder
// benchmark, which must build exactly the same geometry.
RTCGeometry new_mesh_geometry(RTCDevice device, const KernelScene& ks, uint32_t mesh,
                              RTCBuildQuality quality);

// The kernel Tracer for Embree, usable from any thread.
struct EmbreeTracer {
  RTCScene scene;
  const KernelData* kd;
  Hit intersect(const Ray& ray, uint32_t alpha_key) const;
  bool occluded(const Ray& ray, uint32_t alpha_key) const;
};

// The same with packets of up to 16 rays (rtcIntersect16 / rtcOccluded16),
// for the wavefront pipeline on the CPU (core/render/cpu_wavefront.h). Each
// ray carries its own alpha key (in the ray id, which the filter reads).
struct EmbreePacketTracer : EmbreeTracer {
  void intersect_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n, Hit* hits) const;
  void occluded_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                       bool* occluded) const;
};

}  // namespace tandem
