// A deforming mesh's vertices given as a pose (Scene::pose_mesh) rather
// than written: a deformation of fixed base vertices with one set of joint
// matrices and morph weights (scenes/mesh_deformer.h), or the vertices an
// embedding game computed (api/), which can be written again, bit for bit,
// as often as it is asked for.
//
// Why a pose and not vertices: a frame loop that skins a million vertices
// needs them once, in the compiled arrays the renderers read. Written into
// the Scene first, they would be written twice and read a third time by the
// compiler's copy. Held as a pose, the Scene carries no vertex data until
// something reads its mesh, and the compiler writes the pose straight into
// the kernel arrays (taking the positions' box as it goes), the one place
// anything is written on the way to the devices.
#pragma once

#include <cstddef>

namespace tandem {

struct Mesh;
struct SceneBounds;
struct Vec2;  // core/kernel/math.h
struct Vec3;
struct Vec4;

// Where a compiled mesh's vertex attributes lie in the kernel arrays.
// normals/tangents/uv0 are null where the compiled mesh has none.
struct MeshVertexTarget {
  Vec3* positions = nullptr;
  Vec3* normals = nullptr;
  Vec4* tangents = nullptr;
  Vec2* uv0 = nullptr;
  size_t vertex_count = 0;
};

// Host-side interface: the deformer (scenes/) implements it; core/world
// only asks it for vertices.
class MeshPose {
 public:
  virtual ~MeshPose() = default;
  // How many vertices the pose writes (the mesh's vertex count).
  virtual size_t vertex_count() const = 0;
  // The posed attributes (positions, and those of normals, tangents and
  // uv0 the pose sets) into the Scene's mesh; others are left as they are.
  virtual void write(Mesh& out) const = 0;
  // The same vertices, converted as the compiler converts a Mesh, into
  // `target` (the attributes it has); their box into `box`. Returns false
  // when `target` does not fit the pose or a position is not finite (the
  // compiler then copies the Scene's realised mesh instead).
  virtual bool write(const MeshVertexTarget& target, SceneBounds* box) const = 0;
};

}  // namespace tandem
