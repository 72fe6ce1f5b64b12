// The wavefront path tracer on the GPU: each stage of core/kernel/wavefront.h
// is one kernel over its queue, in the order the CPU driver
// (backends/cpu_loops/cpu_wavefront.h) runs them. extend and connect trace with
// persistent threads (Aila & Laine 2009: just enough warps to fill the GPU,
// each fetching 32 queue entries at a time, so warps that drew short rays
// take more work instead of idling); shade_miss and shade_hit cover the slots
// and exit past their queue's length, which stays in device memory. The host
// reads one counter every few rounds to learn when the batch is done.
#include <algorithm>
#include <mutex>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/wavefront.h"

namespace tandem {

namespace {

constexpr uint32_t kWaveThreads = 128;
// Rounds between two reads of the queue counter by the host: the kernels of
// rounds after the last path ended exit at once, a read costs a round trip.
constexpr uint32_t kRoundsPerCheck = 4;
// Resident blocks per SM the two traversal kernels are compiled for: 8 x 128
// threads is 50% occupancy on sm_90 and caps them at 64 registers, which the
// single-loop traversal (bvh_traverse.h) fits without spilling. Traversal is
// bound by memory latency, which more resident warps hide.
constexpr uint32_t kTraceBlocksPerSm = 8;
// And for shade_hit, the BSDF's kernel: left to itself ptxas aims at 5
// blocks (96 registers) and spills 16 / 24 B since the clear coat and sheen
// layers; 4 blocks (25% occupancy) give it the 104 registers it needs.
constexpr uint32_t kShadeBlocksPerSm = 4;

__global__ void __launch_bounds__(kWaveThreads)
    wave_fill_kernel(const KernelData* __restrict__ kd_global, TileBatch batch, WavefrontArrays w) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t slot = blockIdx.x * blockDim.x + threadIdx.x;
  if (slot < w.slots) wavefront_regenerate(kd, batch, w, kWavefrontFillRound, slot);
}

__global__ void wave_begin_round_kernel(WavefrontArrays w) {
  wavefront_begin_round(w);
}

// Persistent threads over the queue of length counters[length], taking
// work from counters[taken].
template <class F>
__device__ __forceinline__ void persistent_loop(const WavefrontArrays& w, uint32_t length,
                                                uint32_t taken, const F& f) {
  const uint32_t lane = threadIdx.x & 31u;
  const uint32_t n = w.counters[length];
  for (;;) {
    uint32_t base = 0;
    if (lane == 0) base = atomicAdd(&w.counters[taken], 32u);
    base = __shfl_sync(0xffffffffu, base, 0);
    if (base >= n) break;  // uniform across the warp
    if (base + lane < n) f(base + lane);
  }
}

__global__ void __launch_bounds__(kWaveThreads, kTraceBlocksPerSm)
    wave_extend_kernel(const KernelData* __restrict__ kd_global, WavefrontArrays w,
                       uint32_t round) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const BvhTracer tracer{&kd};
  persistent_loop(w, kWaveExtend, kWaveExtendTaken,
                  [&](uint32_t i) { wavefront_extend(tracer, w, round, i); });
}

__global__ void __launch_bounds__(kWaveThreads)
    wave_shade_miss_kernel(const KernelData* __restrict__ kd_global, TileBatch batch,
                           WavefrontArrays w, uint32_t round, Vec3* radiance) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < w.counters[kWaveMiss]) wavefront_shade_miss(kd, batch, w, round, i, radiance);
}

__global__ void __launch_bounds__(kWaveThreads, kShadeBlocksPerSm)
    wave_shade_hit_kernel(const KernelData* __restrict__ kd_global, TileBatch batch,
                          WavefrontArrays w, uint32_t round, Vec3* radiance) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < w.counters[kWaveHit]) wavefront_shade_hit(kd, batch, w, round, i, radiance);
}

__global__ void __launch_bounds__(kWaveThreads, kTraceBlocksPerSm)
    wave_connect_kernel(const KernelData* __restrict__ kd_global, WavefrontArrays w,
                        uint32_t round) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const BvhTracer tracer{&kd};
  persistent_loop(w, kWaveShadow, kWaveConnectTaken,
                  [&](uint32_t i) { wavefront_connect(tracer, w, round, i); });
}

