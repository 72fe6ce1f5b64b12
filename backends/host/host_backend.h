// Host backend: the kernel integrator traced through Tandem's own BVH
// (BvhTracer, core/kernel/bvh_traverse.h) with TBB on the CPU.
//
// It runs exactly the code the CUDA backend runs on the device, so it is the
// reference that backend is tested against, and it lets the BVH be checked
// against Embree image by image. Like the CUDA backend it has two kernels:
// the megakernel (one path per sample, tile by tile) and the wavefront
// pipeline (core/kernel/wavefront.h over batches of tiles, run by
// core/render/cpu_wavefront.h), which gives the same bits. It does not build
// the BVH itself: the caller runs AccelStructure::update() before
// sync() (traits().needs_bvh).
#pragma once

#include <memory>

#include "backends/kernel_variant.h"
#include "core/render/backend.h"

namespace tandem {

class CpuWavefrontStorage;

class HostBackend final : public Backend {
 public:
  explicit HostBackend(CudaKernelVariant kernel = CudaKernelVariant::kMegakernel);
  ~HostBackend() override;
  std::string name() const override { return "host"; }
  BackendTraits traits() const override { return {.needs_bvh = true, .uses_host_cores = true}; }
  // Throws std::logic_error (a caller's bug, not bad input) when the scene's BVH arrays are missing
  // or do not cover its instances (AccelStructure has not run on it).
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;
  bool render_features(const FeaturePass& pass, PixelFeatures* out) override;

  const KernelData& kernel_data() const { return kd_; }
  CudaKernelVariant kernel() const { return kernel_; }

 private:
  BackendStats render_wavefront(const RenderPass& pass, TileSource& tiles, Film& film);

  CudaKernelVariant kernel_;
  KernelData kd_{};
  std::unique_ptr<CpuWavefrontStorage> wavefront_;
};

}  // namespace tandem
