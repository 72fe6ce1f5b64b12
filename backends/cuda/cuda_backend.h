// CUDA backend: the shared kernels (core/kernel/integrator.h over Tandem's
// own BVH, BvhTracer) on an NVIDIA GPU, through the device operations of
// device_ops.h, so that the same backend runs in CI on the simulated device.
//
// The scene lives on the device double-buffered (device_scene.h): sync()
// commits only the changed element ranges, into the set no render reads, so
// the core tracer may call it for frame N+1 while render() of frame N runs
// (traits().syncs_while_rendering). render() pulls tiles from the TileSource
// in batches, traces every pixel sample of a batch on the device (megakernel
// or wavefront, CudaKernelVariant), sums each pixel's samples on the device
// in the same order and precision as the CPU tile loop, and adds the sums to
// the host Film, overlapping the host side of one batch with the device work
// of the next. For GPU-only output, render_to_device_film() keeps the sums in
// a device film that is resolved or tone mapped to 8 bits on the device.
//
// Like the host backend it traces the KernelScene's BVH arrays, which the
// caller fills with AccelStructure before sync() (traits().needs_bvh).
//
// This header includes no CUDA headers, so plain C++ code can use it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/cuda/device_ops.h"
#include "backends/kernel_variant.h"
#include "core/image/image.h"
#include "core/render/backend.h"

namespace tandem {

// Whether the CUDA backend has a device (a GPU, or the simulated one under
// TANDEM_DEVICE=sim); otherwise `reason` says why (no driver, driver too
// old, no device, no kernel image for the device's architecture, ...).
bool cuda_backend_device_available(std::string* reason);

class CudaBackend final : public Backend {
 public:
  // How much work one batch and one kernel launch take: a batch holds at
  // most max_batch_pixels pixels (a 512x512 frame), a launch at most
  // max_items pixel samples (48 MiB of radiance); more samples run as
  // several chunks summed in order. Tests shrink them to cover the paths.
  struct LaunchLimits {
    uint32_t max_batch_pixels = 1u << 18;
    uint64_t max_items = 1u << 22;
  };

  // On the device open_device() chooses. Throws InputError with the reason
  // when there is none, DeviceError when it fails to start.
  explicit CudaBackend(CudaKernelVariant variant = CudaKernelVariant::kMegakernel);
  CudaBackend(std::shared_ptr<DeviceOps> device, CudaKernelVariant variant, LaunchLimits limits);
  ~CudaBackend() override;
  CudaBackend(const CudaBackend&) = delete;
  CudaBackend& operator=(const CudaBackend&) = delete;

  std::string name() const override { return "cuda"; }
  BackendTraits traits() const override {
    return {.needs_bvh = true,
            .uses_host_cores = false,
            .reads_host_scene_while_rendering = false,
            .syncs_while_rendering = true};
  }
  // Throws std::logic_error when the scene's BVH arrays are missing.
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  // One generation of `log` per device buffer set (each gets what it
  // missed since it was last written).
  void sync_from(const KernelScene& scene, const KernelChangeLog& log) override;
  void forget_synced() override;
  // Throws DeviceRenderError when the device fails.
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;
  // The feature pass on the device (the Features kernel of svgf_kernels.cu),
  // for the camera of the newest sync(), which `out` is sized for. Always
  // true. Throws std::logic_error before sync() and when a sync() with
  // another film size runs on another thread during the call (nothing is
  // written then), DeviceError when the device fails.
  bool render_features(const FeaturePass& pass, PixelFeatures* out, const PassStop& stop) override;

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
  // Exposure in stops, curve and sRGB as tone_map_to_srgb8, on the device.
  std::vector<uint8_t> tone_map_device_film(float exposure_stops, ToneMap curve);

  // A host film render()ed into is also accumulated on the device (one
  // small kernel per batch), so that an application presenting through
  // its own graphics interop reads the image where it is. The mirror
  // restarts with the host film's accumulation (sample_begin 0).
  void set_device_image(bool on);
  // The mirrored image resolved to linear RGB floats (3 per pixel) or tone
  // mapped to sRGB bytes (3 per pixel, rows top first) in one device buffer
  // of this backend, valid until the next such call or render(); the
  // stream is synchronised. Throws std::logic_error without a mirror.
  const void* device_image_linear();
  const void* device_image_srgb8(float exposure_stops, ToneMap curve);

  // Closest hits (any_hit = false) or occlusion (a valid hit = occluded) of
  // `rays` against the synced scene, for tests and benchmarks.
  std::vector<Hit> trace_rays(const std::vector<Ray>& rays, const std::vector<uint32_t>& alpha_keys,
                              bool any_hit);

  // Every kernel array of buffer set `set` as it is on the device, and the
  // set the next render reads (tests).
  std::vector<std::vector<uint8_t>> read_back_scene(uint32_t set);
  uint32_t newest_scene_set() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tandem
