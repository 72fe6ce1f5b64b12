// Closest-hit or occlusion queries for an array of rays over Tandem's BVH
// with persistent threads: the traversal of the wavefront's extend and
// connect stages, for the tests that compare GPU hits with Embree ray by
// ray and for bench --gpu's ray figures. Includes only the traversal
// headers, not the integrator, so it compiles quickly.
#include "backends/cuda/device_exec.h"
#include "core/kernel/bvh_traverse.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

template <class Exec>
TANDEM_DEVICE_FN void TraceRays::run(Exec& ex, const Args& a) {
  const KernelData& kd = load_kernel_data(ex, a.kd);
  persistent_loop(ex, a.n, a.work_counter, [&](uint32_t i) {
    a.hits[i] = bvh_trace(kd, a.rays[i], a.alpha_keys ? a.alpha_keys[i] : 0u, kd.bvh.layout,
                          a.any_hit != 0);
  });
}

TANDEM_KERNEL_END
}  // namespace tandem

TANDEM_KERNEL_REGISTRY(ray_query) {
  register_kernels<TraceRays>(table);
}
