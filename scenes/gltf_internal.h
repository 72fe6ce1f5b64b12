// Pieces shared by the glTF loader's translation units (not a public API;
// tests include it to check the image conversion).
//
// Flow: gltf_loader.cpp reads the file and runs tinygltf, gltf_validate.cpp
// checks every index, range and format in the tinygltf model, then
// gltf_mesh.cpp (geometry, via gltf_accessor.cpp) and gltf_material.cpp
// (materials, textures, images) convert the validated model, and
// gltf_loader.cpp assembles nodes, instances, camera and lights.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <tiny_gltf.h>

#include "core/world/scene.h"
#include "scenes/gltf_animation.h"
#include "scenes/gltf_loader.h"

namespace tandem::gltf {

// --- limits -----------------------------------------------------------------
// Hard limits of the data structures; the memory budgets a file is held to
// are GltfLimits (gltf_loader.h), counted by Context::charge().
inline constexpr uint64_t kMaxMeshVertices = (uint64_t(1) << 31) - 1;   // per tandem Mesh
inline constexpr uint64_t kMaxMeshTriangles = (uint64_t(1) << 31) - 1;  // per tandem Mesh
inline constexpr uint64_t kMaxFileBytes = (uint64_t(1) << 32) - 1;  // tinygltf takes 32-bit sizes

// "1.5 GiB", "12 KiB", "17 bytes": sizes in budget messages.
std::string format_bytes(uint64_t bytes);

// What Context::charge() counts, one running total each.
enum class Budget {
  kAccessorBytes,
  kZeroFilledElements,
  kGeometryBytes,
  kInstances,
  kTextureBytes,
  kNameBytes,       // instance names (a node's name is copied to each of its instances)
  kEmissiveLights,  // each emissive mesh's triangles once, and its instances: a light record each
};
constexpr int kBudgetCount = 7;

// Error/warning helper: every message is prefixed with the file path, as
// the user gave it, so messages are complete sentences on their own.
class Context {
 public:
  Context(std::string path, const tinygltf::Model& model, const GltfLimits& limits = {})
      : model(model), limits(limits), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& reason) const;
  void warn(const std::string& message) const;
  // Warns only the first time `key` is seen (e.g. "one warning per feature").
  void warn_once(const std::string& key, const std::string& message);
  const std::string& path() const { return path_; }

  // Adds `amount` to the running total of `budget`, or fails (before the
  // caller allocates anything) naming `what` and the sizes. Thread-safe is
  // not needed: all charging happens on the loading thread.
  void charge(Budget budget, uint64_t amount, const std::string& what) const;
  // Whether `amount` more would still fit (for things skipped, not failed).
  bool fits(Budget budget, uint64_t amount) const;
  uint64_t used(Budget budget) const { return used_[int(budget)]; }

  const tinygltf::Model& model;
  const GltfLimits& limits;

 private:
  uint64_t limit(Budget budget) const;

  std::string path_;
  std::set<std::string> warned_;
  mutable uint64_t used_[kBudgetCount] = {};
};

// --- gltf_input_guard.cpp ------------------------------------------------------
// Checks on the raw file before tinygltf sees it, and on the files it opens.

// The deepest nesting of JSON arrays/objects in `json` (outside strings),
// stopping early at `limit` + 1. tinygltf converts JSON to its Value type
// recursively, so a file nested thousands deep overflows the stack there.
size_t json_nesting_depth(const char* json, size_t size, size_t limit, size_t* where);
// Throws InputError naming `label`, the object and the field for an index,
// offset, stride, count or enum value of the JSON text that the glTF schema
// forbids (tinygltf reads such a value as absent). Malformed JSON passes:
// tinygltf explains it.
void check_schema_ranges(const char* json, size_t size, const std::string& label);
// The JSON chunk of a .glb, or false when the container is malformed (then
// tinygltf explains what is wrong).
bool glb_json_chunk(const unsigned char* data, size_t size, const char** json, size_t* json_size);
// What is wrong with a .glb's BIN chunk that tinygltf would read past the
// end of the file for, or "".
std::string glb_bin_chunk_problem(const unsigned char* data, size_t size);

// Where tinygltf may read buffers and images from: inside the scene file's
// folder (after resolving symlinks and "..") unless outside is allowed.
struct UriPolicy {
  std::filesystem::path base_dir;  // canonical folder of the scene file
  std::string joined_base;         // the folder as given to tinygltf, to show URIs as written
  bool allow_outside = false;
  std::string refused;  // why the first refused file was refused, for the error
  // Whether `path` (as tinygltf joined it) may be read; records the reason.
  bool permits(const std::string& path);
};

// --- gltf_accessor.cpp ---------------------------------------------------------
// Component / element sizes; 0 for invalid values. Element size includes
// glTF's 4-byte column padding for matrices with 1- or 2-byte components.
size_t component_size(int component_type);
int component_count(int type);
size_t accessor_element_size(int component_type, int type);

// Decodes validated accessors to floats / indices, applying byteStride,
// normalization and sparse substitution. Results are cached per accessor
// because glTF files commonly share accessors between meshes.
class AccessorCache {
 public:
  explicit AccessorCache(const Context& ctx) : ctx_(ctx) {}

