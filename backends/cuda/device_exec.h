// The execution policy of the CUDA backend's kernels: what a kernel body
// (device_kernels.h, the .cu files) may ask of the GPU besides plain
// arithmetic and memory. Written once for two executors:
//   - nvcc: the thread's indices, __syncthreads, the warp intrinsics with
//     masks, atomicAdd and a __shared__ slot, at no cost (a kernel's
//     resources are what the intrinsics alone give; kernel_resources.sh);
//   - the emulated build (TANDEM_EMULATED_GPU, backends/cuda/emulated_*.cpp):
//     the same operations on the simulated device's emulated grid
//     (emulated_grid.h), which checks what the GPU leaves undefined.
// Kernel bodies are templates on the policy and are registered in one table
// per executor by TANDEM_KERNEL_REGISTRY at the end of each .cu file.
// Only for nvcc and the emulated build.
#pragma once

#include "backends/cuda/device_kernels.h"
#include "core/kernel/gpu_intrinsics.h"
#include "core/kernel/sheen_albedo_table.h"
#include "core/kernel/srgb_table.h"

#if defined(__CUDACC__)
#include "backends/cuda/cuda_kernel_table.h"
#elif defined(TANDEM_EMULATED_GPU)
#include "backends/cuda/emulated_grid.h"
#else
#error "device_exec.h is compiled by nvcc or by the emulated build only"
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

class DeviceExec {
 public:
#if defined(__CUDACC__)
  __device__ DeviceExec() {}
#else
  explicit DeviceExec(EmulatedThread& t) : t_(&t) {}
#endif

  // The thread's and the block's indices and sizes, read where they are
  // used: on the GPU they are special registers, which a copy taken at the
  // start would keep live (in registers) for the whole kernel.
  TANDEM_DEVICE_FN DeviceDim3 thread() const {
#if defined(__CUDACC__)
    return {threadIdx.x, threadIdx.y, threadIdx.z};
#else
    return t_->thread_idx;
#endif
  }
  TANDEM_DEVICE_FN DeviceDim3 block() const {
#if defined(__CUDACC__)
    return {blockIdx.x, blockIdx.y, blockIdx.z};
#else
    return t_->block_idx;
#endif
  }
  TANDEM_DEVICE_FN DeviceDim3 block_dim() const {
#if defined(__CUDACC__)
    return {blockDim.x, blockDim.y, blockDim.z};
#else
    return t_->block_dim;
#endif
  }

  // The thread's index in its block (x fastest) and the block's size.
  TANDEM_DEVICE_FN uint32_t thread_rank() const {
    const DeviceDim3 t = thread(), d = block_dim();
    return t.x + d.x * (t.y + d.y * t.z);
  }
  TANDEM_DEVICE_FN uint32_t block_threads() const {
    const DeviceDim3 d = block_dim();
    return d.x * d.y * d.z;
  }
  TANDEM_DEVICE_FN uint32_t lane() const {
    return thread_rank() & 31u;
  }
  // The thread's index in a one-dimensional grid of any size.
  TANDEM_DEVICE_FN uint64_t global_x() const {
    return uint64_t(block().x) * block_dim().x + thread().x;
  }
  // Its column and row in a two-dimensional grid (an image: 32 bits).
  TANDEM_DEVICE_FN uint32_t pixel_x() const {
    return block().x * block_dim().x + thread().x;
  }
  TANDEM_DEVICE_FN uint32_t pixel_y() const {
    return block().y * block_dim().y + thread().y;
  }

  // Every thread of the block waits here for every other.
  TANDEM_DEVICE_FN void sync_block() {
#if defined(__CUDACC__)
    __syncthreads();
#else
    emulated_sync_block(*t_);
#endif
  }
  // Warp operations over the lanes of `mask`, each of which must call the
  // same operation with the same mask.
  TANDEM_DEVICE_FN uint32_t shfl(uint32_t mask, uint32_t value, uint32_t src_lane) {
#if defined(__CUDACC__)
    return __shfl_sync(mask, value, src_lane);
#else
    return emulated_shfl(*t_, mask, value, src_lane);
#endif
  }
  TANDEM_DEVICE_FN uint32_t ballot(uint32_t mask, bool predicate) {
#if defined(__CUDACC__)
    return __ballot_sync(mask, predicate);
#else
    return emulated_ballot(*t_, mask, predicate);
#endif
  }
  TANDEM_DEVICE_FN uint32_t reduce_add(uint32_t mask, uint32_t value) {
#if defined(__CUDACC__)
    return __reduce_add_sync(mask, value);
#else
    return emulated_reduce_add(*t_, mask, value);
#endif
  }
  // atomicAdd on device memory; returns the old value.
  TANDEM_DEVICE_FN uint32_t atomic_add(uint32_t* p, uint32_t v) {
#if defined(__CUDACC__)
    return atomicAdd(p, v);
#else
    return emulated_atomic_add(*t_, p, v);
#endif
  }
  TANDEM_DEVICE_FN unsigned long long atomic_add(unsigned long long* p, unsigned long long v) {
#if defined(__CUDACC__)
    return atomicAdd(p, v);
#else
    return emulated_atomic_add(*t_, p, v);
#endif
  }
  // The block's one shared object of type T (uninitialised).
  template <class T>
  TANDEM_DEVICE_FN T& shared_slot() {
#if defined(__CUDACC__)
    __shared__ alignas(alignof(T)) unsigned char slot[sizeof(T)];
    return *reinterpret_cast<T*>(slot);
#else
    return *static_cast<T*>(emulated_shared_slot(*t_, sizeof(T), alignof(T)));
#endif
  }
  // A word stored into the shared slot (the emulated grid checks that no
  // two threads store the same word between two barriers).
  TANDEM_DEVICE_FN void store_shared(uint32_t* p, uint32_t v) {
#if defined(__CUDACC__)
    *p = v;
#else
    emulated_store_shared(*t_, p, v);
#endif
  }

