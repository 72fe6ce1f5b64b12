// glTF node animations: translation / rotation / scale channels with LINEAR,
// STEP and CUBICSPLINE interpolation, and a player that poses the scene's
// instances from the node hierarchy at any time t.
//
// The loader fills GltfAnimations when GltfOptions::animations is set (see
// gltf_loader.h). Morph-target weights, skins, and animated cameras or
// lights are not played; a broken channel is
// dropped with a warning rather than failing the file, because the static
// pose is still a correct scene.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "core/world/scene.h"

namespace tandem {

enum class GltfInterpolation : uint8_t { kLinear, kStep, kCubicSpline };
enum class GltfAnimatedPath : uint8_t { kTranslation, kRotation, kScale };

struct GltfAnimationChannel {
  uint32_t node = 0;  // glTF node index
  GltfAnimatedPath path = GltfAnimatedPath::kTranslation;
  GltfInterpolation interpolation = GltfInterpolation::kLinear;
  std::vector<float> times;  // non-decreasing key times, seconds
  // components() floats per key (3, or 4 for rotation as x, y, z, w); for
  // CUBICSPLINE three groups per key: in-tangent, value, out-tangent.
  std::vector<float> values;
  uint32_t components() const { return path == GltfAnimatedPath::kRotation ? 4 : 3; }
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
};

// Scene instance `instance` is node `node`'s mesh; `local` is the extra
// transform of an EXT_mesh_gpu_instancing entry (identity otherwise).
struct GltfInstanceBinding {
  uint32_t instance = 0;
  uint32_t node = 0;
  glm::mat4 local{1.0f};
};

struct GltfAnimations {
  std::vector<GltfAnimNode> nodes;  // indexed by glTF node index
  std::vector<uint32_t> order;      // visited nodes, parents before children
  std::vector<GltfInstanceBinding> instances;
  std::vector<GltfAnimation> animations;
  bool empty() const { return animations.empty(); }
  double duration() const;  // longest animation
};

// Samples one channel at time t (clamped to its key range) into `out`
// (components() floats; rotations normalised).
void sample_gltf_channel(const GltfAnimationChannel& channel, double t, float* out);

// World transforms of all nodes (identity for nodes outside the scene) with
// every animation at time t; each animation loops over its own duration.
std::vector<glm::mat4> pose_gltf_nodes(const GltfAnimations& animations, double t);

// Writes the transforms of the animated instances for time t into `scene`
// (only those are marked dirty). Returns how many instances were updated.
size_t apply_gltf_animations(const GltfAnimations& animations, double t, Scene& scene);

}  // namespace tandem
