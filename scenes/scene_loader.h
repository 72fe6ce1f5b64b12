// Turns a SCENE argument ("builtin:NAME" or a .gltf/.glb path) into a Scene.
#pragma once

#include <string>

#include "core/scene/scene.h"

namespace tandem {

struct SceneLoadOptions {
  int gltf_scene = -1;  // -1: the file's default scene
};

// Throws InputError naming the scene and the reason.
Scene load_scene(const std::string& spec, const SceneLoadOptions& options = {});

// Loads an environment map (.hdr/.exr/.pfm, equirectangular) into `scene`.
void load_environment_map(Scene& scene, const std::string& path, float intensity);

}  // namespace tandem
