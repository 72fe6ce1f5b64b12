// SceneSync: the one way a Scene's edits reach the kernel arrays that every
// backend reads (Brigade's SyncScene and UpdateAccStruc, in that order).
//
// It owns the SceneCompiler (scene arrays and constants), the AccelStructure
// (Tandem's BVH arrays, when some consumer traces them) and the KernelScene
// they fill. update() brings all three up to date with a Scene and returns
// a new generation; every consumer (a backend, an MPI peer) remembers the
// generation it last committed and asks changes_since(g) for what it has
// not seen. So a caller never joins the compiler's and the BVH's changes by
// hand, never keeps "what was compiled early" or "what the BVH missed", and
// two consumers that commit at different times (one ahead during a render,
// one after it) each get exactly their own backlog.
#pragma once

#include <cstdint>
#include <memory>

#include "accstruc/accel_structure.h"
#include "core/world/kernel_change_log.h"
#include "core/world/kernel_scene.h"
#include "core/world/scene.h"

namespace tandem {

struct SceneSyncSettings {
  // Build and keep Tandem's BVH (TANDEM_BVH_ARRAYS). Off for consumers that
  // build their own (Embree) or need only the scene arrays.
  bool bvh = true;
  AccelSettings accel;
  // The scene arrays alone, for consumers that build their own structures.
  static SceneSyncSettings arrays_only() {
    SceneSyncSettings s;
    s.bvh = false;
    return s;
  }
};

// What one update() did.
struct SceneSyncUpdate {
  uint64_t generation = 0;
  // The arrays this update rewrote: the compiler's and the BVH's together.
  SceneDelta changes;
  // The BVH's part (counts and timings); empty when the BVH was not updated.
  AccelUpdate accel;
  // Wall time of each stage, and the process's CPU time in it (all threads).
  double compile_seconds = 0.0, accstruc_seconds = 0.0;
  double compile_cpu_seconds = 0.0, accstruc_cpu_seconds = 0.0;
};

class SceneSync {
 public:
  explicit SceneSync(SceneSyncSettings settings = {});
  ~SceneSync();
  SceneSync(const SceneSync&) = delete;
  SceneSync& operator=(const SceneSync&) = delete;

  // Compiles `scene`'s dirty objects under `settings` (the first call, or
  // an added or removed object, compiles everything), then updates the BVH
  // when it is needed, and clears the scene's dirty flags. Returns what was
  // done; its generation is the new generation() (one more than before,
  // also when nothing changed). Out of memory names the stage and the
  // scene's file (core/util/activity.h).
  const SceneSyncUpdate& update(Scene& scene, const RenderSettings& settings);

  // Generation of the last update(); 0 before the first.
  uint64_t generation() const { return log_.generation(); }
  // What changed in the kernel arrays after generation `since`, up to
  // generation(): the union of the updates in between. A consumer that has
  // seen nothing (since 0), or whose generation is older than the kept
  // history, gets everything.
  SceneDelta changes_since(uint64_t since) const { return log_.changes_since(since); }
  // The log itself, for consumers that keep their own generation
  // (Backend::sync_from()).
  const KernelChangeLog& change_log() const { return log_; }

  // Whether Tandem's BVH is kept up to date, and in which layout. While it
  // is not needed (the GPU that traced it fell back to Embree) updates skip
  // it; the first update after it is needed again brings it to what every
  // update would have made of it. No effect without SceneSyncSettings::bvh.
  void set_bvh_needed(bool needed) { bvh_needed_ = needed; }
  // Takes effect at the next update() (kd.bvh.layout changes then).
  void set_bvh_layout(KBvhLayout layout);
  bool has_bvh() const { return accel_ != nullptr; }
  // The BVH builder (per-mesh BLAS, the TLAS); null without SceneSyncSettings::bvh.
  const AccelStructure* accel() const { return accel_.get(); }

  const KernelScene& kernel_scene() const { return kernel_scene_; }
  KernelData view() const { return kernel_scene_.view(); }

 private:
  SceneSyncSettings settings_;
  SceneCompiler compiler_;
  KernelScene kernel_scene_;
  std::unique_ptr<AccelStructure> accel_;
  bool bvh_needed_ = true;
  // The generation the BVH was last brought up to (0: never): while it is
  // not needed it falls behind, and catches up on changes_since() it.
  uint64_t bvh_generation_ = 0;
  KernelChangeLog log_;
  SceneSyncUpdate last_;
};

}  // namespace tandem
