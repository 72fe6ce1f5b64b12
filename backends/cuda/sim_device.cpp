#include "backends/cuda/sim_device.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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

#include "backends/cpu_loops/cpu_wavefront.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/features.h"
#include "core/kernel/integrator.h"

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
    for (;;) {
      s->work.wait(lock, [&] { return s->stopping || !s->queue.empty(); });
      if (s->queue.empty()) return;
      DeviceStreamHandle::Op op = std::move(s->queue.front());
      s->queue.pop_front();
      s->vc.join(op.enqueuer);
      s->vc.tick(s->agent);
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::duration<double>(op.seconds));
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
    for (auto& s : streams) {
      if (!s->live) continue;
      const uint64_t target = s->enqueued;
      progress.wait(lock, [&] { return s->done >= target; });
      host_clock_locked().join(s->vc);
    }
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

void SimDevice::trace_samples(const KernelData* kd, const TileBatch& batch,
                              CudaKernelVariant variant, const WavefrontArrays& wave,
                              Vec3* radiance, unsigned long long* ray_count, DeviceStream stream) {
  if (batch.items() == 0) return;
  DeviceStreamHandle* s = stream;
  auto local = std::make_shared<KernelData>();
  impl_->launch(
      stream, "trace_samples",
      [=, this] {
        *local = impl_->read_kernel_data_locked(kd, *s, "trace_samples");
        impl_->access_locked(batch.tiles, batch.tile_count * sizeof(DeviceTile), false, *s,
                             "trace_samples reads tiles", true);
        impl_->access_locked(radiance, batch.items() * sizeof(Vec3), true, *s,
                             "trace_samples writes radiance", true);
        impl_->access_locked(ray_count, sizeof(*ray_count), true, *s, "trace_samples counts rays",
                             true);
        if (variant == CudaKernelVariant::kWavefront) {
          const uint32_t slots = uint32_t(std::min<uint64_t>(batch.items(), wavefront_slots()));
          if (wave.slots < slots) {
            impl_->hazard_locked("trace_samples: wavefront arrays hold fewer slots than needed");
            return false;
          }
          impl_->access_locked(wave.paths, slots * sizeof(PathState), true, *s,
                               "wavefront writes paths", true);
          impl_->access_locked(wave.counters, kWaveCounterCount * sizeof(uint32_t), true, *s,
                               "wavefront counts", true);
          for (uint32_t* q : {wave.extend_queues[0], wave.extend_queues[1], wave.hit_queue,
                              wave.miss_queue, wave.shadow_queue, wave.slot_item})
            impl_->access_locked(q, slots * sizeof(uint32_t), true, *s, "wavefront queues", true);
        }
        return true;
      },
      [=, this] {
        const KernelData& k = *local;
        if (variant == CudaKernelVariant::kWavefront) {
          WavefrontArrays w = wave;
          w.slots = uint32_t(std::min<uint64_t>(batch.items(), wavefront_slots()));
          *ray_count += run_wavefront_on_cpu(k, BvhTracer{&k}, batch, w, radiance);
          return;
        }
        std::atomic<uint64_t> rays{0};
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, batch.items(), 64),
                          [&](const tbb::blocked_range<uint64_t>& r) {
                            uint64_t n = 0;
                            for (uint64_t item = r.begin(); item != r.end(); ++item) {
                              uint32_t x, y, sample, traced = 0;
                              batch_item(batch, item, &x, &y, &sample);
                              radiance[item] =
                                  render_pixel_sample(k, BvhTracer{&k}, x, y, sample, &traced);
                              n += traced;
                            }
                            rays += n;
                          });
        *ray_count += rays.load();
      });
}

void SimDevice::reduce_samples(const TileBatch& batch, const Vec3* radiance, double* pixel_sums,
                               DeviceStream stream) {
  if (batch.pixel_count == 0) return;
  DeviceStreamHandle* s = stream;
  impl_->launch(
      stream, "reduce_samples",
      [=, this] {
        impl_->access_locked(radiance, batch.items() * sizeof(Vec3), false, *s,
                             "reduce_samples reads radiance", true);
        impl_->access_locked(pixel_sums, 3 * sizeof(double) * batch.pixel_count, true, *s,
                             "reduce_samples adds to pixel sums", true);
        return true;
      },
      [=] {
        for (uint32_t p = 0; p < batch.pixel_count; ++p)
          reduce_pixel_samples(batch, radiance, p, pixel_sums);
      });
}

void SimDevice::accumulate_film(const TileBatch& batch, const double* pixel_sums,
                                uint32_t sample_count, const DeviceFilmView& film,
                                DeviceStream stream) {
  if (batch.pixel_count == 0) return;
  DeviceStreamHandle* s = stream;
  const size_t pixels = size_t(film.width) * film.height;
  impl_->launch(
      stream, "accumulate_film",
      [=, this] {
        impl_->access_locked(batch.tiles, batch.tile_count * sizeof(DeviceTile), false, *s,
                             "accumulate_film reads tiles", true);
        impl_->access_locked(pixel_sums, 3 * sizeof(double) * batch.pixel_count, false, *s,
                             "accumulate_film reads pixel sums", true);
        impl_->access_locked(film.sums, 3 * sizeof(double) * pixels, true, *s,
                             "accumulate_film adds to the film", true);
        impl_->access_locked(film.samples, sizeof(uint32_t) * pixels, true, *s,
                             "accumulate_film counts samples", true);
        return true;
      },
      [=] {
        for (uint32_t p = 0; p < batch.pixel_count; ++p)
          accumulate_film_pixel(batch, pixel_sums, sample_count, film, p);
      });
}

