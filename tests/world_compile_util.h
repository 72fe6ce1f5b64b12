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

// A scene's compiler and the arrays it keeps up to date, compiled as above.
struct Compiled {
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  SceneDelta compile(Scene& s) { return compile_taking_changes(compiler, s, settings, ks); }
};

}  // namespace tandem
