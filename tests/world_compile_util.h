// SceneCompiler::compile as SceneSync runs it, for the tests of the compiler
// itself: the compiler only reads the Scene, and whoever takes its changes
// clears the dirty flags.
#pragma once

#include "core/world/kernel_scene.h"

namespace tandem {

inline SceneDelta compile_taking_changes(SceneCompiler& compiler, Scene& scene,
                                         const RenderSettings& settings, KernelScene& out) {
  SceneDelta delta = compiler.compile(scene, settings, out);
  scene.clear_dirty();
  return delta;
}

}  // namespace tandem
