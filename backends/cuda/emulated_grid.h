// The simulated device's GPU: a kernel's grid of thread blocks executed on
// the CPU with the GPU's own execution model, so that the kernels' bodies
// (the .cu files, compiled a second time by the C++ compiler with
// TANDEM_EMULATED_GPU) run in CI exactly as written.
//
//   - Every thread of a block is a fiber with a stack of its own; a thread
//     runs until it reaches a barrier or a warp operation, then the next one
//     runs. Blocks run in parallel on the host's cores.
//   - A barrier completes when every thread of the block has reached it. A
//     warp operation (shuffle, ballot, reduction) completes when every lane
//     its mask names has reached a warp operation of the same kind and mask;
//     a lane of the mask that has exited, or that waits elsewhere when
//     nothing else can run, is a divergence bug (undefined on a GPU, which
//     may hang or return garbage): the kernel faults with a report.
//   - The block's shared slot starts filled with garbage, and two threads
//     writing the same word of it between two barriers is reported as a race.
//   - Read-only loads (__ldg) and atomics must be aligned and inside device
//     memory: an allocation of the simulated device or a __device__ table.
//   - A fault ends the thread's block, and no further block starts: like a
//     GPU's, the kernel's results are then undefined.
//
// No kernel types here: the emulated build's files include this header next
// to their own copy of the kernel code (device_exec.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "backends/cuda/device_kernel_ids.h"

namespace tandem {

struct EmulatedBlock;  // emulated_grid.cpp

// One emulated thread, as device_exec.h's DeviceExec reads it.
struct EmulatedThread {
  DeviceDim3 thread_idx, block_idx, block_dim, grid_dim;
  EmulatedBlock* block = nullptr;
  uint32_t rank = 0;  // thread_idx.x + block_dim.x * (thread_idx.y + block_dim.y * thread_idx.z)
};

// A kernel's entry in the emulated build: runs its body as `thread`.
using EmulatedKernelEntry = void (*)(const void* args, EmulatedThread& thread);

// The operations of a block, for DeviceExec. Those of a warp and the
// barrier may switch to other threads of the block; a fault does not return.
void emulated_sync_block(EmulatedThread& t);
uint32_t emulated_shfl(EmulatedThread& t, uint32_t mask, uint32_t value, uint32_t src_lane);
uint32_t emulated_ballot(EmulatedThread& t, uint32_t mask, bool predicate);
uint32_t emulated_reduce_add(EmulatedThread& t, uint32_t mask, uint32_t value);
uint32_t emulated_atomic_add(EmulatedThread& t, uint32_t* p, uint32_t v);
unsigned long long emulated_atomic_add(EmulatedThread& t, unsigned long long* p,
                                       unsigned long long v);
// The block's shared slot (one object per kernel, at most 48 KiB).
void* emulated_shared_slot(EmulatedThread& t, size_t bytes, size_t alignment);
// A store into the shared slot, checked for races with the block's other
// threads.
void emulated_store_shared(EmulatedThread& t, uint32_t* p, uint32_t v);

// Memory a kernel may read through __ldg and update atomically.
struct EmulatedMemoryRange {
  uintptr_t begin = 0, end = 0;
};

// The kernels of the emulated build and the __device__ tables they read.
struct EmulatedKernelTable {
  struct Kernel {
    EmulatedKernelEntry entry = nullptr;
    size_t args_bytes = 0;
  };
  Kernel kernels[kDeviceKernelCount];
  std::vector<EmulatedMemoryRange> device_tables;

  void add(DeviceKernel kernel, EmulatedKernelEntry entry, size_t args_bytes);
  void add_device_table(const void* table, size_t bytes);
};
// One per .cu file, defined by its emulated build (TANDEM_KERNEL_REGISTRY,
// device_exec.h).
#define TANDEM_DECLARE_EMULATED_REGISTRY(name) \
  void register_emulated_kernels_##name(EmulatedKernelTable& table);
TANDEM_DEVICE_KERNEL_FILES(TANDEM_DECLARE_EMULATED_REGISTRY)
#undef TANDEM_DECLARE_EMULATED_REGISTRY
// Every emulated kernel, registered on first use.
const EmulatedKernelTable& emulated_kernels();

struct EmulatedLaunch {
  DeviceKernel kernel = DeviceKernel::kMegakernel;
  const void* args = nullptr;  // the kernel's Args (device_kernels.h)
  LaunchDims dims;
  std::vector<EmulatedMemoryRange> memory;  // device memory besides the tables
  // A kernel of no table (the grid's own tests): run instead of `kernel`'s.
  EmulatedKernelEntry entry = nullptr;
  const char* name = nullptr;
};

// Runs the launch to its end; returns what faulted (empty when nothing did),
// each message naming the kernel, the block and the thread.
std::vector<std::string> run_emulated_grid(const EmulatedLaunch& launch);

}  // namespace tandem
