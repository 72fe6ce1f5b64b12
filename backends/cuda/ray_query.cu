// The "extend" stage: closest-hit or occlusion queries for an array of rays
// over Tandem's BVH. Used by the wavefront renderer and by tests that compare
// GPU hits with Embree ray by ray. Includes only the traversal headers, not
// the integrator, so it compiles quickly.
#include <mutex>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "core/kernel/bvh_traverse.h"

namespace tandem {

namespace {

constexpr uint32_t kTraceThreads = 128;
// Resident blocks per SM, as for the wavefront's extend and connect
// (wavefront.cu): 64 registers, 50% occupancy on sm_90, and bench --gpu's ray
// figures measure the traversal those kernels run.
constexpr uint32_t kTraceBlocksPerSm = 8;

// Persistent threads (Aila & Laine 2009, "Understanding the efficiency of
// ray traversal on GPUs"): just enough warps to fill the GPU, each fetching
// 32 rays at a time from a global counter, so warps that drew short rays
// take more work instead of idling until the slowest warp of a block ends.
__global__ void __launch_bounds__(kTraceThreads, kTraceBlocksPerSm)
    trace_rays_kernel(const KernelData* __restrict__ kd_global, const Ray* __restrict__ rays,
                      const uint32_t* __restrict__ alpha_keys, uint32_t n, bool any_hit, Hit* hits,
                      uint32_t* work_counter, uint32_t* hit_queue, uint32_t* miss_queue,
                      uint32_t* queue_counts) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t lane = threadIdx.x & 31u;
  for (;;) {
    uint32_t base = 0;
    if (lane == 0) base = atomicAdd(work_counter, 32u);
    base = __shfl_sync(0xffffffffu, base, 0);
    if (base >= n) break;  // uniform across the warp
    const uint32_t i = base + lane;
    const bool valid = i < n;
    bool is_hit = false;
    if (valid) {
      const Hit h = bvh_trace(kd, rays[i], alpha_keys ? alpha_keys[i] : 0u, kd.bvh.layout, any_hit);
      hits[i] = h;
      is_hit = hit_valid(h);
    }
    if (hit_queue) {
      // Warp-aggregated append: one atomic per queue per warp, and the
      // queues come out compacted (no holes for the other kind).
      const uint32_t hit_mask = __ballot_sync(0xffffffffu, valid && is_hit);
      const uint32_t miss_mask = __ballot_sync(0xffffffffu, valid && !is_hit);
      uint32_t hit_base = 0, miss_base = 0;
      if (lane == 0) {
        if (hit_mask) hit_base = atomicAdd(&queue_counts[0], uint32_t(__popc(hit_mask)));
        if (miss_mask) miss_base = atomicAdd(&queue_counts[1], uint32_t(__popc(miss_mask)));
      }
      hit_base = __shfl_sync(0xffffffffu, hit_base, 0);
      miss_base = __shfl_sync(0xffffffffu, miss_base, 0);
      const uint32_t below = (1u << lane) - 1u;
      if (valid && is_hit) hit_queue[hit_base + __popc(hit_mask & below)] = i;
      if (valid && !is_hit) miss_queue[miss_base + __popc(miss_mask & below)] = i;
    }
  }
}

// Enough resident blocks to fill every SM once; computed once per process
// (the backend uses one device).
uint32_t persistent_blocks() {
  static std::once_flag once;
  static uint32_t blocks = 0;
  std::call_once(once, [] {
    int device = 0, sms = 0, per_sm = 0;
    TANDEM_CUDA_CHECK(cudaGetDevice(&device));
    TANDEM_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    TANDEM_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, trace_rays_kernel,
                                                                    kTraceThreads, 0));
    blocks = uint32_t(std::max(1, sms * std::max(per_sm, 1)));
  });
  return blocks;
}

}  // namespace

void launch_trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* alpha_keys,
                       uint32_t n, bool any_hit, Hit* hits, uint32_t* work_counter,
                       uint32_t* hit_queue, uint32_t* miss_queue, uint32_t* queue_counts,
                       cudaStream_t stream) {
  if (n == 0) return;
  const uint32_t blocks = std::min(persistent_blocks(), blocks_for(n, kTraceThreads));
  trace_rays_kernel<<<blocks, kTraceThreads, 0, stream>>>(
      kd, rays, alpha_keys, n, any_hit, hits, work_counter, hit_queue, miss_queue, queue_counts);
  TANDEM_CUDA_CHECK_LAUNCH("trace_rays_kernel");
}

}  // namespace tandem
