// glTF 2.0 (.gltf / .glb) loader: turns a file into a tandem::Scene.
//
// The file is parsed by tinygltf and then validated completely before any
// Scene object is built, because tinygltf accepts many broken files (indices
// out of range, views past their buffer, node cycles, ...). Every problem
// that would make the scene wrong or the renderer misbehave is an InputError;
// things we can degrade gracefully (a missing texture image, an unsupported
// optional extension, animations when they are not asked for) are warnings.
// Skinned and morphing meshes are shown in their rest pose; with
// GltfOptions::animations they move (GltfAnimations::deformed).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/world/scene.h"

namespace tandem {

struct GltfAnimations;

// What a file may make the loader allocate. Sizes written in a small file
// (counts of accessors without data, images that claim huge dimensions, one
// accessor shared by many primitives) must not turn into unbounded memory,
// so every decoded accessor, merged mesh, instance and texel is counted
// against these before it is allocated; going over is an InputError that
// names the file, the object and the size (textures over budget are
// skipped with a warning instead). Accessor and geometry budgets grow with
// the bytes actually in the file's buffers (4x and 6x), so big real scenes
// load; the defaults suit real scenes, tests and the fuzzer lower them.
struct GltfLimits {
  uint32_t max_json_depth = 128;                          // nesting of JSON arrays/objects
  uint64_t max_accessor_bytes = uint64_t(1) << 30;        // all decoded accessors together
  uint64_t max_zero_filled_elements = uint64_t(1) << 22;  // accessors without bufferView, together
  uint64_t max_geometry_bytes = uint64_t(2) << 30;  // merged meshes' vertex and triangle arrays
  uint64_t max_instances = uint64_t(1) << 22;       // scene instances (nodes and GPU instancing)
  uint64_t max_texture_pixels = uint64_t(1) << 26;  // one image (8192 x 8192)
  uint64_t max_texture_bytes = uint64_t(2) << 30;   // decoded texels of all textures together
  // What decoding one image may hold at once (stb's rows and image, then
  // RGBA8: a 16-bit 8192x8192 RGB PNG takes 768 MiB), and all decoding
  // threads together.
  uint64_t max_image_decode_bytes = uint64_t(1) << 30;
  // Instance names: a node's name is copied to each of its instances (and
  // EXT_mesh_gpu_instancing makes many); names are cut to 256 bytes.
  uint64_t max_name_bytes = uint64_t(64) << 20;
  // Light records: the renderer keeps one (64 bytes) for each emissive
  // triangle of a mesh, once however often the mesh is placed, and one for
  // each instance of an emissive mesh.
  uint64_t max_emissive_lights = uint64_t(1) << 21;
};

struct GltfOptions {
  // Which of the file's scenes to load. -1: the file's default scene (its
  // "scene" property, or scene 0 when it has none).
  int scene_index = -1;
  // When set, node animations are loaded into it (see gltf_animation.h) so
  // the caller can play them; otherwise they are ignored with a warning.
  GltfAnimations* animations = nullptr;
  // Buffer and image URIs must resolve (symlinks followed) inside the folder
  // of the scene file, so a downloaded scene cannot read other files; this
  // lets them point anywhere.
  bool allow_outside_uris = false;
  // Which of the scene's cameras (its camera nodes in walk order, as
  // GltfSummary::camera_names lists them) to use; -1: the first, if any.
  // One beyond them is an InputError.
  int camera = -1;
  GltfLimits limits;
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
  size_t skins = 0;       // skins in the file
  // The loaded scene's camera nodes (what GltfOptions::camera counts), and
  // a line about each of the first 100 (node name and projection).
  size_t scene_cameras = 0;
  std::vector<std::string> camera_names;
  std::vector<Camera> camera_list;  // the same first 100, as the scene would take them
  std::vector<std::string> extensions_used;
  std::vector<std::string> extensions_required;
  // What `tandem info` lists of the file (the first 100 of each).
  std::vector<std::string> scene_names;  // "" where unnamed
  struct Animation {
    std::string name;
    double seconds = 0.0;  // the last key time of its channels
    size_t channels = 0;
  };
  std::vector<Animation> animation_list;
  struct Skin {
    std::string name;
    size_t joints = 0;
  };
  std::vector<Skin> skin_list;
  size_t morph_meshes = 0;        // meshes with morph targets
  size_t most_morph_targets = 0;  // the most targets one primitive has
};

// Loads `path`. Throws InputError whose what() is "<path>: <reason>" for any
// bad file. Warnings go to log_warning() and loading continues. When
// `summary` is given it is filled in as well.
Scene load_gltf(const std::filesystem::path& path, const GltfOptions& options = {},
                GltfSummary* summary = nullptr);

// The same for a file already in memory (the fuzzer's entry point): `label`
// names it in messages, relative URIs resolve against `base_dir`.
Scene load_gltf_from_memory(const unsigned char* data, size_t size, const std::string& label,
                            const std::filesystem::path& base_dir, const GltfOptions& options = {},
                            GltfSummary* summary = nullptr);

}  // namespace tandem
