// A simulated GPU for CI: the CUDA backend's device operations executed on
// the CPU, with what makes a GPU hard to get right kept in.
//
//   - Every stream is a worker thread that runs its operations in order,
//     each after a delay (a base time, random jitter, and for copies a time
//     per byte), so copies and kernels really run late and concurrently.
//   - Events, waits and host synchronisation follow CUDA's rules (a wait
//     applies to the event's most recent record at the time of the call).
//   - Every device-memory access is recorded with a vector clock of the
//     stream that made it; two accesses of the same bytes, one a write, with
//     no chain of stream order / events / host synchronisation between them
//     are a hazard, found whether or not the timing of a run exposed it.
//     Accesses outside a live allocation are hazards too.
//   - Kernels run the same per-item code the .cu kernels run (batch.h, the
//     shared integrator over Tandem's BVH), reading the scene from the
//     simulated device memory: an image rendered on it is bit for bit the
//     host backend's when the backend's uploads are right.
//   - Fresh memory is filled with a pattern, not zeroes, as on a GPU.
// The wavefront variant runs the GPU's queue logic (core/kernel/wavefront.h)
// over the arrays the backend allocated on the device, with the CPU driver
// of backends/cpu_loops/cpu_wavefront.h.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/cuda/device_ops.h"

namespace tandem {

struct SimDeviceOptions {
  double op_seconds = 20e-6;           // every stream operation takes at least this
  double copy_seconds_per_mib = 2e-4;  // and a copy this much per MiB (about 5 GB/s)
  double kernel_seconds = 100e-6;      // and a kernel this much besides its computing
  uint64_t seed = 1;                   // jitter: up to op_seconds more per operation
};

struct SimDeviceReport {
  std::vector<std::string> hazards;    // unordered conflicting accesses, bad addresses
  uint64_t pageable_async_copies = 0;  // async copies from or to unpinned host memory
  size_t live_device_allocations = 0, live_pinned_allocations = 0;
  size_t live_streams = 0, live_events = 0;
  uint64_t bytes_to_device = 0, bytes_to_host = 0;
  uint64_t kernels = 0;
  uint64_t host_waits = 0;  // synchronize() calls that had to block
};

class SimDevice final : public DeviceOps {
 public:
  explicit SimDevice(SimDeviceOptions options = {});
  ~SimDevice() override;
  SimDevice(const SimDevice&) = delete;
  SimDevice& operator=(const SimDevice&) = delete;

  SimDeviceReport report() const;

  std::string name() const override { return "simulated GPU"; }
  void* alloc(size_t bytes) override;
  void free(void* p) override;
  void* alloc_async(size_t bytes, DeviceStream stream) override;
  void free_async(void* p, DeviceStream stream) override;
  void* alloc_pinned(size_t bytes) override;
  void free_pinned(void* p) override;
  DeviceStream create_stream() override;
  void destroy_stream(DeviceStream stream) override;
  DeviceEvent create_event(bool timing) override;
  void destroy_event(DeviceEvent event) override;
  void record(DeviceEvent event, DeviceStream stream) override;
  void wait(DeviceStream stream, DeviceEvent event) override;
  void synchronize(DeviceEvent event) override;
  void synchronize(DeviceStream stream) override;
  double elapsed_seconds(DeviceEvent from, DeviceEvent to) override;
  void copy_to_device(void* dst, const void* src, size_t bytes, DeviceStream stream) override;
  void copy_to_host(void* dst, const void* src, size_t bytes, DeviceStream stream) override;
  void zero(void* dst, size_t bytes, DeviceStream stream) override;
  void trace_samples(const KernelData* kd, const TileBatch& batch, CudaKernelVariant variant,
                     const WavefrontArrays& wave, Vec3* radiance, unsigned long long* ray_count,
                     DeviceStream stream) override;
  // Small, so that tests see slots regenerated many times per batch.
  uint32_t wavefront_slots() const override { return 512; }
  void reduce_samples(const TileBatch& batch, const Vec3* radiance, double* pixel_sums,
                      DeviceStream stream) override;
  void accumulate_film(const TileBatch& batch, const double* pixel_sums, uint32_t sample_count,
                       const DeviceFilmView& film, DeviceStream stream) override;
  void resolve_film(const DeviceFilmView& film, float* rgb, DeviceStream stream) override;
  void tone_map_film(const DeviceFilmView& film, float exposure_scale, uint32_t curve,
                     uint8_t* rgb8, DeviceStream stream) override;
  void trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                  bool any_hit, Hit* hits, uint32_t* work_counter, DeviceStream stream) override;
  void render_features(const KernelData* kd, const FeaturePass& pass, uint32_t width,
                       uint32_t height, PixelFeatures* out, DeviceStream stream) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tandem
