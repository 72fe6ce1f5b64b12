#include "backends/cuda/sim_device.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "backends/cuda/device_kernels.h"
#include "backends/cuda/emulated_grid.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

// Lamport/Fidge vector clock over agents (streams and host threads).
struct VectorClock {
  std::vector<uint64_t> t;
  uint64_t get(size_t agent) const { return agent < t.size() ? t[agent] : 0; }
  void tick(size_t agent) {
    if (t.size() <= agent) t.resize(agent + 1, 0);
    ++t[agent];
  }
  void join(const VectorClock& o) {
    if (t.size() < o.t.size()) t.resize(o.t.size(), 0);
    for (size_t i = 0; i < o.t.size(); ++i)
      t[i] = std::max(t[i], o.t[i]);
  }
};

struct Access {
  uintptr_t begin, end;
  bool write;
  uint32_t agent;
  uint64_t time;  // the agent's own clock component at the access
  std::string what;
};

struct Allocation {
  size_t bytes = 0;
  bool pinned = false;
  bool live = true;
  void* memory = nullptr;
  std::deque<Access> log;  // recent accesses, for hazard checks
};

// Accesses kept per allocation: enough for the few frames a hazard can span.
constexpr size_t kAccessLogDepth = 256;
constexpr size_t kMaxHazards = 64;
constexpr size_t kAlignment = 256;
constexpr uint8_t kFreshMemoryPattern = 0xcd;
constexpr double kSleepQuantumSeconds = 1e-3;

}  // namespace

struct DeviceStreamHandle {
  uint32_t agent = 0;
  struct Op {
    std::function<void()> body;
    VectorClock enqueuer;  // what the enqueuing host thread knew
    double seconds = 0.0;
  };
  std::deque<Op> queue;
  uint64_t enqueued = 0, done = 0;
  VectorClock vc;
  bool stopping = false, live = true;
  std::condition_variable work;
  std::thread worker;
};

struct DeviceEventHandle {
  bool timing = false, live = true;
  uint64_t recorded = 0, completed = 0;
  struct Record {
    VectorClock vc;
    Clock::time_point when;
  };
  std::map<uint64_t, Record> records;  // the most recent few generations
};

struct SimDevice::Impl {
  SimDeviceOptions options;
  mutable std::mutex mutex;
  std::condition_variable progress;  // an operation completed somewhere
  std::map<uintptr_t, Allocation> allocations;
  std::vector<std::unique_ptr<DeviceStreamHandle>> streams;
  std::vector<std::unique_ptr<DeviceEventHandle>> events;
  std::map<std::thread::id, uint32_t> host_agents;
  std::map<uint32_t, VectorClock> host_clocks;
  uint32_t next_agent = 0;
  SimDeviceReport report;
  uint64_t hazards_seen = 0;  // including those past the report's cap
  std::mt19937_64 rng;

  explicit Impl(SimDeviceOptions o) : options(o), rng(o.seed) {}

  VectorClock& host_clock_locked() {
    auto [it, added] = host_agents.try_emplace(std::this_thread::get_id(), next_agent);
    if (added) ++next_agent;
    VectorClock& vc = host_clocks[it->second];
    vc.tick(it->second);
    return vc;
  }

  void hazard_locked(std::string text) {
    // Said once on stderr as well: a hazard skips the operation, and a test
    // that only compares images would otherwise fail without the reason.
    if (hazards_seen == 0) std::fprintf(stderr, "[sim] first hazard: %s\n", text.c_str());
    ++hazards_seen;
    if (report.hazards.size() < kMaxHazards) report.hazards.push_back(std::move(text));
  }

