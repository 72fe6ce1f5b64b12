// CUDA backend: the shared kernels (core/kernel/integrator.h over Tandem's
// own BVH, BvhTracer) on an NVIDIA GPU.
//
// The scene lives on the device double-buffered (device_scene.h): sync()
// commits only the changed element ranges into the buffer set the previous
// frame is not using. render() pulls tiles from the TileSource in batches,
// traces every pixel sample of a batch on the GPU (megakernel or wavefront,
// CudaKernelVariant), sums each pixel's samples on the device in the same
// order and precision as the CPU tile loop, and adds the sums to the host
// Film, overlapping the host side of one batch with the GPU work of the next.
// For GPU-only output, render_to_device_film() keeps the sums in a device
// film that is resolved or tone mapped to 8 bits on the GPU.
//
// Like the host backend it traces the KernelScene's BVH arrays, which the
// caller fills with AccelStructure before sync() (needs_bvh()).
//
// This header includes no CUDA headers, so plain C++ code can use it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/kernel_variant.h"
#include "core/image/image.h"
#include "core/render/backend.h"

namespace tandem {

// CudaKernelVariant and parse_cuda_kernel_variant: backends/kernel_variant.h.

// Whether a CUDA device this build can run on exists; otherwise `reason`
// says why (no driver, driver too old, no device, no kernel image for the
// device's architecture, ...).
bool cuda_query_device(std::string* reason);

class CudaBackend final : public Backend {
 public:
  // Uses device 0. Throws InputError with cuda_query_device's reason when
  // no usable device exists, CudaError when initialisation fails.
  explicit CudaBackend(CudaKernelVariant variant = CudaKernelVariant::kMegakernel);
  ~CudaBackend() override;
  CudaBackend(const CudaBackend&) = delete;
  CudaBackend& operator=(const CudaBackend&) = delete;

  std::string name() const override { return "cuda"; }
  bool needs_bvh() const override { return true; }
  // sync() stages every changed range into pinned memory before returning,
  // and render() reads only device buffers.
  bool reads_host_scene_while_rendering() const override { return false; }
  // Throws std::logic_error when the scene's BVH arrays are missing.
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;

  void set_variant(CudaKernelVariant variant);
  CudaKernelVariant variant() const;
  std::string device_name() const;
  // Bytes the most recent sync() sent to the device.
  uint64_t last_commit_bytes() const;
  // Device memory held by the scene's two buffer sets.
  uint64_t scene_device_bytes() const;

  // GPU-only output: a device film of width x height (cleared).
  void reset_device_film(uint32_t width, uint32_t height);
  BackendStats render_to_device_film(const RenderPass& pass, TileSource& tiles);
  ImageRGB resolve_device_film();
  // Exposure in stops, curve and sRGB as tone_map_to_srgb8, on the GPU.
  std::vector<uint8_t> tone_map_device_film(float exposure_stops, ToneMap curve);

  // Closest hits (any_hit = false) or occlusion (a valid hit = occluded) of
  // `rays` against the synced scene, for tests and benchmarks.
  std::vector<Hit> trace_rays(const std::vector<Ray>& rays, const std::vector<uint32_t>& alpha_keys,
                              bool any_hit);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tandem
