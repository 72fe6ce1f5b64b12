// Small light scenes shared by the kernel's light and environment tests.
#pragma once

#include <cstdint>

#include "core/world/kernel_scene.h"
#include "core/world/light_tables.h"

namespace tandem::light_test {

inline constexpr uint32_t kEnvWidth = 32, kEnvHeight = 16;

// A 32x16 map with a horizontal/vertical colour gradient and a small bright
// spot (a "sun" 200x brighter than the sky), then the sampling tables.
inline KernelScene make_environment_scene(float rotation) {
  KernelScene ks;
  ks.env_texels.resize(kEnvWidth * kEnvHeight);
  for (uint32_t y = 0; y < kEnvHeight; ++y) {
    for (uint32_t x = 0; x < kEnvWidth; ++x) {
      const float gx = float(x) / float(kEnvWidth - 1), gy = float(y) / float(kEnvHeight - 1);
      Vec3 c = make_vec3(0.2f + 0.8f * gx, 0.3f + 0.5f * gy, 0.1f + 0.4f * gx * gy);
      if (x >= 20 && x <= 22 && y >= 4 && y <= 5) c = make_vec3(60.0f, 50.0f, 40.0f);
      ks.env_texels[y * kEnvWidth + x] = make_vec4(c, 0.0f);
    }
  }
  KEnvironment& env = ks.constants.environment;
  env.color = make_vec3(1.0f);
  env.has_map = 1;
  env.width = kEnvWidth;
  env.height = kEnvHeight;
  set_environment_rotation(env, rotation);
  build_environment_tables(ks);
  return ks;
}

}  // namespace tandem::light_test