  // Records an access by stream `s` (whose clock is current) and reports
  // conflicts with earlier accesses that are not ordered before it.
  void access_locked(const void* p, size_t bytes, bool write, const DeviceStreamHandle& s,
                     const std::string& what, bool device_memory) {
    if (bytes == 0) return;
    const auto addr = reinterpret_cast<uintptr_t>(p);
    auto it = allocations.upper_bound(addr);
    if (it == allocations.begin() || (--it, addr + bytes > it->first + it->second.bytes)) {
      if (device_memory)
        hazard_locked(what + ": " + std::to_string(bytes) + " bytes outside any device allocation");
      return;
    }
    Allocation& a = it->second;
    if (!a.live) {
      hazard_locked(what + ": use of freed memory");
      return;
    }
    if (device_memory && a.pinned) {
      hazard_locked(what + ": host (pinned) memory used as device memory");
      return;
    }
    for (const Access& prior : a.log) {
      if (!(write || prior.write) || prior.end <= addr || prior.begin >= addr + bytes) continue;
      if (prior.time <= s.vc.get(prior.agent)) continue;  // ordered before us
      hazard_locked(what + " (stream " + std::to_string(s.agent) + ") " +
                    (write ? "writes" : "reads") + " bytes that " + prior.what + " (stream " +
                    std::to_string(prior.agent) + ") " + (prior.write ? "writes" : "reads") +
                    " with nothing ordering the two (allocation of " + std::to_string(a.bytes) +
                    " bytes)");
    }
    a.log.push_back(Access{addr, addr + bytes, write, s.agent, s.vc.get(s.agent), what});
    if (a.log.size() > kAccessLogDepth) a.log.pop_front();
  }

  void* allocate_locked(size_t bytes, bool pinned) {
    const size_t size = (std::max<size_t>(bytes, 1) + kAlignment - 1) / kAlignment * kAlignment;
    void* p = std::aligned_alloc(kAlignment, size);
    if (!p) throw DeviceError(DeviceFault::kOutOfMemory, "simulated GPU: out of memory");
    std::memset(p, kFreshMemoryPattern, size);
    // Freed allocations stay in the map, so that a late use of one is
    // reported. One whose address lies inside the new block would be found
    // by the lookups below for the new block's bytes from there on (a
    // hazard that skips a copy or a kernel, by where the C library happens
    // to put memory): it is forgotten. One at the same address is replaced.
    const auto first = reinterpret_cast<uintptr_t>(p);
    for (auto it = allocations.upper_bound(first);
         it != allocations.end() && it->first < first + size;) {
      it = it->second.live ? std::next(it) : allocations.erase(it);
    }
    Allocation a;
    a.bytes = bytes;
    a.pinned = pinned;
    a.memory = p;
    allocations[reinterpret_cast<uintptr_t>(p)] = std::move(a);
    (pinned ? report.live_pinned_allocations : report.live_device_allocations) += 1;
    ++report.allocations;
    return p;
  }

  Allocation* find_locked(void* p) {
    auto it = allocations.find(reinterpret_cast<uintptr_t>(p));
    return it == allocations.end() || !it->second.live ? nullptr : &it->second;
  }

  void release_locked(Allocation& a) {
    a.live = false;
    std::free(a.memory);
    a.memory = nullptr;
    (a.pinned ? report.live_pinned_allocations : report.live_device_allocations) -= 1;
  }

  bool is_pinned_locked(const void* p, size_t bytes) {
    const auto addr = reinterpret_cast<uintptr_t>(p);
    auto it = allocations.upper_bound(addr);
    if (it == allocations.begin()) return false;
    --it;
    return it->second.live && it->second.pinned && addr + bytes <= it->first + it->second.bytes;
  }

  double jitter_locked() {
    return options.op_seconds * std::uniform_real_distribution<double>(0.0, 1.0)(rng);
  }

  void enqueue(DeviceStream s, double extra_seconds, std::function<void()> body) {
    std::lock_guard<std::mutex> lock(mutex);
    if (!s || !s->live) throw DeviceError(DeviceFault::kOther, "simulated GPU: invalid stream");
    DeviceStreamHandle::Op op;
    op.body = std::move(body);
    op.enqueuer = host_clock_locked();
    op.seconds = options.op_seconds + jitter_locked() + extra_seconds;
    s->queue.push_back(std::move(op));
    ++s->enqueued;
    s->work.notify_one();
  }

