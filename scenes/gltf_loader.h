// glTF 2.0 (.gltf / .glb) loader: turns a file into a tandem::Scene.
//
// The file is parsed by tinygltf and then validated completely before any
// Scene object is built, because tinygltf accepts many broken files (indices
// out of range, views past their buffer, node cycles, ...). Every problem
// that would make the scene wrong or the renderer misbehave is an InputError;
// things we can degrade gracefully (a missing texture image, an unsupported
// optional extension, skins, morph targets, animations) are warnings.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "core/scene/scene.h"

namespace tandem {

struct GltfAnimations;

struct GltfOptions {
  // Which of the file's scenes to load. -1: the file's default scene (its
  // "scene" property, or scene 0 when it has none).
  int scene_index = -1;
  // When set, node animations are loaded into it (see gltf_animation.h) so
  // the caller can play them; otherwise they are ignored with a warning.
  GltfAnimations* animations = nullptr;
};

// Summary numbers for tests and `tandem info`: counts taken from the file
// itself (not from the built Scene, which merges, de-duplicates and drops
// unused objects).
struct GltfSummary {
  std::string generator;  // asset.generator
  size_t scenes = 0;      // entries in "scenes"
  int scene_loaded = -1;  // index of the scene that was loaded, -1 = implicit (no scenes)
  size_t nodes = 0;
  size_t meshes = 0;
  size_t primitives = 0;      // over all meshes
  size_t file_triangles = 0;  // triangles of all meshes' triangle primitives, before any dropping
  size_t degenerate_triangles_dropped = 0;  // over all meshes (each counted once, not per instance)
  size_t materials = 0;
  size_t textures = 0;
  size_t images = 0;
  size_t images_unavailable = 0;  // referenced images that were missing or could not be decoded
  size_t samplers = 0;
  size_t cameras = 0;
  size_t lights = 0;      // KHR_lights_punctual lights defined in the file
  size_t animations = 0;  // loaded only when GltfOptions::animations is set
  size_t skins = 0;       // ignored by the loader
  std::vector<std::string> extensions_used;
  std::vector<std::string> extensions_required;
};

// Loads `path`. Throws InputError whose what() is "<path>: <reason>" for any
// bad file. Warnings go to log_warning() and loading continues. When
// `summary` is given it is filled in as well.
Scene load_gltf(const std::filesystem::path& path, const GltfOptions& options = {},
                GltfSummary* summary = nullptr);

}  // namespace tandem
