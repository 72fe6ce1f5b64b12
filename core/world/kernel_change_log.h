// What changed in the kernel arrays, generation by generation.
//
// Each generation is one update of the arrays (SceneSync::update): per
// kernel array the ranges its writers rewrote (the per-kind compilers, the
// compiler's writes of posed meshes, the BVH emitters) or "reallocated",
// and the few meaning-level events a backend needs beyond ranges (meshes
// rebuilt or refit, instances moved, constants), all in the SceneDelta the
// writers fill. The BVH, which follows the compiler, adds its changes to
// the same generation. Every consumer keeps the generation it last
// committed and asks changes_since() for its backlog: a backend that syncs
// every frame, one of the CUDA backend's two device buffer sets that was
// last written two frames ago, an MPI worker, the BVH itself after a time
// it was not needed. None of them keeps lists of pending changes of its
// own, and only this log joins two generations' changes.
#pragma once

#include <cstdint>
#include <deque>

#include "core/world/kernel_scene.h"

namespace tandem {

class KernelChangeLog {
 public:
  KernelChangeLog();
  // A copy is another log: its generations mean nothing to the consumers of
  // this one (a new id()).
  KernelChangeLog(const KernelChangeLog& other);
  KernelChangeLog& operator=(const KernelChangeLog& other);

  // Records the changes of a new generation and returns it (1, 2, ...).
  uint64_t append(const SceneDelta& changes);
  // More changes of the newest generation, made from it by a later stage
  // of the same update (the BVH after the compiler). Throws
  // std::logic_error before the first append().
  void add_to_newest(const SceneDelta& changes);
  // The newest generation; 0 before the first append().
  uint64_t generation() const { return generation_; }
  // Its changes (empty before the first append()).
  const SceneDelta& newest() const { return kept_.empty() ? none_ : kept_.back(); }
  // What changed after generation `since`, up to generation(): the union of
  // the generations in between. A consumer that has seen nothing (since 0)
  // or is further behind than the log keeps gets everything
  // (SceneDelta::everything()). Throws std::logic_error for a generation
  // this log has not reached.
  SceneDelta changes_since(uint64_t since) const;
  // Unique per log object in this process: a consumer that remembers a
  // generation remembers the log's id with it, so it never applies another
  // log's generation numbers.
  uint64_t id() const { return id_; }

  // Generations kept for changes_since(): consumers commit every frame or
  // two, so a few suffice.
  static constexpr size_t kKept = 16;

 private:
  uint64_t id_;
  uint64_t generation_ = 0;
  std::deque<SceneDelta> kept_;  // generations (generation_ - kept_.size(), generation_]
  SceneDelta none_;
};

}  // namespace tandem
