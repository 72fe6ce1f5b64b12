// The megakernel: one thread per pixel sample runs the whole path with the
// shared integrator (core/kernel/integrator.h) over Tandem's BVH, exactly the
// code the host backend runs on the CPU.
#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/integrator.h"

namespace tandem {

namespace {

// 128 threads: the integrator needs many registers, and small blocks keep
// the tail of a batch short.
constexpr uint32_t kMegakernelThreads = 128;

__global__ void __launch_bounds__(kMegakernelThreads)
    megakernel(const KernelData* __restrict__ kd_global, TileBatch batch,
               Vec3* __restrict__ radiance, unsigned long long* ray_count) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint64_t item = uint64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  uint32_t rays = 0;
  if (item < batch.items()) {
    uint32_t x, y, sample;
    batch_item(batch, item, &x, &y, &sample);
    radiance[item] = render_pixel_sample(kd, BvhTracer{&kd}, x, y, sample, &rays);
  }
  add_ray_count(rays, ray_count);
}

}  // namespace

void launch_megakernel(const KernelData* kd, const TileBatch& batch, Vec3* radiance,
                       unsigned long long* ray_count, cudaStream_t stream) {
  if (batch.items() == 0) return;
  megakernel<<<blocks_for(batch.items(), kMegakernelThreads), kMegakernelThreads, 0, stream>>>(
      kd, batch, radiance, ray_count);
  TANDEM_CUDA_CHECK_LAUNCH("megakernel");
}

}  // namespace tandem
