// World-space bounds of a scene, kept up to date edit by edit.
//
// A frame that moves k instances must not pay for the whole scene: the
// cache keeps each mesh's object-space box (recomputed only when that mesh's
// vertices change) and each instance's world box in a binary reduction tree
// over the instances, so after k edits bounds() costs O(k log n) instead of
// a walk over every triangle. Boxes combine by exact min/max, so the result
// equals compute_scene_bounds() on the same scene.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

namespace tandem {

struct Mesh;
struct Instance;

struct SceneBounds {
  glm::vec3 lo{0.0f}, hi{0.0f};
  bool empty = true;
  // Every point that went in was finite (lo and hi alone cannot tell: a
  // min or max with a NaN keeps the other operand).
  bool finite = true;
  void extend(const glm::vec3& p);
  void extend(const SceneBounds& b);
  glm::vec3 center() const { return (lo + hi) * 0.5f; }
  float radius() const;
};

// Object-space box of the vertices the mesh's triangles use.
SceneBounds mesh_object_bounds(const Mesh& mesh);
// Box of positions[0, count); *all_finite says whether every coordinate
// was finite (else the box is not mesh_object_bounds()'s).
SceneBounds vertex_bounds(const glm::vec3* positions, size_t count, bool* all_finite);
// The mesh box's 8 corners under the instance's transform; empty when the
// instance is not drawn (scene_ranges.h: singular, not finite, out of range).
SceneBounds instance_world_bounds(const Instance& instance, const SceneBounds& mesh_bounds);
// The full recomputation (every triangle of every mesh): what the cache
// must always agree with.
SceneBounds compute_scene_bounds(const std::vector<Mesh>& meshes,
                                 const std::vector<Instance>& instances);

class SceneBoundsCache {
 public:
  // Scene mutations, in the order the Scene performs them. An instance's
  // mesh never changes after it was added.
  void mesh_added();
  void instance_added(uint32_t mesh);
  void mesh_changed(uint32_t mesh);
  void instance_changed(uint32_t instance);
  // The box of all of a changed mesh's positions (all finite), from code
  // that read them all anyway: the compiler's vertex copy. bounds() then
  // takes it instead of a pass of its own over the mesh, where every vertex
  // is used by a triangle (so the box is the triangles' box). Forgotten at
  // the mesh's next change.
  void mesh_vertex_bounds(uint32_t mesh, const SceneBounds& all_vertices);
  // Whether the next bounds() reads the mesh's vertices (it is stale and
  // has no box from mesh_vertex_bounds() that it can take).
  // The meshes changed since the last bounds(), each once: what it may read.
  const std::vector<uint32_t>& stale_meshes() const { return stale_meshes_; }
  bool reads_vertices(uint32_t mesh) const {
    return mesh < mesh_stale_.size() && mesh_stale_[mesh] &&
           !(given_[mesh] && vertex_use_[mesh] == kAllUsed);
  }

  // Brings the stale entries up to date and returns the union. `mesh(m)`
  // is asked only for the stale meshes whose box it was not given (and
  // once per mesh whether every vertex is used), so a caller whose meshes
  // are written on demand (posed meshes) passes a lookup that writes one.
  using MeshLookup = std::function<const Mesh&(uint32_t)>;
  SceneBounds bounds(size_t mesh_count, const MeshLookup& mesh,
                     const std::vector<Instance>& instances);
  SceneBounds bounds(const std::vector<Mesh>& meshes, const std::vector<Instance>& instances);
  // A mesh's object-space box as of the last bounds().
  const SceneBounds& mesh_box(uint32_t mesh) const { return mesh_bounds_[mesh]; }

 private:
  void mark_instance(uint32_t instance);
  void regrow_tree(size_t mesh_count, const std::vector<Instance>& instances);

  SceneBounds refresh_mesh(uint32_t mesh, const MeshLookup& mesh_lookup);

  std::vector<SceneBounds> mesh_bounds_;
  // Per mesh: a box from mesh_vertex_bounds() waiting (1) or not (0); and
  // whether every vertex is used by a triangle (kUnknown until the first
  // pass over its triangles; triangles never change after add_mesh).
  enum : uint8_t { kUnknown, kAllUsed, kSomeUnused };
  std::vector<SceneBounds> given_bounds_;
  std::vector<uint8_t> given_, vertex_use_;
  std::vector<std::vector<uint32_t>> mesh_instances_;  // instances of each mesh
  std::vector<uint32_t> instance_mesh_;
  std::vector<uint8_t> mesh_stale_, instance_stale_;
  std::vector<uint32_t> stale_meshes_, stale_instances_;
  // tree_[leaves_ + i] is instance i's world box, tree_[p] the union of
  // tree_[2p] and tree_[2p + 1]; tree_[1] is the scene's box.
  std::vector<SceneBounds> tree_;
  uint32_t leaves_ = 0;
};

}  // namespace tandem