  void run_stream(DeviceStreamHandle* s) {
    std::unique_lock<std::mutex> lock(mutex);
    // Device time the stream owes: paid in one sleep once it reaches a
    // quantum or the queue runs dry, rather than one sleep per operation (a
    // wavefront batch is hundreds of small kernels, and every sleep costs a
    // timer's slack on top of its length).
    double owed = 0.0;
    for (;;) {
      s->work.wait(lock, [&] { return s->stopping || !s->queue.empty(); });
      if (s->queue.empty()) return;
      DeviceStreamHandle::Op op = std::move(s->queue.front());
      s->queue.pop_front();
      s->vc.join(op.enqueuer);
      s->vc.tick(s->agent);
      owed += op.seconds;
      const bool pay = owed >= kSleepQuantumSeconds || s->queue.empty();
      lock.unlock();
      if (pay) {
        std::this_thread::sleep_for(std::chrono::duration<double>(owed));
        owed = 0.0;
      }
      op.body();
      lock.lock();
      ++s->done;
      progress.notify_all();
    }
  }

  // The vector clock an event's generation `g` captured (the newest kept
  // one if `g` was pruned, which only ever adds ordering).
  const VectorClock* event_clock_locked(const DeviceEventHandle& e, uint64_t g) {
    if (g == 0 || e.records.empty()) return nullptr;
    auto it = e.records.lower_bound(g);
    if (it == e.records.end()) --it;
    return &it->second.vc;
  }

  void drain_all_locked(std::unique_lock<std::mutex>& lock) {
    bool waited = false;
    for (auto& s : streams) {
      if (!s->live) continue;
      const uint64_t target = s->enqueued;
      waited = waited || s->done < target;
      progress.wait(lock, [&] { return s->done >= target; });
      host_clock_locked().join(s->vc);
    }
    report.device_wide_waits += waited;
  }

