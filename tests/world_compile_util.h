// SceneCompiler::compile as SceneSync runs it, for the tests of the compiler
// itself: the compiler only reads the Scene, and whoever takes its changes
// clears the dirty flags.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "core/world/kernel_scene.h"

namespace tandem {

inline SceneDelta compile_taking_changes(SceneCompiler& compiler, Scene& scene,
                                         const RenderSettings& settings, KernelScene& out) {
  SceneDelta delta = compiler.compile(scene, settings, out);
  scene.clear_dirty();
  return delta;
}

// A scene's compiler and the arrays it keeps up to date, compiled as above.
struct Compiled {
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  SceneDelta compile(Scene& s) { return compile_taking_changes(compiler, s, settings, ks); }
};

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  // memcmp must not see the null data() of an empty vector.
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// What the compiler owns, compared byte for byte, after edit `step`.
inline void expect_same_scene_arrays(const KernelScene& a, const KernelScene& b, int step) {
#define TANDEM_EXPECT_SAME(T, name) \
  EXPECT_TRUE(same_bytes(a.name, b.name)) << #name << " differs after edit " << step;
  TANDEM_SCENE_ARRAYS(TANDEM_EXPECT_SAME)
#undef TANDEM_EXPECT_SAME
  EXPECT_EQ(std::memcmp(&a.constants, &b.constants, sizeof(KernelConstants)), 0)
      << "constants differ after edit " << step;
}

}  // namespace tandem
