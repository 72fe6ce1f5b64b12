#include "app/view/camera_controller.h"

#include <algorithm>
#include <cmath>

namespace tandem {

namespace {

// Just short of straight up/down, where yaw would become meaningless.
constexpr float kMaxPitch = 1.55f;

void angles_from_forward(const glm::vec3& f, float& yaw, float& pitch) {
  pitch = std::asin(std::clamp(f.y, -1.0f, 1.0f));
  yaw = std::atan2(f.x, -f.z);
}

}  // namespace

glm::vec3 forward_from_angles(float yaw, float pitch) {
  return {std::sin(yaw) * std::cos(pitch), std::sin(pitch), -std::cos(yaw) * std::cos(pitch)};
}

void set_camera_basis(Camera& camera, const glm::vec3& position, const glm::vec3& forward) {
  camera.position = position;
  camera.forward = glm::normalize(forward);
  // Pitch is clamped below 90 degrees, so forward is never parallel to +y.
  const glm::vec3 right = glm::normalize(glm::cross(camera.forward, glm::vec3(0.0f, 1.0f, 0.0f)));
  camera.up = glm::normalize(glm::cross(right, camera.forward));
}

FlyCamera::FlyCamera(const Camera& camera, float speed)
    : position_(camera.position), speed_(speed) {
  angles_from_forward(camera.forward, yaw_, pitch_);
  pitch_ = std::clamp(pitch_, -kMaxPitch, kMaxPitch);
}

bool FlyCamera::update(const CameraInput& in, Camera& camera) {
  bool moved = false;
  if (in.look != glm::vec2(0.0f)) {
    yaw_ += in.look.x * kRadiansPerPixel;
    pitch_ = std::clamp(pitch_ - in.look.y * kRadiansPerPixel, -kMaxPitch, kMaxPitch);
    moved = true;
  }
  const glm::vec3 fwd = forward_from_angles(yaw_, pitch_);
  const glm::vec3 right = glm::normalize(glm::cross(fwd, glm::vec3(0.0f, 1.0f, 0.0f)));
  glm::vec3 dir(0.0f);
  if (in.forward) dir += fwd;
  if (in.back) dir -= fwd;
  if (in.right) dir += right;
  if (in.left) dir -= right;
  if (in.up) dir.y += 1.0f;
  if (in.down) dir.y -= 1.0f;
  const double dt = clamp_frame_delta(in.dt);
  if (dir != glm::vec3(0.0f) && dt > 0.0) {
    const float speed = speed_ * (in.fast ? 4.0f : 1.0f);
    position_ += glm::normalize(dir) * speed * float(dt);
    moved = true;
  }
  if (moved || camera.position != position_) set_camera_basis(camera, position_, fwd);
  return moved;
}

OrbitCamera::OrbitCamera(const Camera& camera, const glm::vec3& target) : target_(target) {
  const glm::vec3 to_camera = camera.position - target;
  distance_ = std::max(glm::length(to_camera), 1e-3f);
  angles_from_forward(-to_camera / distance_, yaw_, pitch_);
  pitch_ = std::clamp(pitch_, -kMaxPitch, kMaxPitch);
}

bool OrbitCamera::update(const CameraInput& in, Camera& camera) {
  bool moved = false;
  if (in.orbit != glm::vec2(0.0f)) {
    yaw_ += in.orbit.x * kRadiansPerPixel;
    pitch_ = std::clamp(pitch_ - in.orbit.y * kRadiansPerPixel, -kMaxPitch, kMaxPitch);
    moved = true;
  }
  glm::vec3 fwd = forward_from_angles(yaw_, pitch_);
  if (in.pan != glm::vec2(0.0f)) {
    // Pan in the view plane, scaled with distance so the point under the
    // cursor roughly follows it.
    const glm::vec3 right = glm::normalize(glm::cross(fwd, glm::vec3(0.0f, 1.0f, 0.0f)));
    const glm::vec3 up = glm::cross(right, fwd);
    const float k = distance_ * 0.002f;
    target_ += (-in.pan.x * right + in.pan.y * up) * k;
    moved = true;
  }
  if (in.wheel != 0.0f) {
    distance_ = std::clamp(distance_ * std::pow(kZoomPerNotch, in.wheel), 1e-2f, 1e5f);
    moved = true;
  }
  if (moved) set_camera_basis(camera, target_ - fwd * distance_, fwd);
  return moved;
}

}  // namespace tandem
