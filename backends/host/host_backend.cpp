#include "backends/host/host_backend.h"

#include <stdexcept>
#include <string>

#include "core/kernel/bvh_traverse.h"
#include "core/render/cpu_tile_loop.h"

namespace tandem {

namespace {

// The kernel treats a missing BVH as "nothing to hit" (an empty scene), so a
// caller that forgot AccelStructure would silently get a black image; check
// here, once per sync, that every instanced mesh with triangles has a root.
void check_bvh_present(const KernelScene& ks) {
  const bool wide = ks.constants.bvh_layout == kBvhLayoutWide;
  const size_t node_count = wide ? ks.bvh_wide_nodes.size() : ks.bvh_nodes.size();
  const char* layout = wide ? "wide" : "binary";
  auto fail = [&](const std::string& what) {
    throw std::logic_error(std::string("host backend: ") + what + " (" + layout +
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

}  // namespace

void HostBackend::sync(const KernelScene& scene, const SceneDelta& /*delta*/) {
  // Nothing to copy: the BVH lives in the KernelScene's own arrays, which
  // AccelStructure has already brought up to date for this delta.
  check_bvh_present(scene);
  kd_ = scene.view();
}

BackendStats HostBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
}

}  // namespace tandem