__global__ void __launch_bounds__(kWaveThreads)
    wave_retire_kernel(const KernelData* __restrict__ kd_global, TileBatch batch, WavefrontArrays w,
                       uint32_t round, Vec3* radiance) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < w.counters[kWaveRetire]) wavefront_retire_ended(kd, batch, w, round, i, radiance);
}

__global__ void wave_count_rays_kernel(WavefrontArrays w, unsigned long long* ray_count) {
  atomicAdd(ray_count, static_cast<unsigned long long>(w.counters[kWaveRays]));
}

// Enough resident blocks of `kernel` to fill every SM once.
template <class Kernel>
uint32_t resident_blocks(Kernel kernel) {
  int device = 0, sms = 0, per_sm = 0;
  TANDEM_CUDA_CHECK(cudaGetDevice(&device));
  TANDEM_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
  TANDEM_CUDA_CHECK(
      cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kernel, kWaveThreads, 0));
  return uint32_t(std::max(1, sms * std::max(per_sm, 1)));
}

}  // namespace

void launch_wavefront(const KernelData* kd, const TileBatch& batch, const WavefrontArrays& wave,
                      Vec3* radiance, unsigned long long* ray_count, uint32_t* host_counter,
                      cudaStream_t stream) {
  const uint64_t items = batch.items();
  if (items == 0) return;
  WavefrontArrays w = wave;
  w.slots = uint32_t(std::min<uint64_t>(items, wave.slots));
  static std::once_flag once;
  static uint32_t extend_blocks = 0, connect_blocks = 0;
  std::call_once(once, [] {
    extend_blocks = resident_blocks(wave_extend_kernel);
    connect_blocks = resident_blocks(wave_connect_kernel);
  });
  const uint32_t slot_blocks = blocks_for(w.slots, kWaveThreads);
  TANDEM_CUDA_CHECK(cudaMemsetAsync(w.counters, 0, kWaveCounterCount * sizeof(uint32_t), stream));
  wave_fill_kernel<<<slot_blocks, kWaveThreads, 0, stream>>>(kd, batch, w);
  TANDEM_CUDA_CHECK_LAUNCH("wave_fill_kernel");
  // Each round retires at least one path unless the batch is misbehaving;
  // the bound only stops a runaway loop.
  const uint64_t max_rounds = items * 64 + 64;
  for (uint32_t round = 0; round < max_rounds; ++round) {
    wave_begin_round_kernel<<<1, 1, 0, stream>>>(w);
    TANDEM_CUDA_CHECK_LAUNCH("wave_begin_round_kernel");
    wave_extend_kernel<<<std::min(extend_blocks, slot_blocks), kWaveThreads, 0, stream>>>(kd, w,
                                                                                          round);
    TANDEM_CUDA_CHECK_LAUNCH("wave_extend_kernel");
    wave_shade_miss_kernel<<<slot_blocks, kWaveThreads, 0, stream>>>(kd, batch, w, round, radiance);
    TANDEM_CUDA_CHECK_LAUNCH("wave_shade_miss_kernel");
    wave_shade_hit_kernel<<<slot_blocks, kWaveThreads, 0, stream>>>(kd, batch, w, round, radiance);
    TANDEM_CUDA_CHECK_LAUNCH("wave_shade_hit_kernel");
    wave_connect_kernel<<<std::min(connect_blocks, slot_blocks), kWaveThreads, 0, stream>>>(kd, w,
                                                                                            round);
    TANDEM_CUDA_CHECK_LAUNCH("wave_connect_kernel");
    wave_retire_kernel<<<slot_blocks, kWaveThreads, 0, stream>>>(kd, batch, w, round, radiance);
    TANDEM_CUDA_CHECK_LAUNCH("wave_retire_kernel");
    if (round % kRoundsPerCheck == kRoundsPerCheck - 1) {
      TANDEM_CUDA_CHECK(cudaMemcpyAsync(host_counter, &w.counters[kWaveNextExtend],
                                        sizeof(uint32_t), cudaMemcpyDeviceToHost, stream));
      TANDEM_CUDA_CHECK(cudaStreamSynchronize(stream));
      if (*host_counter == 0) break;
    }
  }
  wave_count_rays_kernel<<<1, 1, 0, stream>>>(w, ray_count);
  TANDEM_CUDA_CHECK_LAUNCH("wave_count_rays_kernel");
}

}  // namespace tandem
