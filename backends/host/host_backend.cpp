#include "backends/host/host_backend.h"

#include "core/kernel/bvh_traverse.h"
#include "core/render/cpu_tile_loop.h"

namespace tandem {

void HostBackend::sync(const KernelScene& scene, const SceneDelta& /*delta*/) {
  // Nothing to copy: the BVH lives in the KernelScene's own arrays, which
  // AccelStructure has already brought up to date for this delta.
  check_bvh_present(scene, "host backend");
  kd_ = scene.view();
}

BackendStats HostBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
}

}  // namespace tandem