 private:
#if !defined(__CUDACC__)
  EmulatedThread* t_;
#endif
};

// The kernels read the scene description through a block-wide copy of
// KernelData in shared memory: every thread dereferences its pointers in the
// innermost traversal loops, and shared memory serves those uniform loads
// without touching the L1 data cache that the BVH nodes need. Each word is
// stored by one thread of the block, whatever the block's shape.
template <class Exec>
TANDEM_DEVICE_FN const KernelData& load_kernel_data(Exec& ex, const KernelData* src) {
  static_assert(sizeof(KernelData) % sizeof(uint32_t) == 0, "copied as words");
  KernelData& kd = ex.template shared_slot<KernelData>();
  const uint32_t* s = reinterpret_cast<const uint32_t*>(src);
  uint32_t* d = reinterpret_cast<uint32_t*>(&kd);
  for (uint32_t i = ex.thread_rank(); i < sizeof(KernelData) / sizeof(uint32_t);
       i += ex.block_threads())
    ex.store_shared(&d[i], s[i]);
  ex.sync_block();
  return kd;
}

// Adds each thread's ray count to *total with one atomic per warp. Every
// lane of the warp must call it.
template <class Exec>
TANDEM_DEVICE_FN void add_ray_count(Exec& ex, uint32_t rays, unsigned long long* total) {
  const uint32_t sum = ex.reduce_add(0xffffffffu, rays);
  if (ex.lane() == 0) ex.atomic_add(total, static_cast<unsigned long long>(sum));
}

// Persistent threads (Aila & Laine 2009, "Understanding the efficiency of
// ray traversal on GPUs"): just enough warps to fill the GPU, each taking 32
// entries at a time of a queue of length n from the counter *taken, so that
// warps that drew short work take more instead of idling until the slowest
// warp of their block ends. Every lane of the warp must call it.
template <class Exec, class F>
TANDEM_DEVICE_FN void persistent_loop(Exec& ex, uint32_t n, uint32_t* taken, const F& f) {
  for (;;) {
    uint32_t base = 0;
    if (ex.lane() == 0) base = ex.atomic_add(taken, 32u);
    base = ex.shfl(0xffffffffu, base, 0);
    if (base >= n) break;  // uniform across the warp
    if (base + ex.lane() < n) f(base + ex.lane());
  }
}

// Kernel K's entry in this executor's table.
#if defined(__CUDACC__)
template <class K>
__global__ void __launch_bounds__(K::kThreads, K::kMinBlocks)
    cuda_entry(const __grid_constant__ typename K::Args args) {
  DeviceExec ex;
  K::run(ex, args);
}
using DeviceKernelTable = CudaKernelTable;
template <class K>
const void* kernel_entry() {
  return reinterpret_cast<const void*>(&cuda_entry<K>);
}
#else
template <class K>
void emulated_entry(const void* args, EmulatedThread& thread) {
  DeviceExec ex(thread);
  K::run(ex, *static_cast<const typename K::Args*>(args));
}
using DeviceKernelTable = EmulatedKernelTable;
template <class K>
EmulatedKernelEntry kernel_entry() {
  return &emulated_entry<K>;
}
#endif

template <class K>
void add_kernel(DeviceKernelTable& table) {
  table.add(K::kId, kernel_entry<K>(), sizeof(typename K::Args));
  // What the kernels read through the read-only cache besides the scene.
  table.add_device_table(kSrgb8ToLinearDevice, sizeof kSrgb8ToLinearDevice);
  table.add_device_table(kSheenAlbedoDevice, sizeof kSheenAlbedoDevice);
}

template <class... Kernels>
void register_kernels(DeviceKernelTable& table) {
  (add_kernel<Kernels>(table), ...);
}

TANDEM_KERNEL_END
}  // namespace tandem

// The registration function of one .cu file, at namespace scope after its
// kernels: register_cuda_kernels_NAME or register_emulated_kernels_NAME, which
// the CUDA device (cuda_device_ops.cpp) or the emulated grid
// (emulated_grid.cpp) calls.
#if defined(__CUDACC__)
#define TANDEM_KERNEL_REGISTRY(name) \
  void ::tandem::register_cuda_kernels_##name(::tandem::CudaKernelTable& table)
#else
#define TANDEM_KERNEL_REGISTRY(name) \
  void ::tandem::register_emulated_kernels_##name(::tandem::EmulatedKernelTable& table)
#endif