  // Reads the KernelData a kernel receives and records the reads of every
  // array it points at.
  KernelData read_kernel_data_locked(const KernelData* kd, const DeviceStreamHandle& s,
                                     const char* kernel) {
    access_locked(kd, sizeof(KernelData), false, s, std::string(kernel) + " reads KernelData",
                  true);
    KernelData local{};
    if (find_containing_locked(kd, sizeof(KernelData))) std::memcpy(&local, kd, sizeof local);
#define TANDEM_SIM_READ_ARRAY(T, name)                                          \
  if (local.name##_count)                                                       \
    access_locked(local.name, size_t(local.name##_count) * sizeof(T), false, s, \
                  std::string(kernel) + " reads " #name, true);
    TANDEM_KERNEL_ARRAYS(TANDEM_SIM_READ_ARRAY)
#undef TANDEM_SIM_READ_ARRAY
    return local;
  }

  // The live device allocations, which an emulated kernel may address.
  std::vector<EmulatedMemoryRange> device_memory() {
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<EmulatedMemoryRange> ranges;
    for (const auto& [base, a] : allocations)
      if (a.live && !a.pinned) ranges.push_back({base, base + a.bytes});
    return ranges;
  }

  // Records what `kernel` reads and writes, from its arguments; false when
  // an address is bad (the kernel then does not run, as a faulting one).
  // Whole arrays are recorded where a kernel's reach depends on queue
  // lengths in device memory: all of a kernel's accesses are in stream
  // order anyway, and a conflicting access from elsewhere is a hazard
  // wherever in the array it falls.
  bool kernel_accesses_locked(DeviceKernel kernel, const void* args, const DeviceStreamHandle& s) {
    const std::string name = device_kernel_name(kernel);
    const uint64_t before = hazards_seen;
    auto read = [&](const void* p, size_t bytes, const char* what) {
      if (p && bytes) access_locked(p, bytes, false, s, name + " reads " + what, true);
    };
    auto write = [&](const void* p, size_t bytes, const char* what) {
      if (p && bytes) access_locked(p, bytes, true, s, name + " writes " + what, true);
    };
    auto tiles = [&](const TileBatch& b) {
      read(b.tiles, b.tile_count * sizeof(DeviceTile), "tiles");
    };
    switch (kernel) {
      case DeviceKernel::kMegakernel: {
        const auto& a = *static_cast<const MegakernelArgs*>(args);
        read_kernel_data_locked(a.kd, s, name.c_str());
        tiles(a.batch);
        write(a.radiance, a.batch.items() * sizeof(Vec3), "radiance");
        write(a.ray_count, sizeof *a.ray_count, "the ray count");
        break;
      }
      case DeviceKernel::kWaveFill:
      case DeviceKernel::kWaveBeginRound:
      case DeviceKernel::kWaveExtend:
      case DeviceKernel::kWaveShadeMiss:
      case DeviceKernel::kWaveShadeHit:
      case DeviceKernel::kWaveConnect:
      case DeviceKernel::kWaveRetire:
      case DeviceKernel::kWaveCountRays:
        wave_accesses_locked(kernel, *static_cast<const WaveArgs*>(args), s, read, write);
        break;
      case DeviceKernel::kTraceRays: {
        const auto& a = *static_cast<const TraceRaysArgs*>(args);
        read_kernel_data_locked(a.kd, s, name.c_str());
        read(a.rays, a.n * sizeof(Ray), "rays");
        read(a.alpha_keys, a.n * sizeof(uint32_t), "alpha keys");
        write(a.hits, a.n * sizeof(Hit), "hits");
        write(a.work_counter, sizeof(uint32_t), "its work counter");
        break;
      }
      case DeviceKernel::kReduceSamples: {
        const auto& a = *static_cast<const ReduceSamplesArgs*>(args);
        read(a.radiance, a.batch.items() * sizeof(Vec3), "radiance");
        write(a.pixel_sums, 3 * sizeof(double) * a.batch.pixel_count, "pixel sums");
        break;
      }
      case DeviceKernel::kAccumulateFilm: {
        const auto& a = *static_cast<const AccumulateFilmArgs*>(args);
        tiles(a.batch);
        read(a.pixel_sums, 3 * sizeof(double) * a.batch.pixel_count, "pixel sums");
        film_accesses(a.film, true, read, write);
        break;
      }
      case DeviceKernel::kResolveFilm: {
        const auto& a = *static_cast<const ResolveFilmArgs*>(args);
        film_accesses(a.film, false, read, write);
        write(a.rgb, 3 * sizeof(float) * size_t(a.film.width) * a.film.height, "rgb");
        break;
      }
      case DeviceKernel::kToneMapFilm: {
        const auto& a = *static_cast<const ToneMapFilmArgs*>(args);
        film_accesses(a.film, false, read, write);
        write(a.rgb8, 3 * size_t(a.film.width) * a.film.height, "rgb8");
        break;
      }
      case DeviceKernel::kFeatures: {
        const auto& a = *static_cast<const FeaturesArgs*>(args);
        const KernelData kd = read_kernel_data_locked(a.kd, s, name.c_str());
        if (kd.constants.camera.width != a.width || kd.constants.camera.height != a.height) {
          hazard_locked(name + ": a " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                        " film for a " + std::to_string(kd.constants.camera.width) + "x" +
                        std::to_string(kd.constants.camera.height) + " camera");
          return false;
        }
        if (a.pass.prev_object_to_world)
          read(a.pass.prev_object_to_world, a.pass.prev_instance_count * sizeof(Mat34),
               "previous transforms");
        write(a.out, size_t(a.width) * a.height * sizeof(PixelFeatures), "features");
        break;
      }
      case DeviceKernel::kSvgfTemporal: {
        const auto& a = *static_cast<const SvgfTemporalArgs*>(args);
        const size_t n = size_t(a.params.width) * a.params.height;
        const SvgfTemporalBuffers& b = a.buffers;
        read(b.features, n * sizeof(PixelFeatures), "features");
        read(b.radiance, n * sizeof(Vec3), "radiance");
        if (b.prev_features) {
          read(b.prev_features, n * sizeof(PixelFeatures), "previous features");
          read(b.prev_color, n * sizeof(Vec4), "history");
          read(b.prev_moments, n * sizeof(Vec4), "previous moments");
        }
        write(b.color, n * sizeof(Vec4), "illumination");
        write(b.moments, n * sizeof(Vec4), "moments");
        write(b.depth_slope, n * sizeof(Vec2), "depth slopes");
        write(b.guide, n * sizeof(SvgfGuide), "guides");
        write(b.material, n * sizeof(uint32_t), "materials");
        break;
      }
      case DeviceKernel::kSvgfVariance: {
        const auto& a = *static_cast<const SvgfVarianceArgs*>(args);
        const size_t n = size_t(a.params.width) * a.params.height;
        const SvgfVarianceBuffers& b = a.buffers;
        read(b.guide, n * sizeof(SvgfGuide), "guides");
        read(b.material, n * sizeof(uint32_t), "materials");
        read(b.depth_slope, n * sizeof(Vec2), "depth slopes");
        read(b.color, n * sizeof(Vec4), "illumination");
        read(b.moments, n * sizeof(Vec4), "moments");
        write(b.out, n * sizeof(Vec4), "its output");
        break;
      }
      case DeviceKernel::kSvgfAtrous: {
        const auto& a = *static_cast<const SvgfAtrousArgs*>(args);
        const size_t n = size_t(a.params.width) * a.params.height;
        const SvgfAtrousBuffers& b = a.buffers;
        read(b.guide, n * sizeof(SvgfGuide), "guides");
        read(b.material, n * sizeof(uint32_t), "materials");
        read(b.depth_slope, n * sizeof(Vec2), "depth slopes");
        read(b.in, n * sizeof(Vec4), "its input");
        write(a.out, n * sizeof(Vec4), "its output");
        if (a.radiance) {
          read(a.features, n * sizeof(PixelFeatures), "features");
          write(a.radiance, n * sizeof(Vec3), "radiance");
        }
        break;
      }
      case DeviceKernel::kSvgfModulate: {
        const auto& a = *static_cast<const SvgfModulateArgs*>(args);
        const size_t n = size_t(a.params.width) * a.params.height;
        read(a.features, n * sizeof(PixelFeatures), "features");
        read(a.illumination, n * sizeof(Vec4), "illumination");
        write(a.out, n * sizeof(Vec3), "radiance");
        break;
      }
    }
    return hazards_seen == before;
  }

  template <class Read, class Write>
  static void film_accesses(const DeviceFilmView& film, bool adds, const Read& read,
                            const Write& write) {
    const size_t pixels = size_t(film.width) * film.height;
    if (adds) {
      write(film.sums, 3 * sizeof(double) * pixels, "the film");
      write(film.samples, sizeof(uint32_t) * pixels, "sample counts");
    } else {
      read(film.sums, 3 * sizeof(double) * pixels, "the film");
      read(film.samples, sizeof(uint32_t) * pixels, "sample counts");
    }
  }

  // A wavefront stage: the arrays of its slots it reads and writes
  // (core/kernel/wavefront.h).
  template <class Read, class Write>
  void wave_accesses_locked(DeviceKernel kernel, const WaveArgs& a, const DeviceStreamHandle& s,
                            const Read& read, const Write& write) {
    const WavefrontArrays& w = a.w;
    const size_t slots = w.slots, queue = slots * sizeof(uint32_t);
    write(w.counters, kWaveCounterCount * sizeof(uint32_t), "queue counters");
    if (kernel == DeviceKernel::kWaveBeginRound) return;
    if (kernel == DeviceKernel::kWaveCountRays) {
      write(a.ray_count, sizeof *a.ray_count, "the ray count");
      return;
    }
    read_kernel_data_locked(a.kd, s, device_kernel_name(kernel));
    const bool regenerates =
        kernel == DeviceKernel::kWaveFill || kernel == DeviceKernel::kWaveShadeMiss ||
        kernel == DeviceKernel::kWaveShadeHit || kernel == DeviceKernel::kWaveRetire;
    write(w.paths, slots * sizeof(PathState), "paths");
    if (regenerates) {
      read(a.batch.tiles, a.batch.tile_count * sizeof(DeviceTile), "tiles");
      write(w.slot_item, queue, "slot items");
      if (kernel != DeviceKernel::kWaveFill)
        write(a.radiance, a.batch.items() * sizeof(Vec3), "radiance");
    }
    // Every stage but extend may queue a path for the next round.
    for (uint32_t* q : w.extend_queues)
      write(q, queue, "extend queues");
    switch (kernel) {
      case DeviceKernel::kWaveExtend:
        write(w.hits, slots * sizeof(Hit), "hits");
        write(w.hit_queue, queue, "the hit queue");
        write(w.miss_queue, queue, "the miss queue");
        break;
      case DeviceKernel::kWaveShadeMiss:
        read(w.miss_queue, queue, "the miss queue");
        break;
      case DeviceKernel::kWaveShadeHit:
        read(w.hit_queue, queue, "the hit queue");
        read(w.hits, slots * sizeof(Hit), "hits");
        write(w.shadows, slots * sizeof(ShadowRay), "shadow rays");
        write(w.shadow_queue, queue, "the shadow queue");
        break;
      case DeviceKernel::kWaveConnect:
        read(w.shadow_queue, queue, "the shadow queue");
        read(w.shadows, slots * sizeof(ShadowRay), "shadow rays");
        write(w.retire_queue, queue, "the retire queue");
        break;
      case DeviceKernel::kWaveRetire:
        read(w.retire_queue, queue, "the retire queue");
        break;
      default:
        break;
    }
  }

  bool find_containing_locked(const void* p, size_t bytes) {
    const auto addr = reinterpret_cast<uintptr_t>(p);
    auto it = allocations.upper_bound(addr);
    if (it == allocations.begin()) return false;
    --it;
    return it->second.live && addr + bytes <= it->first + it->second.bytes;
  }

  // An asynchronous copy between pinned host memory and device memory;
  // `to_device` says which side is which. It takes time by its size and
  // counts as pageable when the host side is not pinned.
  void copy(void* dst, const void* src, size_t bytes, DeviceStream s, bool to_device) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (!is_pinned_locked(to_device ? src : dst, bytes)) ++report.pageable_async_copies;
      (to_device ? report.bytes_to_device : report.bytes_to_host) += bytes;
    }
    const char* what = to_device ? "copy_to_device" : "copy_to_host";
    enqueue(s, options.copy_seconds_per_mib * double(bytes) / (1 << 20),
            [this, dst, src, bytes, s, to_device, what] {
              bool ok;
              {
                std::lock_guard<std::mutex> lock(mutex);
                const uint64_t before = hazards_seen;
                access_locked(src, bytes, false, *s, what, !to_device);
                access_locked(dst, bytes, true, *s, what, to_device);
                ok = hazards_seen == before;
              }
              if (ok) std::memcpy(dst, src, bytes);
            });
  }

  // Runs `body` as a kernel on `s`: records its accesses first (`accesses`
  // returns false when an address is bad, and the kernel is skipped, as a
  // faulting kernel would be), then computes without the lock.
  void launch(DeviceStream s, const char* name, std::function<bool()> accesses,
              std::function<void()> body) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++report.kernels;
    }
    enqueue(s, options.kernel_seconds,
            [this, accesses = std::move(accesses), body = std::move(body)] {
              bool ok;
              {
                std::lock_guard<std::mutex> lock(mutex);
                const uint64_t before = hazards_seen;
                ok = accesses() && hazards_seen == before;
              }
              if (ok) body();
            });
    (void)name;
  }
};

