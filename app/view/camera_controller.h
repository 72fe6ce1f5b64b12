// Interactive cameras for tandem-view, free of any windowing code so tests
// can drive them: a first-person fly camera (WASD + mouse look) and an orbit
// camera (drag to orbit, pan, wheel to zoom). Both read one frame's input and
// write position/forward/up into a Camera, reporting whether it moved (any
// motion restarts progressive accumulation).
#pragma once

#include <glm/glm.hpp>

#include "core/world/scene.h"

namespace tandem {

// The longest step a controller takes from one frame's input. After a long
// frame (a still frame converging, a stall) the next frame's dt is large:
// moving by speed * dt would throw the camera out of the scene.
inline constexpr double kMaxFrameDeltaSeconds = 0.1;
inline double clamp_frame_delta(double dt) {
  return dt > kMaxFrameDeltaSeconds ? kMaxFrameDeltaSeconds : (dt > 0.0 ? dt : 0.0);
}

// One frame of input, already decoded from the window system.
struct CameraInput {
  double dt = 0.0;  // seconds since the previous frame (clamp_frame_delta() applies)
  // Fly camera: held keys (W/S, A/D, E/Q, shift).
  bool forward = false, back = false, left = false, right = false, up = false, down = false;
  bool fast = false;
  // Mouse motion in pixels: look (fly, while the look button is held),
  // orbit (left drag) and pan (right drag); wheel in notches (+ = zoom in).
  glm::vec2 look{0.0f}, orbit{0.0f}, pan{0.0f};
  float wheel = 0.0f;
};

class FlyCamera {
 public:
  // Starts where `camera` is, looking where it looks; `speed` in scene
  // units per second (shift multiplies it by 4).
  FlyCamera(const Camera& camera, float speed);
  bool update(const CameraInput& in, Camera& camera);
  float yaw() const { return yaw_; }
  float pitch() const { return pitch_; }
  void set_speed(float speed) { speed_ = speed; }

  static constexpr float kRadiansPerPixel = 0.003f;

 private:
  glm::vec3 position_;
  float yaw_, pitch_;  // radians; yaw about +y from -z, pitch from the horizon
  float speed_;
};

class OrbitCamera {
 public:
  // Orbits `target` at the camera's current distance from it.
  OrbitCamera(const Camera& camera, const glm::vec3& target);
  bool update(const CameraInput& in, Camera& camera);
  const glm::vec3& target() const { return target_; }
  float distance() const { return distance_; }

  static constexpr float kRadiansPerPixel = 0.005f;
  static constexpr float kZoomPerNotch = 0.9f;  // distance factor per wheel notch

 private:
  glm::vec3 target_;
  float yaw_, pitch_, distance_;
};

// Unit forward vector for yaw/pitch (yaw 0, pitch 0 looks down -z) and the
// camera basis the kernel wants (up orthogonal to forward).
glm::vec3 forward_from_angles(float yaw, float pitch);
void set_camera_basis(Camera& camera, const glm::vec3& position, const glm::vec3& forward);

}  // namespace tandem
