// glTF node animations: translation / rotation / scale / morph-weight
// channels with LINEAR, STEP and CUBICSPLINE interpolation, and a player that
// poses the scene's instances from the node hierarchy at any time t and
// deforms its skinned and morphing meshes (mesh_deformer.h).
//
// The loader fills GltfAnimations when GltfOptions::animations is set (see
// gltf_loader.h). Animated cameras and lights are not played; a broken
// channel is dropped with a warning rather than failing the file, because
// the static pose is still a correct scene.
//
// Skinned meshes: the instance of a skinned node has the identity transform
// and its vertices are skinned straight into world space with the joints'
// world matrices (palette = world(joint) * inverseBindMatrix), which is the
// glTF rule that the skinned mesh node's own transform is ignored. Morphing
// meshes without a skin keep their node's transform and are morphed in
// their own space.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "core/world/scene.h"
#include "scenes/mesh_deformer.h"

namespace tandem {

enum class GltfInterpolation : uint8_t { kLinear, kStep, kCubicSpline };
enum class GltfAnimatedPath : uint8_t { kTranslation, kRotation, kScale, kWeights };

struct GltfAnimationChannel {
  uint32_t node = 0;  // glTF node index
  GltfAnimatedPath path = GltfAnimatedPath::kTranslation;
  GltfInterpolation interpolation = GltfInterpolation::kLinear;
  std::vector<float> times;  // non-decreasing key times, seconds
  // components() floats per key (3, or 4 for rotation as x, y, z, w); for
  // CUBICSPLINE three groups per key: in-tangent, value, out-tangent.
  std::vector<float> values;
  uint32_t weight_count = 0;  // kWeights: morph targets of the node's mesh
  uint32_t components() const {
    return path == GltfAnimatedPath::kRotation  ? 4
           : path == GltfAnimatedPath::kWeights ? weight_count
                                                : 3;
  }
};

struct GltfAnimation {
  std::string name;
  double duration = 0.0;  // last key time over all channels
  std::vector<GltfAnimationChannel> channels;
};

// A node of the loaded scene's hierarchy with its rest pose.
struct GltfAnimNode {
  int parent = -1;          // glTF node index, -1 for a root
  bool visited = false;     // part of the loaded scene
  bool animated = false;    // it or an ancestor is the target of a channel
  glm::mat4 matrix{1.0f};   // rest local transform when has_matrix
  bool has_matrix = false;  // glTF "matrix" nodes cannot be animated (spec)
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // w, x, y, z (glm order)
  glm::vec3 scale{1.0f};
  // Morph weights of the node's mesh: node.weights, else mesh.weights, else
  // zeros (empty when the mesh has no targets).
  std::vector<float> weights;
};

// Scene instance `instance` is node `node`'s mesh; `local` is the extra
// transform of an EXT_mesh_gpu_instancing entry (identity otherwise).
struct GltfInstanceBinding {
  uint32_t instance = 0;
  uint32_t node = 0;
  glm::mat4 local{1.0f};
  // Skinned: the joints place the vertices, the node's transform is ignored
  // (the instance keeps `local` alone), so node animation leaves it alone.
  bool skinned = false;
};

struct GltfSkin {
  std::vector<uint32_t> joints;         // glTF node per joint
  std::vector<glm::mat4> inverse_bind;  // one per joint (identity when absent)
};

// A Scene mesh that one glTF node deforms (each such node has its own copy
// of the mesh). Palette slots 0..joints-1 are the skin's joints; slot
// `joints` is the node's own world transform, which vertices whose weights
// are all zero follow (they are drawn as an unskinned mesh would be).
struct GltfDeformedMesh {
  uint32_t node = 0;  // glTF node with the mesh (and skin)
  int skin = -1;      // index into GltfAnimations::skins, -1: morph only
  // Shared with the poses the Scene holds (deform_scene_mesh()).
  std::shared_ptr<const MeshDeformation> deformation;
  mutable DeformedPose last;  // an unchanged pose is not deformed again
};

struct GltfAnimations {
  std::vector<GltfAnimNode> nodes;  // indexed by glTF node index
  std::vector<uint32_t> order;      // visited nodes, parents before children
  std::vector<GltfInstanceBinding> instances;
  std::vector<GltfAnimation> animations;
  std::vector<GltfSkin> skins;
  std::vector<GltfDeformedMesh> deformed;
  bool empty() const { return animations.empty(); }
  double duration() const;  // longest animation
};

// Samples one channel at time t (clamped to its key range) into `out`
// (components() floats; rotations normalised).
void sample_gltf_channel(const GltfAnimationChannel& channel, double t, float* out);

// Local poses (TRS and morph weights) of all nodes with every animation at
// time t; each animation loops over its own duration.
std::vector<GltfAnimNode> pose_gltf_local(const GltfAnimations& animations, double t);
// World transforms of those poses (identity for nodes outside the scene).
std::vector<glm::mat4> gltf_world_transforms(const GltfAnimations& animations,
                                             const std::vector<GltfAnimNode>& local);
// Both steps: world transforms at time t.
std::vector<glm::mat4> pose_gltf_nodes(const GltfAnimations& animations, double t);

// Deforms every mesh of `animations.deformed` for the given pose (through
// Scene::edit_mesh_vertices), except those that hold this pose already.
// Returns how many meshes were written.
size_t deform_gltf_meshes(const GltfAnimations& animations, const std::vector<GltfAnimNode>& local,
                          const std::vector<glm::mat4>& world, Scene& scene);

// Writes the transforms of the animated instances for time t into `scene`
// (only those are marked dirty) and deforms the skinned and morphing meshes.
// Returns how many instances were updated.
size_t apply_gltf_animations(const GltfAnimations& animations, double t, Scene& scene);

}  // namespace tandem
