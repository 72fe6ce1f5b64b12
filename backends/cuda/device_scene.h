// The CUDA backend's copy of the scene: one device buffer per entry of
// TANDEM_KERNEL_ARRAYS in each of two buffer sets, and a device-side
// KernelData per set that the kernels read. See commit_plan.h for why two
// sets and how changes reach both.
//
// Per frame only the changed element ranges are packed into a pinned staging
// buffer and sent with cudaMemcpyAsync on the scene's own copy stream.
// Events order everything without blocking the host or the GPU:
//   - a set's copies wait (on the copy stream) for `rendered`, recorded
//     after the last kernel that read the set, so frame N-1 finishes with a
//     set before frame N+1 overwrites it;
//   - rendering waits (on the render stream) for `uploaded`;
//   - the host waits for a set's previous `uploaded` only before reusing the
//     set's staging buffer, which by then is normally long complete.
// Textures stay plain device arrays of RGBA8 texels filtered in code (as
// on the CPU), not CUDA texture objects: texture units would filter with
// 8-bit fixed-point weights and break CPU/GPU agreement.
#pragma once

#include <cuda_runtime_api.h>

#include <array>
#include <cstddef>

#include "backends/cuda/commit_plan.h"

namespace tandem {

class DeviceScene {
 public:
  DeviceScene();
  ~DeviceScene();
  DeviceScene(const DeviceScene&) = delete;
  DeviceScene& operator=(const DeviceScene&) = delete;

  // Uploads `delta` (and what the target set missed from earlier frames)
  // into the set the previous commit did not use, asynchronously. `ks` is
  // only read during the call. Returns the bytes sent.
  size_t commit(const KernelScene& ks, const SceneDelta& delta);
  size_t last_commit_bytes() const { return last_commit_bytes_; }

  // Makes `stream` wait for the current set's upload and returns its
  // device-side KernelData; call end_render() after the last kernel that
  // reads it has been enqueued on `stream`.
  const KernelData* begin_render(cudaStream_t stream);
  void end_render(cudaStream_t stream);

  // The current set's KernelData as the host sees it (device pointers).
  const KernelData& host_view() const { return sets_[commits_.current_set()].view; }
  bool ready() const { return commits_.has_committed(); }
  size_t device_bytes() const;
  // Blocks until every upload has landed (tests, teardown).
  void synchronize();

 private:
  struct BufferSet {
    std::array<void*, kKernelArrayCount> buffers{};
    KernelData view{};             // host copy of what d_view holds
    KernelData* d_view = nullptr;  // device copy read by the kernels
    void* staging = nullptr;       // pinned
    size_t staging_capacity = 0;
    cudaEvent_t uploaded = nullptr, rendered = nullptr;
  };
  void reserve_staging(BufferSet& set, size_t bytes);

  DoubleBufferedCommits commits_;
  std::array<BufferSet, DoubleBufferedCommits::kSets> sets_{};
  cudaStream_t copy_stream_ = nullptr;
  size_t last_commit_bytes_ = 0;
};

}  // namespace tandem
