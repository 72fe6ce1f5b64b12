// The CPU backend: the shared kernel integrator on the host's cores with
// TBB, traced through Embree 3 or through Tandem's own BVH.
//
// Both traversals run the same tile loop, wavefront driver and feature pass
// (backends/cpu_loops/); they differ only in the kernel Tracer those are
// instantiated with, and in what sync() must do to bring it up to date:
//   kEmbree     commits an Embree scene (EmbreeScene, embree_tracer.h) built
//               from the KernelScene's meshes and instances.
//   kTandemBvh  traverses the KernelScene's own BVH arrays with BvhTracer
//               (core/kernel/bvh_traverse.h), exactly the code the CUDA
//               backend runs on the device. It is the reference that backend
//               is tested against, and lets the BVH be checked against Embree
//               image by image. It does not build the BVH itself: the caller
//               updates the scene through a SceneSync with a BVH before sync()
//               (traits().needs_bvh).
// Like the CUDA backend it has two kernels: the megakernel (one path per
// sample, tile by tile) and the wavefront pipeline (core/kernel/wavefront.h
// over batches of tiles), which gives the megakernel's bits over our BVH;
// with Embree it traces the pipeline's queues in 16-ray packets.
//
// The command line names the traversals `cpu` (Embree) and `host` (our BVH),
// which name() returns.
#pragma once

#include <memory>

#include "backends/kernel_variant.h"
#include "core/render/backend.h"

namespace tandem {

class CpuWavefrontStorage;
class EmbreeScene;
struct EmbreeTracer;

enum class CpuTraversal {
  kEmbree,     // Embree 3's BVH, built by Embree from the scene's meshes
  kTandemBvh,  // Tandem's BVH (accstruc), as the CUDA backend traces it
};

class CpuBackend final : public Backend {
 public:
  // Throws std::runtime_error when kEmbree and Embree cannot create a device.
  explicit CpuBackend(CpuTraversal traversal,
                      CudaKernelVariant kernel = CudaKernelVariant::kMegakernel);
  ~CpuBackend() override;
  CpuBackend(const CpuBackend&) = delete;
  CpuBackend& operator=(const CpuBackend&) = delete;

  // "cpu" for kEmbree, "host" for kTandemBvh (the --backend names).
  std::string name() const override;
  BackendTraits traits() const override;
  // With kTandemBvh, throws std::logic_error (a caller's bug, not bad input)
  // when the scene's BVH arrays are missing or do not cover its instances
  // (AccelStructure has not run on it).
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;
  bool render_features(const FeaturePass& pass, PixelFeatures* out, const PassStop& stop) override;

  // Single-ray queries through the backend's traversal, for tests and
  // benchmarks (thread-safe after sync).
  Hit intersect(const Ray& ray, uint32_t alpha_key = 0) const;
  bool occluded(const Ray& ray, uint32_t alpha_key = 0) const;
  // The Embree tracer the backend renders with (include
  // backends/cpu/embree_tracer.h to use it); throws std::logic_error unless
  // the traversal is kEmbree.
  EmbreeTracer embree_tracer() const;

  const KernelData& kernel_data() const { return kd_; }
  CpuTraversal traversal() const { return traversal_; }
  CudaKernelVariant kernel() const { return kernel_; }

 private:
  CpuTraversal traversal_;
  CudaKernelVariant kernel_;
  std::unique_ptr<EmbreeScene> embree_;  // kEmbree only
  std::unique_ptr<CpuWavefrontStorage> wavefront_;
  KernelData kd_{};
};

}  // namespace tandem
