// The megakernel: one thread per pixel sample runs the whole path with the
// shared integrator (core/kernel/integrator.h) over Tandem's BVH, in the
// form with one traversal call site (render_pixel_sample_one_trace_site).
#include "backends/cuda/device_exec.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/integrator.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

template <class Exec>
TANDEM_DEVICE_FN void Megakernel::run(Exec& ex, const Args& a) {
  const KernelData& kd = load_kernel_data(ex, a.kd);
  const uint64_t item = ex.global_x();
  uint32_t rays = 0;
  if (item < a.batch.items()) {
    uint32_t x, y, sample;
    batch_item(a.batch, item, &x, &y, &sample);
    a.radiance[item] = render_pixel_sample_one_trace_site(kd, BvhTracer{&kd}, x, y, sample, &rays);
  }
  add_ray_count(ex, rays, a.ray_count);
}

TANDEM_KERNEL_END
}  // namespace tandem

TANDEM_KERNEL_REGISTRY(megakernel) {
  register_kernels<Megakernel>(table);
}
