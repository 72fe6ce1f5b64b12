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
//   - Kernels are the .cu files' own bodies, compiled a second time with
//     the GPU's branches of the kernel code (emulated_*.cpp) and run on an
//     emulated grid of thread blocks (emulated_grid.h: every thread a fiber,
//     barriers and warp operations checked for divergence, shared-memory
//     races, __ldg and atomics checked against device memory). They read
//     the scene from the simulated device memory with the GPU's BVH loops:
//     an image rendered on it is bit for bit the host backend's when the
//     backend's uploads are right. A kernel fault is reported as a hazard.
//   - Fresh memory is filled with a pattern, not zeroes, as on a GPU.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/cuda/device_ops.h"

namespace tandem {

struct SimDeviceOptions {
  double op_seconds = 10e-6;           // every stream operation takes at least this
  double copy_seconds_per_mib = 2e-4;  // and a copy this much per MiB (about 5 GB/s)
  double kernel_seconds = 30e-6;       // and a kernel this much besides its computing
  uint64_t seed = 1;                   // jitter: up to op_seconds more per operation
};

struct SimDeviceReport {
  std::vector<std::string> hazards;    // unordered conflicting accesses, bad addresses
  uint64_t pageable_async_copies = 0;  // async copies from or to unpinned host memory
  size_t live_device_allocations = 0, live_pinned_allocations = 0;
  size_t live_streams = 0, live_events = 0;
  uint64_t bytes_to_device = 0, bytes_to_host = 0;
  uint64_t kernels = 0;
  uint64_t host_waits = 0;   // synchronize() calls that had to block
  uint64_t allocations = 0;  // alloc, alloc_async and alloc_pinned calls
  // free() and free_pinned() calls that waited for work queued on a stream
  // (cudaFree and cudaFreeHost wait for the whole device).
  uint64_t device_wide_waits = 0;
};

class SimDevice final : public DeviceOps {
 public:
  explicit SimDevice(SimDeviceOptions options = {});
  ~SimDevice() override;
  SimDevice(const SimDevice&) = delete;
  SimDevice& operator=(const SimDevice&) = delete;

  SimDeviceReport report() const;
  // Enqueues an operation that keeps `stream` busy for `seconds` (a long
  // kernel), for tests of what must not wait for one.
  void stall(DeviceStream stream, double seconds);

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
  DeviceProperties properties() const override;
  uint32_t resident_blocks(DeviceKernel kernel, uint32_t block_threads) override;
  void launch(DeviceKernel kernel, const LaunchDims& dims, const void* args, size_t args_bytes,
              DeviceStream stream) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tandem
