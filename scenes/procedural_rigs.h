// Skinned meshes built in code, so built-in scenes deform without any file:
//  - the walker: a box-limbed figure (7 joints: pelvis, thighs, shins,
//    arms) with a walk cycle along a circle; the arena has a few of them;
//  - the skinned grid (builtin:skinned-grid): a sheet of about 1 M vertices
//    on a chain of 8 joints (4 influences per vertex, cubic B-spline
//    weights) that waves, for `bench --deform`.
//
// The rigs are a pure function of their parameters, so a player finds the
// meshes in any copy of a scene by name ("rig.walker.<i>", "rig.skinned-grid")
// and rebuilds the deformation data from code rather than carrying it with
// the Scene.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/world/scene.h"
#include "scenes/mesh_deformer.h"

namespace tandem {

struct ProceduralRig {
  Mesh mesh;                    // bind pose (the walker stands at the origin facing +z)
  MeshDeformation deformation;  // .mesh still to be set to the Scene mesh index
};

// A walker's path: a circle of `radius` around `center` walked at `speed`
// (m/s, negative: clockwise) from angle `angle`; the walk cycle starts at
// `cycle_phase` (radians). `scale` sizes the figure (1: 1.77 m tall).
struct WalkerPath {
  glm::vec3 center{0.0f};
  float radius = 2.0f, speed = 0.8f, angle = 0.0f, cycle_phase = 0.0f, scale = 1.0f;
};
inline constexpr uint32_t kWalkerJoints = 7;

ProceduralRig make_walker_rig(uint32_t material);
// The walker's palette (kWalkerJoints entries) at time t.
void walker_palette(double t, const WalkerPath& path, JointMatrix* out);
// The walkers of builtin:arena; walker i is the mesh "rig.walker.<i>".
const std::vector<WalkerPath>& arena_walker_paths();

inline constexpr uint32_t kGridJoints = 8;
// A `resolution` x `resolution` vertex sheet, 10 m square, in the xz plane.
ProceduralRig make_skinned_grid_rig(uint32_t resolution, uint32_t material);
inline constexpr uint32_t kSkinnedGridResolution = 1000;  // builtin:skinned-grid: 1 M vertices
void skinned_grid_palette(double t, JointMatrix* out);
Scene make_skinned_grid_scene(uint32_t resolution = kSkinnedGridResolution);

// Poses the procedural rigs found in a scene.
class ProceduralRigPlayer {
 public:
  explicit ProceduralRigPlayer(const Scene& scene);
  bool empty() const { return rigs_.empty(); }
  size_t rig_count() const { return rigs_.size(); }
  size_t vertex_count() const;
  // Poses every rig's mesh for time t (marking those meshes dirty;
  // deform_scene_mesh()).
  void pose(double t, Scene& scene) const;

 private:
  struct Rig {
    // Shared with the poses the Scene holds (deform_scene_mesh()).
    std::shared_ptr<const MeshDeformation> deformation;
    int walker = -1;            // index into arena_walker_paths(), -1: the grid
    mutable DeformedPose last;  // an unchanged pose is not deformed again
  };
  std::vector<Rig> rigs_;
};

}  // namespace tandem
