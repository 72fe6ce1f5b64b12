// CPU mesh deformation: morph targets, then linear blend skinning (the
// order glTF prescribes), evaluated every frame. A deforming mesh is handed
// to the Scene as a pose (Scene::pose_mesh, core/world/mesh_pose.h): the
// compiler writes it straight into the kernel arrays the renderers read,
// and the Scene's own copy is written only if something reads it. Either
// way the compiler sees a kDirtyVertices mesh and the BVH refits it
// (topology never changes).
//
// A MeshDeformation holds what one deforming Scene mesh needs: its base
// (bind-pose, unmorphed) vertices, per-vertex joint influences and the
// morph-target deltas. Where the joint matrices and the morph weights come
// from (glTF node animations, a procedural walk cycle) is the caller's
// business; deform_mesh only takes a palette and a weight list.
//
// Normals and tangents are skinned with the same blended matrix as the
// position: tangents by its upper 3x3, normals by the cofactor of that 3x3
// (the inverse transpose up to a positive scale, with the sign of the
// determinant restored), both then normalised. So non-uniformly scaled joints
// still give normals perpendicular to the skinned surface. A normal or
// tangent the blend collapses to zero keeps its unskinned direction rather
// than becoming NaN.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/world/scene.h"

namespace tandem {

// One joint's skinning matrix, the top three rows of an affine 4x4 matrix
// stored row by row (m[4 * r + c]): 12 floats, so that blending four of
// them per vertex is a run of multiply-adds the compiler vectorises.
struct JointMatrix {
  float m[12];
};
JointMatrix joint_matrix(const glm::mat4& affine);
glm::mat4 to_mat4(const JointMatrix& j);

struct MeshDeformation {
  uint32_t mesh = 0;  // the Scene mesh it writes
  // Base vertices: bind pose, before morphing. normals/tangents are empty
  // when the mesh has none (then none are written).
  std::vector<glm::vec3> base_positions;
  std::vector<glm::vec3> base_normals;
  std::vector<glm::vec4> base_tangents;

  // Skinning: `influences` (joint, weight) pairs per vertex, vertex-major;
  // joints are palette slots (< palette_size), weights of a vertex sum to 1.
  // influences == 0: not skinned, positions stay in the mesh's own space.
  uint32_t palette_size = 0;
  uint32_t influences = 0;
  std::vector<uint16_t> joints;
  std::vector<float> weights;

  // Morph targets, target-major (delta of target k for vertex v at
  // [k * vertices + v]); an attribute's array is empty when no target of
  // the mesh moves it.
  uint32_t targets = 0;
  std::vector<glm::vec3> position_deltas, normal_deltas, tangent_deltas;

  size_t vertex_count() const { return base_positions.size(); }
  bool skinned() const { return influences > 0; }
};

// Whether the skinning's hot loop runs its AVX2 copy (the same bits as the
// baseline's): where the CPU has AVX2, unless TANDEM_HOST_ISA=sse2; tests
// switch it to compare both.
struct DeformIsaChoice {
  bool avx2 = false;
};
extern DeformIsaChoice deform_isa;

// Writes the deformed vertices of `d` into `out` (positions, and normals and
// tangents when the base has them), in parallel over blocks of vertices.
// `palette` has d.palette_size entries when d is skinned (else unused);
// `morph_weights` has d.targets entries (null: all zero). `out` must have
// d.vertex_count() vertices.
void deform_mesh(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh& out);

// What deform_scene_mesh() last wrote into its Scene mesh. A pose equal to
// it (a paused or held clip, a rig at rest, the viewer redrawing one time)
// is then neither skinned again nor, the mesh staying clean, refit.
struct DeformedPose {
  std::vector<JointMatrix> palette;  // empty: not skinned
  std::vector<float> morph_weights;  // empty: no weights given
  uint64_t vertex_version = 0;       // Scene::mesh_vertex_version() after the write; 0: none
};

// Poses the Scene mesh d->mesh (Scene::pose_mesh: the compiler writes the
// pose into the kernel arrays, the Scene's copy waits until read), unless
// the mesh still holds (its vertex version is last's) the same pose (bit
// for bit the same palette and weights); then it is left alone, not marked
// dirty. Returns whether it posed; updates last. The pose keeps `d` alive.
bool deform_scene_mesh(const std::shared_ptr<const MeshDeformation>& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, DeformedPose& last);
// The same, written into the Scene mesh at once through
// Scene::edit_mesh_vertices, for a deformation that is not shared.
bool deform_scene_mesh(const MeshDeformation& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, DeformedPose& last);

}  // namespace tandem
