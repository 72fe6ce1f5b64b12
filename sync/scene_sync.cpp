#include "sync/scene_sync.h"

#include <chrono>
#include <string>

#include "core/util/activity.h"
#include "core/util/cpu_time.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

SceneSync::SceneSync(SceneSyncSettings settings) : settings_(std::move(settings)) {
  if (settings_.bvh) accel_ = std::make_unique<AccelStructure>(settings_.accel);
}

SceneSync::~SceneSync() = default;

void SceneSync::set_bvh_layout(KBvhLayout layout) {
  settings_.accel.layout = layout;
  if (accel_) accel_->set_layout(layout);
}

const SceneSyncUpdate& SceneSync::update(Scene& scene, const RenderSettings& settings) {
  // Out of memory in either stage names the stage and the scene's file.
  const std::string of = " of " + scene.source_name();
  SceneSyncUpdate up;
  {
    const ScopedActivity activity("compiling the materials, meshes and lights" + of);
    const auto start = Clock::now();
    const double cpu = process_cpu_seconds();
    up.changes = compiler_.compile(scene, settings, kernel_scene_);
    scene.clear_dirty();  // the changes are this object's now
    up.compile_seconds = seconds_since(start);
    up.compile_cpu_seconds = process_cpu_seconds() - cpu;
  }
  // The compiler's changes make the new generation; the BVH's, made from
  // them, join it.
  up.generation = log_.append(up.changes);
  if (accel_ && bvh_needed_) {
    const ScopedActivity activity("building the acceleration structure" + of);
    const auto start = Clock::now();
    const double cpu = process_cpu_seconds();
    // The generations since the BVH last followed: this one alone, unless
    // it was not needed for a while (then all it missed; further back than
    // the log keeps, or never built: everything, a full build).
    if (bvh_generation_ + 1 == up.generation) {
      up.accel = accel_->update(kernel_scene_, up.changes);
    } else {
      up.accel = accel_->update(kernel_scene_, log_.changes_since(bvh_generation_));
    }
    bvh_generation_ = up.generation;
    log_.add_to_newest(up.accel.delta);
    up.changes = log_.newest();
    up.accstruc_seconds = seconds_since(start);
    up.accstruc_cpu_seconds = process_cpu_seconds() - cpu;
  }
  last_ = std::move(up);
  return last_;
}

}  // namespace tandem
