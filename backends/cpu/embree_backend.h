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

#include "core/render/backend.h"

namespace tandem {

class EmbreeBackend final : public Backend {
 public:
  EmbreeBackend();
  ~EmbreeBackend() override;
  EmbreeBackend(const EmbreeBackend&) = delete;
  EmbreeBackend& operator=(const EmbreeBackend&) = delete;

  std::string name() const override { return "cpu"; }
  BackendTraits traits() const override { return {.uses_host_cores = true}; }
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;

  // Single-ray queries, for tests and benchmarks (thread-safe after sync).
  Hit intersect(const Ray& ray, uint32_t alpha_key = 0) const;
  bool occluded(const Ray& ray, uint32_t alpha_key = 0) const;
  RTCScene top_level() const { return top_; }
  const KernelData& kernel_data() const { return kd_; }

 private:
  void release_scenes();
  void build_all(const KernelScene& scene);

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

}  // namespace tandem
