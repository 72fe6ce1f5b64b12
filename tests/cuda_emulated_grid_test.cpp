// The emulated grid (backends/cuda/emulated_grid.h) that runs the CUDA
// kernels' bodies on the simulated device: warp operations and barriers
// compute what the GPU computes, and what the GPU leaves undefined (a warp
// operation a lane of its mask never reaches, a barrier some threads never
// reach, two threads storing one shared word between barriers, a read-only
// load or an atomic outside device memory or misaligned) faults with a
// report instead of passing. Also the GPU's intrinsics of the kernel code
// (core/kernel/gpu_intrinsics.h) against the host's functions.
//
// This file is itself an emulated build: its test kernels are written with
// the execution policy (device_exec.h) as the .cu files are.
#define TANDEM_EMULATED_GPU 1

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "backends/cuda/device_exec.h"
#include "core/kernel/rng_tables.h"

namespace tandem {
TANDEM_KERNEL_BEGIN
namespace {

struct Buffer {
  uint32_t* data;
  uint32_t n;
};

// Every warp operation, full and partial masks: out[k * threads + t].
struct WarpOps {
  using Args = Buffer;
  template <class Exec>
  static void run(Exec& ex, const Args& a) {
    const uint32_t t = ex.thread_rank(), lane = ex.lane(), n = ex.block_threads();
    a.data[0 * n + t] = ex.ballot(0xffffffffu, lane % 3 == 0);
    a.data[1 * n + t] = ex.reduce_add(0xffffffffu, lane + 1);
    a.data[2 * n + t] = ex.shfl(0xffffffffu, t * 10, 5);
    // The two halves of the warp, each on its own.
    const uint32_t half = lane < 16 ? 0x0000ffffu : 0xffff0000u;
    a.data[3 * n + t] = ex.shfl(half, lane, lane < 16 ? 3 : 17);
    a.data[4 * n + t] = ex.reduce_add(half, 1);
  }
};

// Each thread stores its word of the shared slot, and after the barrier
// reads its neighbour's.
struct Shared {
  uint32_t words[128];
};
struct SharedNeighbours {
  using Args = Buffer;
  template <class Exec>
  static void run(Exec& ex, const Args& a) {
    Shared& s = ex.template shared_slot<Shared>();
    const uint32_t t = ex.thread_rank(), n = ex.block_threads();
    ex.store_shared(&s.words[t], 1000 * ex.block().x + t);
    ex.sync_block();
    a.data[ex.block().x * n + t] = s.words[(t + 1) % n];
  }
};

// The faulty kernels: `a.n` says which fault.
enum Fault : uint32_t {
  kShflAfterExit,
  kMaskWithoutCaller,
  kBarrierAfterExit,
  kExitDuringBarrier,
  kSharedRace,
  kSharedNoRace,  // the same stores with a barrier between: fine
  kLoadOutside,
  kLoadMisaligned,
  kAtomicOutside,
  kWarpOpAgainstBarrier,
};
struct Faulty {
  using Args = Buffer;
  template <class Exec>
  static void run(Exec& ex, const Args& a) {
    const uint32_t t = ex.thread_rank(), n = ex.block_threads();
    switch (a.n) {
      case kShflAfterExit:
        if (ex.lane() >= 16) return;
        a.data[t] = ex.shfl(0xffffffffu, t, 0);
        return;
      case kMaskWithoutCaller:
        a.data[t] = ex.shfl(0x1u << ((ex.lane() + 1) % 32), t, (ex.lane() + 1) % 32);
        return;
      case kBarrierAfterExit:
        if (t == 0) return;
        ex.sync_block();
        return;
      case kExitDuringBarrier:
        if (t == n - 1) return;
        ex.sync_block();
        return;
      case kSharedRace:
      case kSharedNoRace: {
        Shared& s = ex.template shared_slot<Shared>();
        if (t == 0) ex.store_shared(&s.words[7], 1);
        if (a.n == kSharedNoRace) ex.sync_block();
        if (t == 1) ex.store_shared(&s.words[7], 2);
        return;
      }
      case kLoadOutside: {
        const uint32_t host_word = 5;
        a.data[t] = gpu_load_readonly(&host_word);
        return;
      }
      case kLoadMisaligned: {
        const auto* p =
            reinterpret_cast<const GpuWord4*>(reinterpret_cast<const char*>(a.data) + 4);
        a.data[t] = gpu_load_readonly(p).x;
        return;
      }
      case kAtomicOutside: {
        uint32_t host_word = 0;
        ex.atomic_add(&host_word, 1u);
        a.data[t] = host_word;
        return;
      }
      case kWarpOpAgainstBarrier:
        if (ex.lane() < 16)
          a.data[t] = ex.shfl(0xffffffffu, t, 0);
        else
          ex.sync_block();
        return;
    }
  }
};

// KernelData into the shared slot of a 16 x 16 block: with
// load_kernel_data (every word stored by one thread), or (x_only) striding
// by the x index alone, as the feature kernel once did, so that the 16 rows
// of the block store every word 16 times.
struct CopyKernelData {
  struct Args {
    const KernelData* kd;
    uint32_t* out;
    uint32_t x_only;
  };
  template <class Exec>
  static void run(Exec& ex, const Args& a) {
    const KernelData* kd = nullptr;
    if (a.x_only) {
      KernelData& slot = ex.template shared_slot<KernelData>();
      const uint32_t* s = reinterpret_cast<const uint32_t*>(a.kd);
      uint32_t* d = reinterpret_cast<uint32_t*>(&slot);
      for (uint32_t i = ex.thread().x; i < sizeof(KernelData) / 4; i += ex.block_dim().x)
        ex.store_shared(&d[i], s[i]);
      ex.sync_block();
      kd = &slot;
    } else {
      kd = &load_kernel_data(ex, a.kd);
    }
    if (ex.thread_rank() == 0) a.out[ex.block().x] = kd->constants.camera.width;
  }
};

// The intrinsics over a batch of words: out[4 * i + k].
struct Intrinsics {
  using Args = Buffer;
  template <class Exec>
  static void run(Exec& ex, const Args& a) {
    const uint64_t i = ex.global_x();
    if (i >= a.n) return;
    const uint32_t x = gpu_load_readonly(&a.data[i]);
    uint32_t* out = a.data + a.n + 4 * i;
    out[0] = gpu_reverse_bits(x);
    out[1] = gpu_find_first_set(x);
    out[2] = gpu_popcount(x);
    out[3] = gpu_atomic_add(&a.data[a.n + 4 * a.n], 1u) < a.n ? 1u : 0u;
  }
};

template <class K>
std::vector<std::string> run(const char* name, std::vector<uint32_t>& memory, uint32_t n,
                             DeviceDim3 grid, DeviceDim3 block) {
  const Buffer args{memory.data(), n};
  EmulatedLaunch launch;
  launch.entry = &emulated_entry<K>;
  launch.name = name;
  launch.args = &args;
  launch.dims = {grid, block};
  const auto begin = reinterpret_cast<uintptr_t>(memory.data());
  launch.memory.push_back({begin, begin + memory.size() * sizeof(uint32_t)});
  return run_emulated_grid(launch);
}

std::string text(const std::vector<std::string>& faults) {
  std::string s;
  for (const std::string& f : faults)
    s += "\n  " + f;
  return s;
}

}  // namespace
TANDEM_KERNEL_END

namespace {

TEST(CudaEmulatedGrid, WarpOperationsComputeWhatTheGpuComputes) {
  const uint32_t n = 64;
  std::vector<uint32_t> out(5 * n, 0);
  const std::vector<std::string> faults = run<WarpOps>("warp ops", out, n, {1, 1, 1}, {n, 1, 1});
  ASSERT_TRUE(faults.empty()) << text(faults);
  uint32_t ballot = 0;
  for (uint32_t lane = 0; lane < 32; lane += 3)
    ballot |= 1u << lane;
  for (uint32_t t = 0; t < n; ++t) {
    const uint32_t lane = t % 32, warp_base = t - lane;
    EXPECT_EQ(out[t], ballot) << t;
    EXPECT_EQ(out[n + t], 32u * 33u / 2u) << t;
    EXPECT_EQ(out[2 * n + t], (warp_base + 5) * 10) << t;
    EXPECT_EQ(out[3 * n + t], lane < 16 ? 3u : 17u) << t;
    EXPECT_EQ(out[4 * n + t], 16u) << t;
  }
}

TEST(CudaEmulatedGrid, BarrierOrdersTheBlocksSharedSlot) {
  const uint32_t n = 96, blocks = 5;
  std::vector<uint32_t> out(n * blocks, 0);
  const std::vector<std::string> faults =
      run<SharedNeighbours>("shared", out, n, {blocks, 1, 1}, {32, 3, 1});
  ASSERT_TRUE(faults.empty()) << text(faults);
  for (uint32_t b = 0; b < blocks; ++b)
    for (uint32_t t = 0; t < n; ++t)
      EXPECT_EQ(out[b * n + t], 1000 * b + (t + 1) % n) << b << " " << t;
}

// Each undefined behaviour faults with a report that says what it was; the
// same stores ordered by a barrier do not.
TEST(CudaEmulatedGrid, WhatTheGpuLeavesUndefinedFaults) {
  struct Case {
    Fault fault;
    const char* expected;  // in the report; null: no fault
  };
  const Case cases[] = {
      {kShflAfterExit, "waits at __shfl_sync with mask 0xffffffff, which names it"},
      {kMaskWithoutCaller, "does not name the calling lane"},
      {kBarrierAfterExit, "__syncthreads() after thread 0"},
      {kExitDuringBarrier, "exited while threads of its block wait at __syncthreads()"},
      {kSharedRace, "shared-memory race: threads 0 and 1"},
      {kSharedNoRace, nullptr},
      {kLoadOutside, "outside device memory"},
      {kLoadMisaligned, "misaligned"},
      {kAtomicOutside, "atomicAdd of 4 bytes"},
      {kWarpOpAgainstBarrier, "diverged"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE("fault " + std::to_string(c.fault));
    std::vector<uint32_t> memory(256, 0);
    const std::vector<std::string> faults =
        run<Faulty>("faulty", memory, c.fault, {3, 1, 1}, {64, 1, 1});
    if (!c.expected) {
      EXPECT_TRUE(faults.empty()) << text(faults);
      continue;
    }
    // A fault ends its block and no later block starts.
    ASSERT_EQ(faults.size(), 1u) << text(faults);
    EXPECT_NE(faults[0].find(c.expected), std::string::npos) << faults[0];
    EXPECT_NE(faults[0].find("faulty, block (0, 0, 0), thread"), std::string::npos) << faults[0];
  }
}

TEST(CudaEmulatedGrid, KernelDataIsCopiedOncePerBlockWhateverItsShape) {
  KernelData kd{};
  kd.constants.camera.width = 1234;
  std::vector<uint32_t> out(4, 0);
  for (uint32_t x_only : {0u, 1u}) {
    SCOPED_TRACE(x_only ? "stride by x" : "load_kernel_data");
    const CopyKernelData::Args args{&kd, out.data(), x_only};
    EmulatedLaunch launch;
    launch.entry = &emulated_entry<CopyKernelData>;
    launch.name = "copy";
    launch.args = &args;
    launch.dims = {{4, 1, 1}, {16, 16, 1}};
    for (const void* p : {static_cast<const void*>(&kd), static_cast<const void*>(out.data())}) {
      const auto begin = reinterpret_cast<uintptr_t>(p);
      launch.memory.push_back({begin, begin + (p == &kd ? sizeof kd : out.size() * 4)});
    }
    const std::vector<std::string> faults = run_emulated_grid(launch);
    if (x_only) {
      ASSERT_EQ(faults.size(), 1u) << text(faults);
      EXPECT_NE(faults[0].find("shared-memory race"), std::string::npos) << faults[0];
    } else {
      EXPECT_TRUE(faults.empty()) << text(faults);
      EXPECT_EQ(out, std::vector<uint32_t>(4, 1234u));
    }
  }
}

TEST(CudaEmulatedGrid, IntrinsicsGiveTheHostFunctionsResults) {
  const uint32_t n = 4096;
  std::vector<uint32_t> memory(n + 4 * n + 1, 0);
  uint32_t x = 0x12345678u;
  for (uint32_t i = 0; i < n; ++i) {
    x = x * 1664525u + 1013904223u;
    memory[i] = i < 33 ? (i == 32 ? 0u : 1u << i) : x;
  }
  const std::vector<std::string> faults =
      run<Intrinsics>("intrinsics", memory, n, {(n + 127) / 128, 1, 1}, {128, 1, 1});
  ASSERT_TRUE(faults.empty()) << text(faults);
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t v = memory[i];
    const uint32_t* out = &memory[n + 4 * i];
    EXPECT_EQ(out[0], reverse_bits_u32_shifts(v)) << v;
    EXPECT_EQ(out[1], v ? uint32_t(__builtin_ctz(v)) + 1u : 0u) << v;
    EXPECT_EQ(out[2], uint32_t(__builtin_popcount(v))) << v;
    EXPECT_EQ(out[3], 1u) << v;
  }
  EXPECT_EQ(memory[n + 4 * n], n);  // every thread's atomic landed
}

}  // namespace
}  // namespace tandem