void SimDevice::resolve_film(const DeviceFilmView& film, float* rgb, DeviceStream stream) {
  const size_t pixels = size_t(film.width) * film.height;
  if (pixels == 0) return;
  DeviceStreamHandle* s = stream;
  impl_->launch(
      stream, "resolve_film",
      [=, this] {
        impl_->access_locked(film.sums, 3 * sizeof(double) * pixels, false, *s,
                             "resolve_film reads the film", true);
        impl_->access_locked(film.samples, sizeof(uint32_t) * pixels, false, *s,
                             "resolve_film reads sample counts", true);
        impl_->access_locked(rgb, 3 * sizeof(float) * pixels, true, *s, "resolve_film writes",
                             true);
        return true;
      },
      [=] {
        for (size_t i = 0; i < pixels; ++i)
          film_pixel_mean(film, i, &rgb[3 * i]);
      });
}

void SimDevice::tone_map_film(const DeviceFilmView& film, float exposure_scale, uint32_t curve,
                              uint8_t* rgb8, DeviceStream stream) {
  const size_t pixels = size_t(film.width) * film.height;
  if (pixels == 0) return;
  DeviceStreamHandle* s = stream;
  impl_->launch(
      stream, "tone_map_film",
      [=, this] {
        impl_->access_locked(film.sums, 3 * sizeof(double) * pixels, false, *s,
                             "tone_map_film reads the film", true);
        impl_->access_locked(film.samples, sizeof(uint32_t) * pixels, false, *s,
                             "tone_map_film reads sample counts", true);
        impl_->access_locked(rgb8, 3 * pixels, true, *s, "tone_map_film writes", true);
        return true;
      },
      [=] {
        for (size_t i = 0; i < pixels; ++i)
          tone_map_film_pixel(film, i, exposure_scale, curve, rgb8);
      });
}

void SimDevice::trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* alpha_keys,
                           uint32_t n, bool any_hit, Hit* hits, uint32_t* work_counter,
                           DeviceStream stream) {
  if (n == 0) return;
  DeviceStreamHandle* s = stream;
  auto local = std::make_shared<KernelData>();
  impl_->launch(
      stream, "trace_rays",
      [=, this] {
        *local = impl_->read_kernel_data_locked(kd, *s, "trace_rays");
        impl_->access_locked(rays, n * sizeof(Ray), false, *s, "trace_rays reads rays", true);
        if (alpha_keys)
          impl_->access_locked(alpha_keys, n * sizeof(uint32_t), false, *s,
                               "trace_rays reads alpha keys", true);
        impl_->access_locked(hits, n * sizeof(Hit), true, *s, "trace_rays writes hits", true);
        impl_->access_locked(work_counter, sizeof(uint32_t), true, *s, "trace_rays takes work",
                             true);
        return true;
      },
      [=] {
        const KernelData& k = *local;
        tbb::parallel_for(
            tbb::blocked_range<uint32_t>(0, n, 256), [&](const tbb::blocked_range<uint32_t>& r) {
              for (uint32_t i = r.begin(); i != r.end(); ++i)
                hits[i] =
                    bvh_trace(k, rays[i], alpha_keys ? alpha_keys[i] : 0u, k.bvh.layout, any_hit);
            });
        *work_counter = n;
      });
}

void SimDevice::render_features(const KernelData* kd, const FeaturePass& pass, uint32_t width,
                                uint32_t height, PixelFeatures* out, DeviceStream stream) {
  const size_t n = size_t(width) * height;
  if (n == 0) return;
  DeviceStreamHandle* s = stream;
  auto local = std::make_shared<KernelData>();
  impl_->launch(
      stream, "render_features",
      [=, this] {
        *local = impl_->read_kernel_data_locked(kd, *s, "render_features");
        if (local->constants.camera.width != width || local->constants.camera.height != height) {
          impl_->hazard_locked("render_features: film size differs from the scene's camera");
          return false;
        }
        if (pass.prev_object_to_world && pass.prev_instance_count)
          impl_->access_locked(pass.prev_object_to_world, pass.prev_instance_count * sizeof(Mat34),
                               false, *s, "render_features reads previous transforms", true);
        impl_->access_locked(out, n * sizeof(PixelFeatures), true, *s,
                             "render_features writes features", true);
        return true;
      },
      [=] {
        // The same per-pixel code the CUDA kernel and the CPU backends run.
        const KernelData& k = *local;
        tbb::parallel_for(tbb::blocked_range<uint32_t>(0, height, 2),
                          [&](const tbb::blocked_range<uint32_t>& rows) {
                            for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                              for (uint32_t x = 0; x < width; ++x)
                                out[size_t(y) * width + x] =
                                    compute_pixel_features(k, BvhTracer{&k}, pass, x, y);
                          });
      });
}

}  // namespace tandem