SimDevice::SimDevice(SimDeviceOptions options) : impl_(std::make_unique<Impl>(options)) {}

SimDevice::~SimDevice() {
  for (auto& s : impl_->streams) {
    if (s->live) destroy_stream(s.get());
  }
  for (auto& [base, a] : impl_->allocations) {
    if (a.live) std::free(a.memory);
  }
}

SimDeviceReport SimDevice::report() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->report;
}

void SimDevice::stall(DeviceStream stream, double seconds) {
  impl_->enqueue(stream, seconds, [] {});
}

void* SimDevice::alloc(size_t bytes) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->allocate_locked(bytes, false);
}

void SimDevice::free(void* p) {
  if (!p) return;
  // cudaFree waits for the whole device first.
  std::unique_lock<std::mutex> lock(impl_->mutex);
  impl_->drain_all_locked(lock);
  Allocation* a = impl_->find_locked(p);
  if (!a || a->pinned)
    throw DeviceError(DeviceFault::kOther, "simulated GPU: free of a bad pointer");
  impl_->release_locked(*a);
}

void* SimDevice::alloc_async(size_t bytes, DeviceStream stream) {
  void* p;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    p = impl_->allocate_locked(bytes, false);
  }
  // Usable in the stream's order: an unordered use elsewhere is a hazard
  // against this marker write.
  DeviceStreamHandle* s = stream;
  impl_->enqueue(stream, 0.0, [this, p, bytes, s] {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->access_locked(p, bytes, true, *s, "alloc_async", true);
  });
  return p;
}

