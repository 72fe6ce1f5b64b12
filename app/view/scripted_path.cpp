#include "app/view/scripted_path.h"

#include <cmath>

#include "app/view/camera_controller.h"

namespace tandem {

glm::vec3 camera_target(const Camera& base) {
  const float d = base.focus_distance > 0.0f ? base.focus_distance : 1.0f;
  return base.position + base.forward * d;
}

Camera scripted_camera(const Camera& base, double t) {
  const glm::vec3 target = camera_target(base);
  const glm::vec3 offset = base.position - target;
  const float angle = float(0.25 * t);  // radians: a full turn in ~25 s
  const float c = std::cos(angle), s = std::sin(angle);
  glm::vec3 rotated(c * offset.x + s * offset.z, offset.y, -s * offset.x + c * offset.z);
  rotated.y += 0.15f * glm::length(offset) * float(std::sin(0.4 * t));
  Camera cam = base;
  set_camera_basis(cam, target + rotated, target - (target + rotated));
  return cam;
}

}  // namespace tandem
