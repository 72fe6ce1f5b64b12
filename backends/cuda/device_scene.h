// The CUDA backend's copy of the scene: one device buffer per entry of
// TANDEM_KERNEL_ARRAYS in each of two buffer sets, and a device-side
// KernelData per set that the kernels read. See commit_plan.h for why two
// sets and how changes reach both.
//
// Which set a commit writes: the newest set while no render has claimed it
// since its last commit (a second commit for the same frame amends it),
// otherwise the other one. So while frame N renders from one set, frame N+1 is committed into
// the other, from another thread (sync() during render(): Brigade's
// SyncAccStruc overlapping the render).
//
// Per commit only the changed element ranges are packed into the set's
// pinned staging memory and sent with asynchronous copies on the scene's own
// copy stream. Events order everything without blocking the host or the
// GPU:
//   - a set's copies wait (on the copy stream) for `rendered`, recorded after
//     the last kernel of the previous render that read the set;
//   - a render waits (on its stream) for the set's `uploaded`;
//   - the host waits for a set's previous `uploaded` only before reusing the
//     set's staging buffer, which by then is normally long complete.
// A commit whose device calls fail part-way frees the set and marks it for a
// full upload, so the bookkeeping never describes buffers that are not there.
//
// Textures stay plain device arrays of RGBA8 texels filtered in code (as
// on the CPU), not CUDA texture objects: texture units would filter with
// 8-bit fixed-point weights and break CPU/GPU agreement.
#pragma once

#include <array>
#include <cstddef>
#include <mutex>
#include <vector>

#include "backends/cuda/commit_plan.h"
#include "backends/cuda/device_ops.h"

namespace tandem {

class DeviceScene {
 public:
  explicit DeviceScene(DeviceOps& ops);
  ~DeviceScene();
  DeviceScene(const DeviceScene&) = delete;
  DeviceScene& operator=(const DeviceScene&) = delete;

  // Uploads what `log` records beyond the generation the target set holds
  // (what it missed from earlier frames included), asynchronously. `ks` is
  // only read during the call. Returns the bytes sent. Thread-safe against
  // a render in flight on another thread.
  size_t commit(const KernelScene& ks, const KernelChangeLog& log);
  // The same with `delta` as the next generation of a log of this scene's
  // own, for callers that sync deltas rather than a log.
  size_t commit(const KernelScene& ks, const SceneDelta& delta);
  // Both sets' next commits send everything.
  void forget_generations();
  size_t last_commit_bytes() const;

  // A render's hold on the newest set: `stream` waits for the set's upload,
  // and `view` is its device-side KernelData. end_render() releases the
  // same set after the last kernel that reads it has been enqueued.
  struct RenderTicket {
    uint32_t set = 0;
    const KernelData* view = nullptr;
    // Of the set's scene, for the host's launch geometry: the camera's film
    // size and the most segments a path can have (max_depth + 1).
    uint32_t width = 0, height = 0, max_segments = 1;
  };
  RenderTicket begin_render(DeviceStream stream);
  void end_render(const RenderTicket& ticket, DeviceStream stream);

  // Device time of the commits the ticket's set received before it was
  // claimed, and how much of it ran before the render could have started
  // (hidden behind the previous frame's render). Call once per ticket after
  // the render's stream has been synchronised.
  struct CommitTiming {
    double copy_seconds = 0.0, hidden_seconds = 0.0;
  };
  CommitTiming take_timing(const RenderTicket& ticket);

  bool ready() const;
  size_t device_bytes() const;
  // Blocks until every upload has landed (tests, teardown).
  void synchronize();
  // Every array of `set` as it is on the device, one byte vector per
  // kernel array (tests compare them with the host arrays).
  std::vector<std::vector<uint8_t>> read_back(uint32_t set);
  uint32_t newest_set() const;

 private:
  // Pinned memory the host packs a commit into. It grows by adding chunks
  // and never frees one before the scene goes: freeing pinned memory waits
  // for the whole device (cudaFreeHost), which would stall the commit of
  // frame N + 1 until frame N's render ends.
  struct Staging {
    std::vector<DeviceBuffer> chunks;
    size_t capacity = 0;
    void reserve(DeviceOps& ops, size_t bytes);
  };
  struct BufferSet {
    std::array<void*, kKernelArrayCount> buffers{};
    KernelData view{};    // host copy of what d_view holds
    DeviceBuffer d_view;  // device copy read by the kernels
    Staging staging;
    DeviceEventOwner uploaded, rendered, copy_begin, ready;
    bool claimed = false;         // a render claimed the set since its last commit
    uint32_t readers = 0;         // renders between begin_render and end_render
    bool timing_pending = false;  // copy_begin recorded since the last claim
  };
  void upload(BufferSet& set, const CommitPlan& plan, const KernelScene& ks);
  void release_buffers(BufferSet& set) noexcept;

  DeviceOps& ops_;
  DeviceStreamOwner copy_stream_;
  size_t commit_locked(const KernelScene& ks, const KernelChangeLog& log);

  DoubleBufferedCommits commits_;
  KernelChangeLog own_log_;  // commit(ks, delta)'s
  std::array<BufferSet, DoubleBufferedCommits::kSets> sets_{};
  size_t last_commit_bytes_ = 0;
  mutable std::mutex mutex_;
};

}  // namespace tandem