void SimDevice::free_async(void* p, DeviceStream stream) {
  if (!p) return;
  DeviceStreamHandle* s = stream;
  impl_->enqueue(stream, 0.0, [this, p, s] {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    Allocation* a = impl_->find_locked(p);
    if (!a) {
      impl_->hazard_locked("free_async of a bad pointer");
      return;
    }
    impl_->access_locked(p, a->bytes, true, *s, "free_async", true);
    impl_->release_locked(*a);
  });
}

void* SimDevice::alloc_pinned(size_t bytes) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->allocate_locked(bytes, true);
}

void SimDevice::free_pinned(void* p) {
  if (!p) return;
  std::unique_lock<std::mutex> lock(impl_->mutex);
  impl_->drain_all_locked(lock);
  Allocation* a = impl_->find_locked(p);
  if (!a || !a->pinned)
    throw DeviceError(DeviceFault::kOther, "simulated GPU: free_pinned of a bad pointer");
  impl_->release_locked(*a);
}

DeviceStream SimDevice::create_stream() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto s = std::make_unique<DeviceStreamHandle>();
  s->agent = impl_->next_agent++;
  DeviceStreamHandle* raw = s.get();
  raw->worker = std::thread([this, raw] { impl_->run_stream(raw); });
  impl_->streams.push_back(std::move(s));
  ++impl_->report.live_streams;
  return raw;
}

