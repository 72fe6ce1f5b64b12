#include "backends/cuda/emulated_grid.h"

#include <sys/mman.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <unordered_map>
#include <utility>

#include "core/kernel/gpu_intrinsics.h"

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TANDEM_EMULATED_GRID_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) && !defined(TANDEM_EMULATED_GRID_ASAN)
#define TANDEM_EMULATED_GRID_ASAN 1
#endif
#if defined(TANDEM_EMULATED_GRID_ASAN)
// AddressSanitizer must be told about every switch between stacks, or it
// takes the fibers' frames for overflows of the thread's stack.
#include <sanitizer/asan_interface.h>
#include <sanitizer/common_interface_defs.h>
#endif

// Switching between fibers. On x86-64 a few instructions that save and
// restore what the ABI says a call preserves (the callee-saved registers,
// the SSE and x87 control words): ucontext's swapcontext also saves the
// signal mask, a system call per switch, which made it most of the
// emulation's time. Elsewhere ucontext.
#if defined(__x86_64__)
#define TANDEM_FIBER_ASM 1
extern "C" {
// Saves the current context on its stack and *from_sp, then continues the
// context whose stack pointer is to_sp.
void tandem_fiber_switch(void** from_sp, void* to_sp);
// Where a new fiber starts: calls r13(r12) on the fiber's own stack.
void tandem_fiber_start();
}
asm(R"(
  .text
  .globl tandem_fiber_switch
  .type tandem_fiber_switch, @function
tandem_fiber_switch:
  pushq %rbp
  pushq %rbx
  pushq %r12
  pushq %r13
  pushq %r14
  pushq %r15
  subq $8, %rsp
  stmxcsr (%rsp)
  fnstcw 4(%rsp)
  movq %rsp, (%rdi)
  movq %rsi, %rsp
  ldmxcsr (%rsp)
  fldcw 4(%rsp)
  addq $8, %rsp
  popq %r15
  popq %r14
  popq %r13
  popq %r12
  popq %rbx
  popq %rbp
  ret
  .size tandem_fiber_switch, .-tandem_fiber_switch

  .globl tandem_fiber_start
  .type tandem_fiber_start, @function
tandem_fiber_start:
  movq %r12, %rdi
  callq *%r13
  ud2
  .size tandem_fiber_start, .-tandem_fiber_start
  .section .note.GNU-stack, "", @progbits
  .text
)");
#else
#include <ucontext.h>
#endif

