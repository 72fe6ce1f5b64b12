// The CPU backend's Embree traversal (CpuTraversal::kEmbree,
// backends/cpu/cpu_backend.h): the Embree 3 scene it keeps in step with the
// KernelScene, and the kernel Tracers that query it.
//
// Two layouts. Two-level: one Embree BLAS (RTCScene) per mesh, one instance
// geometry per scene instance in a top-level scene whose geometry IDs equal
// instance indices. Flat: when no mesh is instanced more than once, every
// identity instance is its mesh's triangle geometry directly in the top-level
// scene (again with its instance index as geometry ID); other instances stay
// instances of their BLAS. That saves the instance level of every query that
// hits an identity instance (the top-level traversal and the ray's transform
// into the mesh: about a quarter of Embree's instructions on the Cornell
// box) and gives the same hits bit for bit (transforming by the identity
// changes no value), so a frame never depends on the layout it was traced
// in. The flat layout is used until the scene first moves an instance or
// deforms a mesh; from then on the two-level layout refits cheaply.
// Vertex and index buffers are shared with KernelScene (no copies), and
// alpha testing runs the kernel's alpha_test_opaque from an intersection
// filter.
#pragma once

#include <embree3/rtcore.h>

#include <vector>

#include "core/kernel/kernel_data.h"
#include "core/world/kernel_scene.h"

namespace tandem {

// An Embree device with the BLAS and the top-level scene of one KernelScene.
class EmbreeScene {
 public:
  // Throws std::runtime_error when Embree cannot create a device.
  EmbreeScene();
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Brings the Embree scene up to date with `scene` for `delta`: a rebuild,
  // or BLAS refits and instance transform updates.
  void sync(const KernelScene& scene, const SceneDelta& delta);
  // Null before the first sync.
  RTCScene top_level() const { return top_; }
  // Whether the scene is one-level (see above).
  bool flat() const { return flat_; }
  // Never flatten (tests compare the two layouts).
  void disallow_flat() { dynamic_ = true; }
  // Instances the last sync() committed again without a rebuild.
  uint32_t last_instance_commits() const { return last_instance_commits_; }

 private:
  void release_scenes();
  void build_all(const KernelScene& scene);
  void build_two_level(const KernelScene& scene);
  void build_flat(const KernelScene& scene);
  RTCScene build_blas(const KernelScene& scene, uint32_t mesh);
  void attach_mesh(RTCScene target, const KernelScene& scene, uint32_t mesh, unsigned id);
  void attach_instance(const KInstance& inst, unsigned id);

  RTCDevice device_ = nullptr;
  RTCScene top_ = nullptr;
  std::vector<RTCScene> blas_;  // null for the meshes of a flat scene's identity instances
  bool flat_ = false;
  bool dynamic_ = false;  // an instance has moved or a mesh deformed: stay two-level
  std::vector<std::vector<uint32_t>> mesh_instances_;  // two-level: the instances of each mesh
  uint32_t last_instance_commits_ = 0;
};

// A triangle geometry over mesh `mesh` of `ks`, sharing its vertex and index
// arrays (no copies), with the given build quality; not yet committed, so
// callers can add filters first. Used by the backend and by the builder
// benchmark, which must build exactly the same geometry.
RTCGeometry new_mesh_geometry(RTCDevice device, const KernelScene& ks, uint32_t mesh,
                              RTCBuildQuality quality);

// The kernel Tracer for Embree, usable from any thread.
struct EmbreeTracer {
  RTCScene scene;
  const KernelData* kd;
  Hit intersect(const Ray& ray, uint32_t alpha_key) const;
  bool occluded(const Ray& ray, uint32_t alpha_key) const;
};

// The same with packets of up to 16 rays (rtcIntersect16 / rtcOccluded16),
// for the wavefront pipeline on the CPU (backends/cpu_loops/cpu_wavefront.h). Each
// ray carries its own alpha key (in the ray id, which the filter reads).
struct EmbreePacketTracer : EmbreeTracer {
  void intersect_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n, Hit* hits) const;
  void occluded_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                       bool* occluded) const;
  // Closest hits of n coherent rays (the CPU tile loop's camera rays, a few
  // pixels' samples) in packets of 8 (rtcIntersect8) with Embree's coherent
  // flag: the width that measured fastest for them (callgrind on the Cornell
  // box: camera rays 56% fewer instructions than with rtcIntersect1; 16-wide
  // packets were slower than single rays on this round's Xeon). The same
  // hits as intersect() on the scenes measured (bit-identical images).
  void intersect_coherent(const Ray* rays, const uint32_t* alpha_keys, uint32_t n, Hit* hits) const;
};

}  // namespace tandem
