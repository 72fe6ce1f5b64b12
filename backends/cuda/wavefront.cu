// Wavefront path tracing (Laine, Karras & Aila 2013, "Megakernels considered
// harmful"): the path is split into stages run as separate kernels over
// queues, so each kernel is small and its threads do the same kind of work.
//
// What is split today, per batch:
//   generate  camera rays of every pixel sample (same RNG dimensions as
//             render_pixel_sample), plus the bounce-0 alpha key;
//   extend    the camera rays' closest hits with persistent threads
//             (ray_query.cu), writing compacted hit and miss queues;
//   shade     the rest of each path with the shared integrator, first over
//             the miss queue (environment only, cheap, coherent) and then
//             over the hit queue. The integrator is handed a tracer that
//             returns the precomputed bounce-0 hit, so the result is bit for
//             bit the megakernel's.
// Still to split: shade into shade / connect stages with per-bounce
// queues (next extend queue, shadow-ray queue traced by launch_trace_rays
// with any_hit). That needs trace_path in core/kernel/integrator.h factored
// into per-bounce step functions over an explicit path state; until then the
// bounces after the first run megakernel-style inside "shade".
#include <stdexcept>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/integrator.h"

namespace tandem {

namespace {

constexpr uint32_t kWaveThreads = 128;

__global__ void __launch_bounds__(kWaveThreads)
    generate_kernel(const KernelData* __restrict__ kd_global, TileBatch batch, Ray* rays,
                    uint32_t* alpha_keys) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint64_t item = uint64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (item >= batch.items()) return;
  uint32_t x, y, sample;
  batch_item(batch, item, &x, &y, &sample);
  // Mirrors render_pixel_sample; if the two ever disagree, FirstHitTracer
  // notices the different ray and traces it itself (slower, still right).
  const KCamera& cam = kd.constants.camera;
  const PathRng rng = make_path_rng(y * cam.width + x, sample, kd.constants.integrator.seed);
  // Must match render_pixel_sample (integrator.h) draw for draw.
  const Vec2 jitter = rng_2d(rng, kDimPixelJitter), lens = rng_2d(rng, kDimLens);
  rays[item] = generate_camera_ray(cam, float(x) + jitter.x, float(y) + jitter.y, lens.x, lens.y);
  alpha_keys[item] = rng_bits(rng, bounce_dimension(0, kBounceAlpha));
}

TANDEM_HD bool same_ray(const Ray& a, const Ray& b) {
  return float_as_uint(a.origin.x) == float_as_uint(b.origin.x) &&
         float_as_uint(a.origin.y) == float_as_uint(b.origin.y) &&
         float_as_uint(a.origin.z) == float_as_uint(b.origin.z) &&
         float_as_uint(a.dir.x) == float_as_uint(b.dir.x) &&
         float_as_uint(a.dir.y) == float_as_uint(b.dir.y) &&
         float_as_uint(a.dir.z) == float_as_uint(b.dir.z) &&
         float_as_uint(a.tmin) == float_as_uint(b.tmin) &&
         float_as_uint(a.tmax) == float_as_uint(b.tmax);
}

// Answers the path's first closest-hit query from the extend stage and every
// later query (and all occlusion queries) by traversal.
struct FirstHitTracer {
  BvhTracer inner;
  Ray first_ray;
  uint32_t first_key;
  Hit first_hit;
  mutable bool used;
  TANDEM_HD Hit intersect(const Ray& ray, uint32_t alpha_key) const {
    if (!used) {
      used = true;
      if (alpha_key == first_key && same_ray(ray, first_ray)) return first_hit;
    }
    return inner.intersect(ray, alpha_key);
  }
  TANDEM_HD bool occluded(const Ray& ray, uint32_t alpha_key) const {
    return inner.occluded(ray, alpha_key);
  }
};

__global__ void __launch_bounds__(kWaveThreads)
    shade_kernel(const KernelData* __restrict__ kd_global, TileBatch batch,
                 const uint32_t* __restrict__ queue, const uint32_t* __restrict__ queue_count,
                 const Ray* __restrict__ rays, const uint32_t* __restrict__ alpha_keys,
                 const Hit* __restrict__ hits, Vec3* radiance, unsigned long long* ray_count) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t slot = blockIdx.x * blockDim.x + threadIdx.x;
  uint32_t rays_traced = 0;
  if (slot < *queue_count) {
    const uint32_t item = queue[slot];
    uint32_t x, y, sample;
    batch_item(batch, item, &x, &y, &sample);
    const FirstHitTracer tracer{BvhTracer{&kd}, rays[item], alpha_keys[item], hits[item], false};
    radiance[item] = render_pixel_sample(kd, tracer, x, y, sample, &rays_traced);
  }
  add_ray_count(rays_traced, ray_count);
}

}  // namespace

void launch_wavefront(const KernelData* kd, const TileBatch& batch, const WavefrontScratch& scratch,
                      Vec3* radiance, unsigned long long* ray_count, cudaStream_t stream) {
  const uint64_t n = batch.items();
  if (n == 0) return;
  if (n > scratch.capacity)
    throw std::logic_error("launch_wavefront: scratch holds fewer items than the batch");
  const uint32_t blocks = blocks_for(n, kWaveThreads);
  // counters: [0] the extend stage's work counter, [1] hits, [2] misses.
  TANDEM_CUDA_CHECK(cudaMemsetAsync(scratch.counters, 0, 4 * sizeof(uint32_t), stream));
  generate_kernel<<<blocks, kWaveThreads, 0, stream>>>(kd, batch, scratch.rays, scratch.alpha_keys);
  TANDEM_CUDA_CHECK_LAUNCH("generate_kernel");
  uint32_t* hit_queue = scratch.queues;
  uint32_t* miss_queue = scratch.queues + n;
  launch_trace_rays(kd, scratch.rays, scratch.alpha_keys, uint32_t(n), false, scratch.hits,
                    &scratch.counters[0], hit_queue, miss_queue, &scratch.counters[1], stream);
  // The queue lengths stay on the device: the grids cover every item and
  // threads past the length exit at once, which avoids a host round trip.
  shade_kernel<<<blocks, kWaveThreads, 0, stream>>>(kd, batch, miss_queue, &scratch.counters[2],
                                                    scratch.rays, scratch.alpha_keys, scratch.hits,
                                                    radiance, ray_count);
  TANDEM_CUDA_CHECK_LAUNCH("shade_kernel (misses)");
  shade_kernel<<<blocks, kWaveThreads, 0, stream>>>(kd, batch, hit_queue, &scratch.counters[1],
                                                    scratch.rays, scratch.alpha_keys, scratch.hits,
                                                    radiance, ray_count);
  TANDEM_CUDA_CHECK_LAUNCH("shade_kernel (hits)");
}

}  // namespace tandem
