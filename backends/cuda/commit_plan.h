// Bookkeeping of the CUDA backend's double-buffered scene commits, kept free
// of CUDA so it can be unit-tested on machines without a GPU.
//
// The device holds two complete buffer sets (one device buffer per kernel
// array plus a device-side KernelData each). Frame N renders from one set
// while frame N+1's deltas are uploaded into the other, so an upload never
// waits for the GPU to finish the frame in flight (Brigade's SyncAccStruc).
// The price is that every change has to reach *both* sets: a range rewritten
// in frame N is uploaded into set A at frame N and must be uploaded into set
// B when B is next committed (frame N+1), even if frame N+1 did not touch it.
// Each set therefore remembers the generation of the kernel arrays it holds
// (KernelChangeLog), and a commit uploads the log's changes since then.
// Ranges of one array are kept apart (ArrayChange::kMaxRanges of them, one
// copy each); beyond that the closest merge, which at worst re-sends
// unchanged elements in between (never misses one).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "backends/cuda/kernel_arrays.h"
#include "core/world/kernel_change_log.h"

namespace tandem {

// One host -> device copy of elements [begin, end) of an array. `resize`:
// the set's buffer must first hold `count` elements (reallocated when its
// capacity is below count; capacity given in elements).
struct ArrayCopy {
  uint32_t array = 0;
  uint32_t begin = 0, end = 0;
  bool resize = false;
  uint32_t count = 0;       // the array's element count after this commit
  size_t new_capacity = 0;  // elements to allocate; 0 = keep the buffer
  size_t bytes() const { return size_t(end - begin) * kernel_array_element_size(array); }
};

struct CommitPlan {
  uint32_t set = 0;  // which buffer set receives the copies
  // The log and generation the set holds once the plan is performed.
  uint64_t log = 0, generation = 0;
  std::vector<ArrayCopy> copies;
  // KernelData (pointers, counts, constants) must be re-sent to the set.
  bool view_changed = false;
  size_t array_bytes() const;
  // Everything the commit moves host -> device, KernelData included.
  size_t total_bytes() const;
};

class DoubleBufferedCommits {
 public:
  static constexpr uint32_t kSets = 2;

  // Plans the upload into `target` of what `log` records after the
  // generation the set holds (everything for a set that holds nothing, or
  // another log's generation), from the current contents of `ks`, changing
  // nothing: the caller performs the plan and then reports complete()
  // (every copy was enqueued) or invalidate() (a device call failed
  // part-way), so the bookkeeping never describes buffers that a failed
  // commit left behind.
  CommitPlan plan(const KernelScene& ks, uint32_t target, const KernelChangeLog& log) const;
  void complete(const CommitPlan& plan);
  // The set's device buffers are gone (freed after a failed commit, or
  // never made): its next commit re-sends everything.
  void invalidate(uint32_t set);
  // Both sets' next commits re-send everything (their buffers stay).
  void forget_generations();

  // plan() of `delta` as the next generation of a log of this object's own
  // into the set the previous commit did not use, then complete(): one
  // alternating commit, for callers that need no recovery (tests of the
  // planner).
  CommitPlan plan(const KernelScene& ks, const SceneDelta& delta);

  // The set the most recent completed plan targeted (the one to render from).
  uint32_t current_set() const { return current_; }
  bool has_committed() const { return committed_; }
  // Element count and capacity of an array in a set, as the plans left them.
  uint32_t count(uint32_t set, uint32_t array) const { return sets_[set].count[array]; }
  size_t capacity(uint32_t set, uint32_t array) const { return sets_[set].capacity[array]; }
  // Whether the set still lacks changes `log` holds (a log it does not hold
  // a generation of: everything).
  bool pending(uint32_t set, const KernelChangeLog& log) const;
  // The same for the log of plan(ks, delta).
  bool pending(uint32_t set) const { return pending(set, own_log_); }

 private:
  struct SetState {
    uint64_t log = 0, generation = 0;  // what the set holds (log 0: nothing)
    std::array<uint32_t, kKernelArrayCount> count{};
    std::array<size_t, kKernelArrayCount> capacity{};
    bool view_uploaded = false;  // its device KernelData was ever written
  };

  std::array<SetState, kSets> sets_{};
  KernelChangeLog own_log_;       // plan(ks, delta)'s
  uint32_t current_ = kSets - 1;  // so the first alternating commit goes to set 0
  bool committed_ = false;
};

}  // namespace tandem
