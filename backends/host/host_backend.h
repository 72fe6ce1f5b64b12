// Host backend: the kernel integrator traced through Tandem's own BVH
// (BvhTracer, core/kernel/bvh_traverse.h) with TBB on the CPU.
//
// It runs exactly the code the CUDA backend runs on the device, so it is the
// reference that backend is tested against, and it lets the BVH be checked
// against Embree image by image. It does not build the BVH itself: the
// caller runs AccelStructure::update_and_mark() before sync() (needs_bvh()).
#pragma once

#include "core/render/backend.h"

namespace tandem {

class HostBackend final : public Backend {
 public:
  std::string name() const override { return "host"; }
  BackendTraits traits() const override { return {.needs_bvh = true, .uses_host_cores = true}; }
  // Throws std::logic_error (a caller's bug, not bad input) when the scene's BVH arrays are missing
  // or do not cover its instances (AccelStructure has not run on it).
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;

  const KernelData& kernel_data() const { return kd_; }

 private:
  KernelData kd_{};
};

}  // namespace tandem
