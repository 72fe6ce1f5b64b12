#include <stdexcept>
#include <string>

#include "core/scene/kernel_scene.h"

namespace tandem {

void check_bvh_present(const KernelScene& ks, const char* backend) {
  const bool wide = ks.constants.bvh_layout == kBvhLayoutWide;
  const size_t node_count = wide ? ks.bvh_wide_nodes.size() : ks.bvh_nodes.size();
  const char* layout = wide ? "wide" : "binary";
  auto fail = [&](const std::string& what) {
    throw std::logic_error(std::string(backend) + ": " + what + " (" + layout +
                           " layout); run AccelStructure::update_and_mark() before sync()");
  };
  bool any_triangles = false;
  for (const KInstance& inst : ks.instances) {
    if (inst.mesh >= ks.meshes.size()) fail("instance refers to a missing mesh");
    const KMesh& mesh = ks.meshes[inst.mesh];
    if (mesh.triangle_count == 0) continue;
    any_triangles = true;
    const uint32_t root = wide ? mesh.wide_root : mesh.bvh_root;
    // kInvalidIndex is legitimate: a mesh whose triangles are all degenerate.
    if (root != kInvalidIndex && root >= node_count) fail("a mesh's BLAS root is out of range");
  }
  if (!any_triangles) return;
  const uint32_t tlas = wide ? ks.constants.tlas_wide_root : ks.constants.tlas_root;
  if (node_count == 0 || tlas >= node_count) fail("the scene has no BVH");
}

}  // namespace tandem
