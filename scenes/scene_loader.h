// Turns a SCENE argument ("builtin:NAME" or a .gltf/.glb path) into a Scene.
#pragma once

#include <string>

#include "core/image/image.h"
#include "core/world/scene.h"

namespace tandem {

struct GltfAnimations;
struct GltfSummary;

struct SceneLoadOptions {
  int gltf_scene = -1;  // -1: the file's default scene
  // glTF URIs may name files outside the scene file's folder (see GltfOptions).
  bool allow_outside_uris = false;
  // When set, a glTF file's node animations are loaded into it (see
  // scene_animator.h to play them).
  GltfAnimations* animations = nullptr;
  // Which of a glTF scene's cameras to use (GltfOptions::camera; -1: the
  // first). A built-in scene has one: camera 0.
  int camera = -1;
  // When set, a glTF file's summary (gltf_loader.h) is written here.
  GltfSummary* gltf_summary = nullptr;
};

// Throws InputError naming the scene and the reason.
Scene load_scene(const std::string& spec, const SceneLoadOptions& options = {});

// An environment map's pixels, and the memory each takes once the scene is
// compiled (measured: an 8192x4096 map peaked at 1.3 GB).
constexpr uint64_t kMaxEnvironmentPixels = uint64_t(8192) * 4096;
constexpr uint32_t kEnvironmentBytesPerPixel = 40;

// Loads an environment map (.hdr/.exr/.pfm, equirectangular) into `scene`.
// Throws InputError when it has more than kMaxEnvironmentPixels (checked
// from its header) or its brightest texel times `intensity` is beyond what
// float radiance can accumulate (it would render black).
void load_environment_map(Scene& scene, const std::string& path, float intensity);

// The same for an image already decoded; `source` names it in messages.
void set_environment_map(Scene& scene, const ImageRGB& image, const std::string& source,
                         float intensity);

// The default sky that lights a glTF scene no environment was given for
// (the CLI, the viewer and the API's load_gltf), decoded from the bytes
// embedded at build time.
ImageRGB default_environment_image();
// Where the default sky's source lives in the repository (for messages).
constexpr const char* kDefaultEnvironmentName = "data/env/sky.hdr";

}  // namespace tandem