void SimDevice::destroy_stream(DeviceStream stream) {
  if (!stream) return;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (!stream->live) return;
    stream->stopping = true;
    stream->work.notify_one();
  }
  stream->worker.join();  // after the queue drained
  std::lock_guard<std::mutex> lock(impl_->mutex);
  stream->live = false;
  --impl_->report.live_streams;
}

DeviceEvent SimDevice::create_event(bool timing) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto e = std::make_unique<DeviceEventHandle>();
  e->timing = timing;
  DeviceEventHandle* raw = e.get();
  impl_->events.push_back(std::move(e));
  ++impl_->report.live_events;
  return raw;
}

void SimDevice::destroy_event(DeviceEvent event) {
  if (!event) return;
  // The handle itself lives until the device goes: operations still queued
  // may refer to it, as CUDA allows.
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!event->live) return;
  event->live = false;
  --impl_->report.live_events;
}

void SimDevice::record(DeviceEvent event, DeviceStream stream) {
  uint64_t g;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (!event || !event->live)
      throw DeviceError(DeviceFault::kOther, "simulated GPU: record of a bad event");
    g = ++event->recorded;
  }
  DeviceStreamHandle* s = stream;
  impl_->enqueue(stream, 0.0, [this, event, g, s] {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    event->completed = std::max(event->completed, g);
    event->records[g] = DeviceEventHandle::Record{s->vc, Clock::now()};
    while (event->records.size() > 16)
      event->records.erase(event->records.begin());
    impl_->progress.notify_all();
  });
}

void SimDevice::wait(DeviceStream stream, DeviceEvent event) {
  uint64_t g;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (!event || !event->live)
      throw DeviceError(DeviceFault::kOther, "simulated GPU: wait on a bad event");
    g = event->recorded;  // CUDA: the most recent record at the time of the call
  }
  if (g == 0) return;
  DeviceStreamHandle* s = stream;
  impl_->enqueue(stream, 0.0, [this, event, g, s] {
    std::unique_lock<std::mutex> lock(impl_->mutex);
    impl_->progress.wait(lock, [&] { return event->completed >= g; });
    if (const VectorClock* vc = impl_->event_clock_locked(*event, g)) s->vc.join(*vc);
  });
}

