// The CPU backend's Embree traversal (CpuTraversal::kEmbree,
// backends/cpu/cpu_backend.h): the Embree 3 scene it keeps in step with the
// KernelScene, and the kernel Tracers that query it.
//
// One Embree BLAS (RTCScene) per mesh, one instance geometry per scene
// instance in a top-level scene whose geometry IDs equal instance indices.
// Vertex and index buffers are shared with KernelScene (no copies), and alpha
// testing runs the kernel's alpha_test_opaque from an intersection filter.
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

 private:
  void release_scenes();
  void build_all(const KernelScene& scene);

  RTCDevice device_ = nullptr;
  RTCScene top_ = nullptr;
  std::vector<RTCScene> blas_;
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
};

}  // namespace tandem
