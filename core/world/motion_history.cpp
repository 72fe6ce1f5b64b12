#include "core/world/motion_history.h"

namespace tandem {

FeaturePass MotionHistory::advance(const KernelData& kd) {
  std::vector<Mat34> current(kd.instances_count);
  for (uint32_t i = 0; i < kd.instances_count; ++i)
    current[i] = kd.instances[i].object_to_world;
  FeaturePass pass{};
  const KCamera& cam = kd.constants.camera;
  // A new resolution changes the film mapping: measure from the same
  // camera at the new size (the history is dropped by the denoiser anyway).
  const bool usable =
      has_last_ && last_camera_.width == cam.width && last_camera_.height == cam.height;
  if (usable) {
    prev_.swap(last_);
    pass.prev_camera = last_camera_;
  } else {
    prev_ = current;
    pass.prev_camera = cam;
  }
  last_ = std::move(current);
  last_camera_ = cam;
  has_last_ = true;
  pass.prev_object_to_world = prev_.data();
  pass.prev_instance_count = uint32_t(prev_.size());
  return pass;
}

}  // namespace tandem
