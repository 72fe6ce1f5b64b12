// The scripted camera path of headless runs and `tandem bench --frames`: a
// slow orbit of the scene's own camera around the point it looks at, with a
// gentle rise and fall, driven by time only (so every run of N frames sees
// the same cameras and, with the fixed frame step, the same scene).
#pragma once

#include "core/world/scene.h"

namespace tandem {

// Simulated seconds between scripted frames (independent of the real frame
// time, so frame i always shows time i * kScriptedFrameStep).
inline constexpr double kScriptedFrameStep = 1.0 / 30.0;

// The point `base` looks at: along forward at its focus distance.
glm::vec3 camera_target(const Camera& base);

Camera scripted_camera(const Camera& base, double t);

}  // namespace tandem
