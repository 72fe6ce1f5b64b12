#include <stdexcept>
#include <string>

#include "core/world/kernel_scene.h"

namespace tandem {

void check_bvh_present(const KernelScene& ks, const char* backend) {
  const bool wide = ks.bvh.layout == kBvhLayoutWide;
  const size_t node_count = wide ? ks.bvh_wide_nodes.size() : ks.bvh_nodes.size();
  const char* layout = wide ? "wide" : "binary";
  auto fail = [&](const std::string& what) {
    throw std::logic_error(
        std::string(backend) + ": " + what + " (" + layout +
        " layout); update the scene through a SceneSync that builds the BVH before sync()");
  };
  bool any_triangles = false;
  for (const KInstance& inst : ks.instances) {
    if (inst.mesh >= ks.meshes.size()) fail("instance refers to a missing mesh");
    const KMesh& mesh = ks.meshes[inst.mesh];
    if (mesh.triangle_count == 0) continue;
    if (inst.mesh >= ks.blas_roots.size()) fail("a mesh has no BLAS root");
    const KBlasRoot& roots = ks.blas_roots[inst.mesh];
    const uint32_t root = wide ? roots.wide_root : roots.bvh_root;
    // kInvalidIndex is legitimate: a mesh whose triangles are all degenerate.
    if (root != kInvalidIndex && root >= node_count) fail("a mesh's BLAS root is out of range");
    // A hidden instance, or one of such a mesh, is out of the TLAS: a scene
    // of nothing else has none.
    any_triangles = any_triangles || (root != kInvalidIndex && !(inst.flags & kInstanceHidden));
  }
  if (!any_triangles) return;
  const uint32_t tlas = wide ? ks.bvh.tlas_wide_root : ks.bvh.tlas_root;
  if (node_count == 0 || tlas >= node_count) fail("the scene has no BVH");
}

}  // namespace tandem