void SimDevice::synchronize(DeviceEvent event) {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  if (!event || !event->live)
    throw DeviceError(DeviceFault::kOther, "simulated GPU: synchronize on a bad event");
  const uint64_t g = event->recorded;
  if (event->completed < g) {
    ++impl_->report.host_waits;
    impl_->progress.wait(lock, [&] { return event->completed >= g; });
  }
  if (const VectorClock* vc = impl_->event_clock_locked(*event, g))
    impl_->host_clock_locked().join(*vc);
}

void SimDevice::synchronize(DeviceStream stream) {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  if (!stream || !stream->live)
    throw DeviceError(DeviceFault::kOther, "simulated GPU: synchronize on a bad stream");
  const uint64_t target = stream->enqueued;
  if (stream->done < target) {
    ++impl_->report.host_waits;
    impl_->progress.wait(lock, [&] { return stream->done >= target; });
  }
  impl_->host_clock_locked().join(stream->vc);
}

double SimDevice::elapsed_seconds(DeviceEvent from, DeviceEvent to) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  for (DeviceEvent e : {from, to}) {
    if (!e || !e->live || !e->timing || e->records.empty() || e->completed < e->recorded)
      throw DeviceError(DeviceFault::kOther,
                        "simulated GPU: elapsed time of an incomplete or non-timing event");
  }
  return std::chrono::duration<double>(to->records.rbegin()->second.when -
                                       from->records.rbegin()->second.when)
      .count();
}

void SimDevice::copy_to_device(void* dst, const void* src, size_t bytes, DeviceStream stream) {
  impl_->copy(dst, src, bytes, stream, true);
}

void SimDevice::copy_to_host(void* dst, const void* src, size_t bytes, DeviceStream stream) {
  impl_->copy(dst, src, bytes, stream, false);
}

void SimDevice::zero(void* dst, size_t bytes, DeviceStream stream) {
  DeviceStreamHandle* s = stream;
  impl_->enqueue(stream, 0.0, [this, dst, bytes, s] {
    bool ok;
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      const uint64_t before = impl_->hazards_seen;
      impl_->access_locked(dst, bytes, true, *s, "zero", true);
      ok = impl_->hazards_seen == before;
    }
    if (ok) std::memset(dst, 0, bytes);
  });
}

DeviceProperties SimDevice::properties() const {
  // Small: tests see the wavefront's 512 slots regenerated many times per
  // batch, and persistent kernels run as two blocks.
  return DeviceProperties{2, 64};
}

uint32_t SimDevice::resident_blocks(DeviceKernel, uint32_t block_threads) {
  return std::max<uint32_t>(1, properties().max_threads_per_multiprocessor / block_threads);
}

void SimDevice::launch(DeviceKernel kernel, const LaunchDims& dims, const void* args,
                       size_t args_bytes, DeviceStream stream) {
  const EmulatedKernelTable& table = emulated_kernels();
  if (args_bytes != table.kernels[uint32_t(kernel)].args_bytes)
    throw std::logic_error(std::string("simulated GPU: launch of ") + device_kernel_name(kernel) +
                           " with arguments of the wrong size");
  // The arguments are the launch's, as CUDA copies them at the call.
  auto copy = std::make_shared<std::vector<unsigned char>>(
      static_cast<const unsigned char*>(args),
      static_cast<const unsigned char*>(args) + args_bytes);
  DeviceStreamHandle* s = stream;
  impl_->launch(
      stream, device_kernel_name(kernel),
      [=, this] { return impl_->kernel_accesses_locked(kernel, copy->data(), *s); },
      [=, this] {
        EmulatedLaunch launch;
        launch.kernel = kernel;
        launch.args = copy->data();
        launch.dims = dims;
        launch.memory = impl_->device_memory();
        const std::vector<std::string> faults = run_emulated_grid(launch);
        std::lock_guard<std::mutex> lock(impl_->mutex);
        for (const std::string& f : faults)
          impl_->hazard_locked("kernel fault: " + f);
      });
}

}  // namespace tandem