namespace tandem {

namespace {

constexpr uint32_t kWarpSize = 32;
constexpr uint32_t kMaxBlockThreads = 1024;
// Generous: the deepest path (the integrator's traversal frame and BSDF
// state) takes a few KiB, more in a sanitizer build; pages are committed
// only when touched.
constexpr size_t kFiberStackBytes = size_t(512) << 10;
// What the frames of a lane's entry take at the top of its stack.
constexpr size_t kStackTopBytes = size_t(16) << 10;
constexpr size_t kSharedSlotBytes = size_t(48) << 10;
constexpr uint8_t kSharedGarbage = 0xcd;
constexpr size_t kMaxFaults = 16;
constexpr uint64_t kSerialGridThreads = 1024;

// A fiber's stack, with an inaccessible page below it so that an overflow
// faults at once instead of writing over the next stack.
class FiberStack {
 public:
  FiberStack() {
    page_ = size_t(sysconf(_SC_PAGESIZE));
    void* p = mmap(nullptr, kFiberStackBytes + page_, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE | MAP_STACK, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    mprotect(p, page_, PROT_NONE);
    base_ = static_cast<unsigned char*>(p);
  }
  ~FiberStack() { munmap(base_, kFiberStackBytes + page_); }
  FiberStack(const FiberStack&) = delete;
  FiberStack& operator=(const FiberStack&) = delete;
  void* bottom() const { return base_ + page_; }
  size_t size() const { return kFiberStackBytes; }

 private:
  unsigned char* base_ = nullptr;
  size_t page_ = 0;
};

enum class LaneState : uint8_t { kReady, kBarrier, kWarpOp, kExited };
enum class WarpOp : uint8_t { kShfl, kBallot, kReduceAdd };

const char* warp_op_name(WarpOp op) {
  switch (op) {
    case WarpOp::kShfl:
      return "__shfl_sync";
    case WarpOp::kBallot:
      return "__ballot_sync";
    case WarpOp::kReduceAdd:
      return "__reduce_add_sync";
  }
  return "warp operation";
}

struct FiberContext;
#if !defined(TANDEM_FIBER_ASM)
void ucontext_entry(unsigned int high, unsigned int low);
#endif

// A suspended fiber.
struct FiberContext {
#if defined(TANDEM_FIBER_ASM)
  void* sp = nullptr;
#else
  ucontext_t context;
  void (*entry)(void*) = nullptr;
  void* arg = nullptr;
#endif
};

#if !defined(TANDEM_FIBER_ASM)
// makecontext passes int arguments only: the context's address in halves.
void ucontext_entry(unsigned int high, unsigned int low) {
  auto* c = reinterpret_cast<FiberContext*>((uintptr_t(high) << 32) | uintptr_t(low));
  c->entry(c->arg);
}
#endif

void switch_fiber(FiberContext& from, FiberContext& to) {
#if defined(TANDEM_FIBER_ASM)
  tandem_fiber_switch(&from.sp, to.sp);
#else
  swapcontext(&from.context, &to.context);
#endif
}

// Makes `context` start `entry(arg)` on `stack` at its first switch.
void make_fiber(FiberContext& context, FiberStack& stack, void (*entry)(void*), void* arg) {
#if defined(TANDEM_FIBER_ASM)
  // What tandem_fiber_switch pops: the control words, r15..r12, rbx, rbp and
  // the return address, tandem_fiber_start, which then finds the stack
  // pointer 16-byte aligned for its call, as the ABI wants.
  auto top = (reinterpret_cast<uintptr_t>(stack.bottom()) + stack.size()) & ~uintptr_t(15);
  auto* frame = reinterpret_cast<uint64_t*>(top - 64);
  uint32_t mxcsr = 0;
  uint16_t fpu = 0;
  asm volatile("stmxcsr %0" : "=m"(mxcsr));
  asm volatile("fnstcw %0" : "=m"(fpu));
  frame[0] = uint64_t(mxcsr) | uint64_t(fpu) << 32;
  frame[1] = 0;                                  // r15
  frame[2] = 0;                                  // r14
  frame[3] = reinterpret_cast<uint64_t>(entry);  // r13
  frame[4] = reinterpret_cast<uint64_t>(arg);    // r12
  frame[5] = 0;                                  // rbx
  frame[6] = 0;                                  // rbp
  frame[7] = reinterpret_cast<uint64_t>(&tandem_fiber_start);
  context.sp = frame;
#else
  getcontext(&context.context);
  context.context.uc_stack.ss_sp = stack.bottom();
  context.context.uc_stack.ss_size = stack.size();
  context.context.uc_link = nullptr;
  context.entry = entry;
  context.arg = arg;
  const auto address = reinterpret_cast<uintptr_t>(&context);
  makecontext(&context.context, reinterpret_cast<void (*)()>(&ucontext_entry), 2,
              static_cast<unsigned int>(address >> 32),
              static_cast<unsigned int>(address & 0xffffffffu));
#endif
}

struct Lane {
  FiberContext context;
  EmulatedThread thread;
  LaneState state = LaneState::kReady;
  WarpOp op = WarpOp::kShfl;
  uint32_t mask = 0, value = 0, src = 0, result = 0;
  FiberStack* stack = nullptr;
  bool started = false;        // has run at all (a thread not yet run is simply dropped)
  void* fake_stack = nullptr;  // AddressSanitizer's, while switched out
};

std::string hex(uint64_t v) {
  char text[32];
  std::snprintf(text, sizeof text, "0x%llx", static_cast<unsigned long long>(v));
  return text;
}

std::string dim_text(const DeviceDim3& d) {
  char text[48];
  std::snprintf(text, sizeof text, "(%u, %u, %u)", d.x, d.y, d.z);
  return text;
}

}  // namespace

struct EmulatedBlock {
  const EmulatedLaunch* launch = nullptr;
  EmulatedKernelEntry entry = nullptr;
  const std::vector<EmulatedMemoryRange>* memory = nullptr;  // sorted
  std::vector<Lane> lanes;
  FiberContext scheduler;
  Lane* running = nullptr;
  std::string fault;
  bool cancelled = false;  // the block faulted: waiting threads unwind when resumed
  // Threads in each state but kReady, kept with the states (set_state).
  uint32_t at_barrier = 0, at_warp_op = 0, exited = 0;
  uint64_t epoch = 0;       // barriers completed
  size_t shared_bytes = 0;  // the slot's size once a thread asked for it
  // Word of the slot -> (rank, epoch) of its last store.
  std::unordered_map<uint32_t, std::pair<uint32_t, uint64_t>> shared_writes;
  const EmulatedMemoryRange* last_range = nullptr;
  const void* scheduler_stack = nullptr;
  size_t scheduler_stack_size = 0;
  void* scheduler_fake_stack = nullptr;
  alignas(64) unsigned char shared[kSharedSlotBytes];
};

namespace {

// The block the current host thread is running, for the checks called from
// kernel code that has no EmulatedThread at hand (gpu_intrinsics.h).
thread_local EmulatedBlock* t_block = nullptr;

// Per host thread: a block's state and the fibers' stacks, reused from
// block to block.
struct HostThreadState {
  std::unique_ptr<EmulatedBlock> block = std::make_unique<EmulatedBlock>();
  std::vector<std::unique_ptr<FiberStack>> stacks;
};
HostThreadState& host_thread_state() {
  thread_local HostThreadState state;
  return state;
}

Lane& lane_of(EmulatedThread& t) {
  return t.block->lanes[t.rank];
}

uint32_t& state_count(EmulatedBlock& b, LaneState state) {
  static uint32_t ready = 0;  // not counted
  switch (state) {
    case LaneState::kBarrier:
      return b.at_barrier;
    case LaneState::kWarpOp:
      return b.at_warp_op;
    case LaneState::kExited:
      return b.exited;
    case LaneState::kReady:
      break;
  }
  return ready;
}

void set_state(EmulatedBlock& b, Lane& lane, LaneState state) {
  if (lane.state != LaneState::kReady) --state_count(b, lane.state);
  lane.state = state;
  if (state != LaneState::kReady) ++state_count(b, state);
}

// From the scheduler into `lane`, until it blocks, ends or faults.
void resume(EmulatedBlock& b, Lane& lane) {
  b.running = &lane;
  t_block = &b;
#if defined(TANDEM_EMULATED_GRID_ASAN)
  __sanitizer_start_switch_fiber(&b.scheduler_fake_stack, lane.stack->bottom(), lane.stack->size());
#endif
  switch_fiber(b.scheduler, lane.context);
#if defined(TANDEM_EMULATED_GRID_ASAN)
  __sanitizer_finish_switch_fiber(b.scheduler_fake_stack, nullptr, nullptr);
#endif
  b.running = nullptr;
  t_block = nullptr;
}

// From the running lane back to the scheduler; `final`: the lane is never
// resumed (it ended or faulted).
void leave(EmulatedBlock& b, Lane& lane, bool final) {
#if defined(TANDEM_EMULATED_GRID_ASAN)
  __sanitizer_start_switch_fiber(final ? nullptr : &lane.fake_stack, b.scheduler_stack,
                                 b.scheduler_stack_size);
#else
  (void) final;
#endif
  switch_fiber(lane.context, b.scheduler);
#if defined(TANDEM_EMULATED_GRID_ASAN)
  __sanitizer_finish_switch_fiber(lane.fake_stack, nullptr, nullptr);
#endif
}

const char* kernel_name(const EmulatedLaunch& launch) {
  return launch.name ? launch.name : device_kernel_name(launch.kernel);
}

std::string thread_text(const EmulatedBlock& b, const Lane& lane) {
  return std::string(kernel_name(*b.launch)) + ", block " + dim_text(lane.thread.block_idx) +
         ", thread " + dim_text(lane.thread.thread_idx) + " (warp " +
         std::to_string(lane.thread.rank / kWarpSize) + ", lane " +
         std::to_string(lane.thread.rank % kWarpSize) + ")";
}

// Thrown through the kernel's frames, on the fiber's own stack, to end a
// thread of a faulted block: everything the frames hold is released on the
// way (a fiber that was simply dropped would leak the message it built).
struct EmulatedFault {};

// Ends the running thread with a fault report; the scheduler then ends its
// block (run_block). Does not return.
[[noreturn]] void fault(EmulatedBlock& b, Lane& lane, const std::string& what) {
  if (b.fault.empty()) b.fault = thread_text(b, lane) + ": " + what;
  throw EmulatedFault{};
}

// Waits, switched out, until another thread makes this one ready; throws
// when the block faulted meanwhile.
void block_until_ready(EmulatedBlock& b, Lane& lane) {
  while (lane.state != LaneState::kReady) {
    leave(b, lane, false);
    if (b.cancelled) throw EmulatedFault{};
  }
}

// What a lane that ended leaves behind: threads at a barrier it will never
// reach, or at a warp operation whose mask names it.
void check_exit(EmulatedBlock& b, Lane& lane) {
  if (b.at_barrier == 0 && b.at_warp_op == 0) return;
  const uint32_t warp = lane.thread.rank / kWarpSize, bit = lane.thread.rank % kWarpSize;
  for (const Lane& other : b.lanes) {
    if (other.state == LaneState::kBarrier)
      fault(b, lane,
            "exited while threads of its block wait at __syncthreads(), which it never reaches");
    if (other.state == LaneState::kWarpOp && other.thread.rank / kWarpSize == warp &&
        ((other.mask >> bit) & 1u) != 0) {
      fault(b, lane,
            "exited while lane " + std::to_string(other.thread.rank % kWarpSize) + " waits at " +
                warp_op_name(other.op) + " with mask " + hex(other.mask) + ", which names it");
    }
  }
}

void lane_main(void* arg) {
  Lane* lane = static_cast<Lane*>(arg);
  EmulatedBlock& b = *lane->thread.block;
#if defined(TANDEM_EMULATED_GRID_ASAN)
  __sanitizer_finish_switch_fiber(nullptr, &b.scheduler_stack, &b.scheduler_stack_size);
#endif
  lane->started = true;
  try {
    b.entry(b.launch->args, lane->thread);
    check_exit(b, *lane);
  } catch (const EmulatedFault&) {
    // The block faulted: this thread ends here.
  }
  set_state(b, *lane, LaneState::kExited);
  leave(b, *lane, true);
  std::abort();  // an exited lane is never resumed
}

// What the threads of a block that cannot go on wait for.
std::string describe_deadlock(const EmulatedBlock& b) {
  for (const Lane& lane : b.lanes) {
    if (lane.state == LaneState::kWarpOp) {
      const uint32_t base = lane.thread.rank / kWarpSize * kWarpSize;
      std::string others;
      for (uint32_t i = 0; i < kWarpSize; ++i) {
        if (((lane.mask >> i) & 1u) == 0 || base + i >= b.lanes.size()) continue;
        const Lane& o = b.lanes[base + i];
        if (o.state == LaneState::kWarpOp && o.op == lane.op && o.mask == lane.mask) continue;
        others += (others.empty() ? "" : ", ") + std::to_string(i) +
                  (o.state == LaneState::kBarrier ? " (at __syncthreads())"
                                                  : std::string(" (at ") + warp_op_name(o.op) +
                                                        " with mask " + hex(o.mask) + ")");
      }
      return thread_text(b, lane) + ": waits at " + warp_op_name(lane.op) + " with mask " +
             hex(lane.mask) + " for lanes " + others +
             ", which wait elsewhere: the warp's threads diverged (undefined on a GPU)";
    }
  }
  return std::string(kernel_name(*b.launch)) +
         ": the block's threads wait for each other and none can go on";
}

// After a fault: every thread that started and has not ended is resumed to
// unwind from where it waits (block_until_ready throws).
void cancel_block(EmulatedBlock& b) {
  b.cancelled = true;
  for (Lane& lane : b.lanes) {
    if (lane.state == LaneState::kExited) continue;
    if (lane.started)
      resume(b, lane);
    else
      set_state(b, lane, LaneState::kExited);
  }
}

void run_block(EmulatedBlock& b, std::vector<std::unique_ptr<FiberStack>>& stacks,
               const DeviceDim3& block_idx) {
  const DeviceDim3 dim = b.launch->dims.block;
  const auto n = uint32_t(dim.count());
  while (stacks.size() < n)
    stacks.push_back(std::make_unique<FiberStack>());
  b.lanes.resize(n);
  b.fault.clear();
  b.cancelled = false;
  b.at_barrier = b.at_warp_op = b.exited = 0;
  b.epoch = 0;
  b.shared_bytes = 0;
  b.shared_writes.clear();
  b.last_range = nullptr;
  for (uint32_t rank = 0; rank < n; ++rank) {
    Lane& lane = b.lanes[rank];
    lane = Lane{};
    lane.stack = stacks[rank].get();
#if defined(TANDEM_EMULATED_GRID_ASAN)
    // The frames of the entry, which never returns, are still poisoned from
    // the last block, at the top of the stack; every other frame returned or
    // unwound. Only those: unpoisoning the whole 512 KiB for every thread of
    // every block was most of a sanitizer build's emulation time.
    ASAN_UNPOISON_MEMORY_REGION(
        static_cast<unsigned char*>(lane.stack->bottom()) + (lane.stack->size() - kStackTopBytes),
        kStackTopBytes);
#endif
    lane.thread.thread_idx = {rank % dim.x, rank / dim.x % dim.y, rank / (dim.x * dim.y)};
    lane.thread.block_idx = block_idx;
    lane.thread.block_dim = dim;
    lane.thread.grid_dim = b.launch->dims.grid;
    lane.thread.block = &b;
    lane.thread.rank = rank;
    make_fiber(lane.context, *lane.stack, &lane_main, &lane);
  }
  for (;;) {
    bool ran = false;
    for (Lane& lane : b.lanes) {
      if (lane.state != LaneState::kReady) continue;
      resume(b, lane);
      ran = true;
      if (!b.fault.empty()) break;
    }
    if (ran && b.fault.empty()) continue;
    if (b.fault.empty() && b.exited != n) b.fault = describe_deadlock(b);
    if (!b.fault.empty()) cancel_block(b);
    return;
  }
}

}  // namespace

void EmulatedKernelTable::add(DeviceKernel kernel, EmulatedKernelEntry entry, size_t args_bytes) {
  kernels[uint32_t(kernel)] = Kernel{entry, args_bytes};
}

void EmulatedKernelTable::add_device_table(const void* table, size_t bytes) {
  const auto begin = reinterpret_cast<uintptr_t>(table);
  for (const EmulatedMemoryRange& r : device_tables)
    if (r.begin == begin) return;
  device_tables.push_back({begin, begin + bytes});
}

const EmulatedKernelTable& emulated_kernels() {
  static const EmulatedKernelTable table = [] {
    EmulatedKernelTable t;
#define TANDEM_CALL_EMULATED_REGISTRY(name) register_emulated_kernels_##name(t);
    TANDEM_DEVICE_KERNEL_FILES(TANDEM_CALL_EMULATED_REGISTRY)
#undef TANDEM_CALL_EMULATED_REGISTRY
    return t;
  }();
  return table;
}

void emulated_sync_block(EmulatedThread& t) {
  EmulatedBlock& b = *t.block;
  Lane& lane = lane_of(t);
  if (b.exited != 0) {
    for (const Lane& other : b.lanes)
      if (other.state == LaneState::kExited)
        fault(b, lane,
              "__syncthreads() after thread " + std::to_string(other.thread.rank) +
                  " of the block exited: a barrier must be reached by every thread of the block");
  }
  if (b.at_barrier + 1 == b.lanes.size()) {
    ++b.epoch;
    for (Lane& other : b.lanes)
      set_state(b, other, LaneState::kReady);
    return;
  }
  set_state(b, lane, LaneState::kBarrier);
  block_until_ready(b, lane);
}

namespace {

uint32_t warp_op(EmulatedThread& t, WarpOp op, uint32_t mask, uint32_t value, uint32_t src) {
  EmulatedBlock& b = *t.block;
  Lane& lane = lane_of(t);
  const uint32_t me = t.rank % kWarpSize, base = t.rank - me;
  const uint32_t present = std::min<uint32_t>(kWarpSize, uint32_t(b.lanes.size()) - base);
  if (((mask >> me) & 1u) == 0)
    fault(b, lane,
          std::string(warp_op_name(op)) + " with mask " + hex(mask) +
              ", which does not name the calling lane");
  if (present < kWarpSize && (mask >> present) != 0)
    fault(b, lane,
          std::string(warp_op_name(op)) + " with mask " + hex(mask) + " in a warp of " +
              std::to_string(present) + " threads: it names lanes that do not exist");
  if (op == WarpOp::kShfl && (src >= kWarpSize || ((mask >> src) & 1u) == 0))
    fault(b, lane,
          "__shfl_sync from lane " + std::to_string(src) + ", which mask " + hex(mask) +
              " does not name");
  lane.op = op;
  lane.mask = mask;
  lane.value = value;
  lane.src = src;
  set_state(b, lane, LaneState::kWarpOp);
  bool complete = true;
  for (uint32_t i = 0; i < kWarpSize; ++i) {
    if (((mask >> i) & 1u) == 0) continue;
    const Lane& other = b.lanes[base + i];
    if (other.state == LaneState::kExited)
      fault(b, lane,
            std::string(warp_op_name(op)) + " with mask " + hex(mask) + ": lane " +
                std::to_string(i) + " exited without taking part");
    complete =
        complete && other.state == LaneState::kWarpOp && other.op == op && other.mask == mask;
  }
  if (complete) {
    uint32_t result = 0;
    for (uint32_t i = 0; i < kWarpSize; ++i) {
      if (((mask >> i) & 1u) == 0) continue;
      const Lane& other = b.lanes[base + i];
      if (op == WarpOp::kBallot && other.value != 0) result |= 1u << i;
      if (op == WarpOp::kReduceAdd) result += other.value;
    }
    if (op == WarpOp::kShfl) result = b.lanes[base + src].value;
    for (uint32_t i = 0; i < kWarpSize; ++i) {
      if (((mask >> i) & 1u) == 0) continue;
      Lane& other = b.lanes[base + i];
      other.result = result;
      set_state(b, other, LaneState::kReady);
    }
  }
  block_until_ready(b, lane);
  return lane.result;
}

// The range of device memory holding [p, p + bytes), or null.
const EmulatedMemoryRange* find_range(EmulatedBlock& b, uintptr_t p, size_t bytes) {
  const EmulatedMemoryRange* last = b.last_range;
  if (last && p >= last->begin && p + bytes <= last->end) return last;
  const std::vector<EmulatedMemoryRange>& memory = *b.memory;
  auto it = std::upper_bound(memory.begin(), memory.end(), p,
                             [](uintptr_t a, const EmulatedMemoryRange& r) { return a < r.begin; });
  if (it == memory.begin()) return nullptr;
  --it;
  if (p + bytes > it->end) return nullptr;
  b.last_range = &*it;
  return b.last_range;
}

void check_access(EmulatedBlock& b, Lane& lane, const void* p, size_t bytes, size_t alignment,
                  const char* what) {
  const auto address = reinterpret_cast<uintptr_t>(p);
  if (alignment > 1 && address % alignment != 0)
    fault(b, lane,
          std::string(what) + " of " + std::to_string(bytes) + " bytes at " + hex(address) +
              ": misaligned (needs " + std::to_string(alignment) + ")");
  if (!find_range(b, address, bytes))
    fault(b, lane,
          std::string(what) + " of " + std::to_string(bytes) + " bytes at " + hex(address) +
              ": outside device memory");
}

}  // namespace

uint32_t emulated_shfl(EmulatedThread& t, uint32_t mask, uint32_t value, uint32_t src_lane) {
  return warp_op(t, WarpOp::kShfl, mask, value, src_lane);
}

uint32_t emulated_ballot(EmulatedThread& t, uint32_t mask, bool predicate) {
  return warp_op(t, WarpOp::kBallot, mask, predicate ? 1u : 0u, 0);
}

uint32_t emulated_reduce_add(EmulatedThread& t, uint32_t mask, uint32_t value) {
  return warp_op(t, WarpOp::kReduceAdd, mask, value, 0);
}

uint32_t emulated_atomic_add(EmulatedThread& t, uint32_t* p, uint32_t v) {
  check_access(*t.block, lane_of(t), p, sizeof *p, alignof(uint32_t), "atomicAdd");
  return __atomic_fetch_add(p, v, __ATOMIC_RELAXED);
}

unsigned long long emulated_atomic_add(EmulatedThread& t, unsigned long long* p,
                                       unsigned long long v) {
  check_access(*t.block, lane_of(t), p, sizeof *p, alignof(unsigned long long), "atomicAdd");
  return __atomic_fetch_add(p, v, __ATOMIC_RELAXED);
}

void* emulated_shared_slot(EmulatedThread& t, size_t bytes, size_t alignment) {
  EmulatedBlock& b = *t.block;
  if (bytes > kSharedSlotBytes || alignment > 64)
    fault(b, lane_of(t),
          "a shared slot of " + std::to_string(bytes) + " bytes (at most " +
              std::to_string(kSharedSlotBytes) + ")");
  if (b.shared_bytes != 0 && b.shared_bytes != bytes)
    fault(b, lane_of(t), "a second shared slot, of another size, in one kernel");
  if (b.shared_bytes == 0) {
    // Garbage, as shared memory is when a block starts.
    std::memset(b.shared, kSharedGarbage, bytes);
    b.shared_bytes = bytes;
  }
  return b.shared;
}

void emulated_store_shared(EmulatedThread& t, uint32_t* p, uint32_t v) {
  EmulatedBlock& b = *t.block;
  const auto offset = size_t(reinterpret_cast<unsigned char*>(p) - b.shared);
  if (reinterpret_cast<unsigned char*>(p) < b.shared || offset + sizeof v > b.shared_bytes ||
      offset % sizeof v != 0)
    fault(b, lane_of(t),
          "shared-memory store at byte " + std::to_string(offset) +
              " outside the block's shared slot of " + std::to_string(b.shared_bytes) + " bytes");
  const auto word = uint32_t(offset / sizeof v);
  auto [it, added] = b.shared_writes.try_emplace(word, t.rank, b.epoch);
  if (!added) {
    if (it->second.second == b.epoch && it->second.first != t.rank)
      fault(b, lane_of(t),
            "shared-memory race: threads " + std::to_string(it->second.first) + " and " +
                std::to_string(t.rank) + " both write word " + std::to_string(word) +
                " of the shared slot between two barriers");
    it->second = {t.rank, b.epoch};
  }
  *p = v;
}

void gpu_emulation::check_device_access(const void* p, size_t bytes, size_t alignment,
                                        const char* what) {
  EmulatedBlock* b = t_block;
  if (!b || !b->running) {
    std::fprintf(stderr, "tandem: %s outside an emulated kernel\n", what);
    std::abort();
  }
  check_access(*b, *b->running, p, bytes, alignment, what);
}

std::vector<std::string> run_emulated_grid(const EmulatedLaunch& launch) {
  const EmulatedKernelTable& table = emulated_kernels();
  const char* name = kernel_name(launch);
  if (uint32_t(launch.kernel) >= kDeviceKernelCount) return {"launch of an unknown kernel"};
  const EmulatedKernelEntry entry =
      launch.entry ? launch.entry : table.kernels[uint32_t(launch.kernel)].entry;
  if (!entry) return {std::string(name) + ": no emulated build of this kernel"};
  const LaunchDims& d = launch.dims;
  if (d.block.count() == 0 || d.block.count() > kMaxBlockThreads || d.grid.count() == 0)
    return {std::string(name) + ": invalid launch of " + dim_text(d.grid) + " blocks of " +
            dim_text(d.block) + " threads"};
  std::vector<EmulatedMemoryRange> memory = launch.memory;
  memory.insert(memory.end(), table.device_tables.begin(), table.device_tables.end());
  std::sort(
      memory.begin(), memory.end(),
      [](const EmulatedMemoryRange& a, const EmulatedMemoryRange& b) { return a.begin < b.begin; });
  std::atomic<bool> stop{false};
  std::mutex mutex;
  std::vector<std::string> faults;
  const uint64_t blocks = d.grid.count();
  auto run_blocks = [&](const tbb::blocked_range<uint64_t>& r) {
    HostThreadState& state = host_thread_state();
    EmulatedBlock& b = *state.block;
    b.launch = &launch;
    b.entry = entry;
    b.memory = &memory;
    for (uint64_t i = r.begin(); i != r.end(); ++i) {
      if (stop.load(std::memory_order_relaxed)) return;
      const DeviceDim3 block_idx{uint32_t(i % d.grid.x), uint32_t(i / d.grid.x % d.grid.y),
                                 uint32_t(i / (uint64_t(d.grid.x) * d.grid.y))};
      run_block(b, state.stacks, block_idx);
      if (b.fault.empty()) continue;
      stop = true;
      std::lock_guard<std::mutex> lock(mutex);
      if (faults.size() < kMaxFaults) faults.push_back(b.fault);
    }
  };
  // A small grid (most of a wavefront round's kernels once the batch thins
  // out) runs on the calling thread: waking the host's other cores for it
  // costs more than it computes.
  if (blocks * d.block.count() <= kSerialGridThreads)
    run_blocks(tbb::blocked_range<uint64_t>(0, blocks, blocks));
  else
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), run_blocks);
  return faults;
}

}  // namespace tandem