  // count * components floats. Float accessors are checked to be finite;
  // `what` names the use in the error message ("POSITION of mesh 0 primitive 0").
  const std::vector<float>& floats(int accessor, const std::string& what);
  // Scalar unsigned integers (indices, sparse indices).
  const std::vector<uint32_t>& uints(int accessor, const std::string& what);

 private:
  // Counts an accessor's decoded size against the budgets before allocating.
  void charge(const tinygltf::Accessor& a, size_t bytes_per_element, const std::string& who);

  const Context& ctx_;
  std::map<int, std::vector<float>> floats_;
  std::map<int, std::vector<uint32_t>> uints_;
};

// --- gltf_mesh.cpp ---------------------------------------------------------------
struct DecodedMeshes {
  // One entry per glTF mesh: all its triangle primitives merged. Material
  // indices are glTF material indices, or `default_material` for primitives
  // without one.
  std::vector<Mesh> meshes;
  // Meshes with equal keys reference the same accessors and materials, so
  // they can share one tandem Mesh.
  std::vector<std::string> keys;
  std::vector<bool> uses_default_material;
  size_t primitives = 0;
  size_t file_triangles = 0;
  size_t dropped_degenerate = 0;
};
// Decodes and checks every mesh of the file (unused ones too: a broken mesh
// makes the file invalid whether or not the chosen scene shows it).
DecodedMeshes decode_meshes(Context& ctx, AccessorCache& cache, uint32_t default_material);

// --- gltf_material.cpp ---------------------------------------------------------
// Encoded bytes of images that tinygltf read from URIs, by image index
// (filled by the image-loader callback, which never decodes; see
// gltf_loader.cpp for why).
// Sixteen image entries naming one file hold one copy of its bytes.
struct EncodedImages {
  std::map<int, std::vector<unsigned char>> by_image;
  std::map<int, int> same_as;         // image index -> an earlier image with identical bytes
  std::map<int, std::string> errors;  // why an image's file was not read (e.g. UriPolicy)
  void keep(int index, const unsigned char* bytes, size_t size);
  bool has(int index) const { return by_image.count(index) || same_as.count(index); }
  // Bytes of image `index`, or nullptr when tinygltf did not read any.
  const std::vector<unsigned char>* bytes(int index) const;
};

struct MaterialResult {
  std::vector<Material> materials;  // one per glTF material, in file order
  std::vector<Texture> textures;    // only textures that materials reference and that loaded
  size_t images_unavailable = 0;
};
// Converts all materials; decodes the images they reference (in parallel).
// Texture references whose image is missing or undecodable become -1 with
// a warning.
MaterialResult convert_materials(Context& ctx, const EncodedImages& encoded);

// Converts a decoded tinygltf image (1-4 channels, 8 or 16 bits) to packed
// RGBA8 (grey -> RGB = grey, missing alpha -> 255, 16 bit -> 8 bit rounded).
// Returns false when the layout is not one of those.
bool image_to_rgba8(const tinygltf::Image& image, std::vector<uint32_t>& out);
// An 8-bit PNG (any colour type, interlaced or not) to packed RGBA8 through
// libpng (gltf_png.cpp). False with `error` set when libpng refuses it
// (16-bit PNGs included: those go through stb).
bool decode_png_rgba8(const unsigned char* bytes, size_t size, uint32_t& width, uint32_t& height,
                      std::vector<uint32_t>& rgba8, std::string& error);
// The same for `size` bytes of decoded pixels.
bool pixels_to_rgba8(const unsigned char* data, size_t size, int width, int height, int channels,
                     int bits, std::vector<uint32_t>& out);

// --- gltf_animation.cpp -----------------------------------------------------------
// A node reached by the loader's walk of the chosen scene, in walk order
// (parents before children); parent is -1 for the scene's roots.
struct WalkedNode {
  int node;
  int parent;
};
// Converts the file's node animations for the walked hierarchy; `bindings`
// say which scene instance shows which node. Unusable channels are dropped
// with a warning.
// `channels` false: only the hierarchy and rest pose (what the deformers
// need to pose a static scene), no animation channels.
void load_animations(Context& ctx, AccessorCache& cache, const std::vector<WalkedNode>& walked,
                     std::vector<GltfInstanceBinding> bindings, GltfAnimations& out,
                     bool channels = true);
// Default morph weights of node `n`'s mesh: node.weights, else mesh.weights,
// else zeros; one per morph target (empty without a mesh or targets).
// The lists of `summary` that `tandem info` prints (scenes, animations
// with their lengths, skins, morph targets), from a validated model.
void describe_file_contents(const tinygltf::Model& model, GltfSummary& summary);

std::vector<float> gltf_default_weights(const tinygltf::Model& m, const tinygltf::Node& n);

// --- gltf_skin.cpp ------------------------------------------------------------------
// One node of the walked scene whose mesh deforms (it has a skin, or its
// mesh has morph targets), and the Scene mesh made for it alone.
struct DeformedNode {
  int node;
  uint32_t scene_mesh;
};
// Checks the skin data of every skinned mesh of the file (joint indices in
// range, weights not negative) and builds the skins and deformations of
// `nodes` into `out` (whose hierarchy load_animations has filled).
void load_deformers(Context& ctx, AccessorCache& cache, const std::vector<DeformedNode>& nodes,
                    const std::vector<Mesh>& scene_meshes, GltfAnimations& out);

}  // namespace tandem::gltf
