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
  if (accel_ && !bvh_needed_) {
    if (!bvh_missed_) bvh_missed_.emplace();
    bvh_missed_->merge(up.changes);
  } else if (accel_) {
    const ScopedActivity activity("building the acceleration structure" + of);
    const auto start = Clock::now();
    const double cpu = process_cpu_seconds();
    if (bvh_missed_) {
      SceneDelta missed = std::move(*bvh_missed_);
      bvh_missed_.reset();
      missed.merge(up.changes);
      up.accel = accel_->update(kernel_scene_, missed);
    } else {
      up.accel = accel_->update(kernel_scene_, up.changes);
    }
    up.changes.merge(up.accel.delta);
    up.accstruc_seconds = seconds_since(start);
    up.accstruc_cpu_seconds = process_cpu_seconds() - cpu;
  }
  up.generation = log_.append(up.changes);
  last_ = std::move(up);
  return last_;
}

}  // namespace tandem
