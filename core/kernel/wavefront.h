// Wavefront path tracing (Laine, Karras & Aila 2013, "Megakernels
// Considered Harmful"; van Antwerpen 2011): the integrator's stages
// (integrator.h) run over queues of paths instead of one path per thread, so
// that each stage is a small kernel whose threads all do the same kind of
// work. Written once: the GPU runs each function below as a kernel over a
// queue, the host runs them with TBB over the same queues (cpu_wavefront.h),
// so CI runs the GPU's control flow.
//
// A batch is `items` pixel samples (TileBatch numbering). A fixed number of
// path slots works through them, round after round:
//   extend    traces the ray of every slot in the extend queue and sorts the
//             slot into the hit or the miss queue;
//   shade     shades misses (the path ends) and hits (emission, a light
//             sample into the shadow queue, the next ray);
//   connect   traces the shadow rays and adds the unoccluded light samples;
//   retire    writes the radiance of the paths that ended in connect;
// and every path that goes on is appended to the next round's extend queue.
// A slot whose path ended writes the sample's radiance and takes the next
// item of the batch (regeneration), so the queues stay full until the batch
// runs dry. Queues are compacted lists of slot indices appended to with one
// atomic each; their lengths stay in device memory (kernels past the length
// exit at once), so the host reads one counter only to decide when to stop.
// Every item's path is computed exactly as by the megakernel: the radiance
// of each item, and so the image, are the same bits.
#pragma once

#include "core/kernel/gpu_intrinsics.h"
#include "core/kernel/integrator.h"
#include "core/kernel/tile_batch.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

enum WavefrontCounter : uint32_t {
  kWaveExtend = 0,    // entries in this round's extend queue
  kWaveNextExtend,    // entries appended to the next round's extend queue
  kWaveHit,           // entries in the hit queue
  kWaveMiss,          // entries in the miss queue
  kWaveShadow,        // entries in the shadow queue
  kWaveRetire,        // entries in the retire queue (paths that ended in connect)
  kWaveNextItem,      // next batch item for a free slot
  kWaveRays,          // rays traced (closest hit and shadow) by retired paths
  kWaveExtendTaken,   // persistent threads' work counter for extend
  kWaveConnectTaken,  // and for connect
  kWaveCounterCount,
};

// The arrays of a pipeline of `slots` path slots: device memory on the GPU,
// host memory on the CPU. The two extend queues alternate between rounds.
struct WavefrontArrays {
  PathState* paths;
  Hit* hits;
  ShadowRay* shadows;
  uint32_t* slot_item;  // the batch item a slot works on
  uint32_t* extend_queues[2];
  uint32_t* hit_queue;
  uint32_t* miss_queue;
  uint32_t* shadow_queue;
  uint32_t* retire_queue;
  uint32_t* counters;  // WavefrontCounter
  uint32_t slots;
};

// The arrays of `slots` slots carved out of one block of memory at `base`
// (16-byte aligned); with base = null, only `*bytes` is computed.
TANDEM_HD WavefrontArrays wavefront_arrays_in(void* base, uint32_t slots, uint64_t* bytes) {
  WavefrontArrays w{};
  uint64_t offset = 0;
  auto take = [&](uint64_t size) {
    unsigned char* p = base ? static_cast<unsigned char*>(base) + offset : nullptr;
    offset += (size + 15u) & ~uint64_t(15u);
    return p;
  };
  w.paths = reinterpret_cast<PathState*>(take(uint64_t(slots) * sizeof(PathState)));
  w.hits = reinterpret_cast<Hit*>(take(uint64_t(slots) * sizeof(Hit)));
  w.shadows = reinterpret_cast<ShadowRay*>(take(uint64_t(slots) * sizeof(ShadowRay)));
  w.slot_item = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  for (uint32_t*& q : w.extend_queues)
    q = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  w.hit_queue = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  w.miss_queue = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  w.shadow_queue = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  w.retire_queue = reinterpret_cast<uint32_t*>(take(uint64_t(slots) * sizeof(uint32_t)));
  w.counters = reinterpret_cast<uint32_t*>(take(kWaveCounterCount * sizeof(uint32_t)));
  w.slots = slots;
  *bytes = offset;
  return w;
}

TANDEM_HD uint32_t wavefront_add(uint32_t* counter, uint32_t n) {
#if TANDEM_GPU_CODE
  return gpu_atomic_add(counter, n);
#else
  return __atomic_fetch_add(counter, n, __ATOMIC_RELAXED);
#endif
}

TANDEM_HD void wavefront_push(uint32_t* queue, uint32_t* counter, uint32_t slot) {
  queue[wavefront_add(counter, 1u)] = slot;
}

// The queues of round `round`: the extend queue it reads and the one it fills.
TANDEM_HD uint32_t* wavefront_extend_queue(const WavefrontArrays& w, uint32_t round) {
  return w.extend_queues[round & 1u];
}
TANDEM_HD uint32_t* wavefront_next_extend_queue(const WavefrontArrays& w, uint32_t round) {
  return w.extend_queues[(round + 1u) & 1u];
}

// Takes the next item of the batch for `slot` and queues its camera ray for
// the next round's extension; leaves the slot idle once the batch is dry.
TANDEM_HD void wavefront_regenerate(const KernelData& kd, const TileBatch& batch,
                                    const WavefrontArrays& w, uint32_t round, uint32_t slot) {
  const uint32_t item = wavefront_add(&w.counters[kWaveNextItem], 1u);
  if (uint64_t(item) >= batch.items()) return;
  uint32_t x, y, sample;
  batch_item(batch, item, &x, &y, &sample);
  w.slot_item[slot] = item;
  path_generate(kd, x, y, sample, &w.paths[slot]);
  wavefront_push(wavefront_next_extend_queue(w, round), &w.counters[kWaveNextExtend], slot);
}

// Before a round: the queue filled last round becomes the one to extend.
// One thread.
TANDEM_HD void wavefront_begin_round(const WavefrontArrays& w) {
  w.counters[kWaveExtend] = w.counters[kWaveNextExtend];
  w.counters[kWaveNextExtend] = 0;
  w.counters[kWaveHit] = w.counters[kWaveMiss] = w.counters[kWaveShadow] = 0;
  w.counters[kWaveRetire] = 0;
  w.counters[kWaveExtendTaken] = w.counters[kWaveConnectTaken] = 0;
}

// The round number the initial fill of the slots uses: its "next" extend
// queue is round 0's extend queue.
constexpr uint32_t kWavefrontFillRound = ~0u;

// A path that ended: its radiance, then the slot takes new work.
TANDEM_HD void wavefront_retire(const KernelData& kd, const TileBatch& batch,
                                const WavefrontArrays& w, uint32_t round, uint32_t slot,
                                Vec3* radiance) {
  const PathState& p = w.paths[slot];
  radiance[w.slot_item[slot]] = path_finish(kd, p);
  wavefront_add(&w.counters[kWaveRays], p.rays);
  wavefront_regenerate(kd, batch, w, round, slot);
}

// extend, entry i of this round's extend queue: the ray to trace and its
// alpha key, then what to do with the closest hit. Split so that a tracer
// that takes packets of rays (Embree's rtcIntersect16) can serve many
// entries at once.
TANDEM_HD const Ray& wavefront_extend_ray(const WavefrontArrays& w, uint32_t round, uint32_t i,
                                          uint32_t* alpha_key) {
  const PathState& p = w.paths[wavefront_extend_queue(w, round)[i]];
  *alpha_key = path_alpha_key(p);
  return p.ray;
}
TANDEM_HD void wavefront_extend_done(const WavefrontArrays& w, uint32_t round, uint32_t i,
                                     const Hit& hit) {
  const uint32_t slot = wavefront_extend_queue(w, round)[i];
  ++w.paths[slot].rays;
  w.hits[slot] = hit;
  if (hit_valid(hit))
    wavefront_push(w.hit_queue, &w.counters[kWaveHit], slot);
  else
    wavefront_push(w.miss_queue, &w.counters[kWaveMiss], slot);
}
template <class Tracer>
TANDEM_HD void wavefront_extend(const Tracer& tracer, const WavefrontArrays& w, uint32_t round,
                                uint32_t i) {
  uint32_t key;
  const Ray& ray = wavefront_extend_ray(w, round, i, &key);
  wavefront_extend_done(w, round, i, tracer.intersect(ray, key));
}

// shade, entry i of the miss queue: the environment, and the path ends.
TANDEM_HD void wavefront_shade_miss(const KernelData& kd, const TileBatch& batch,
                                    const WavefrontArrays& w, uint32_t round, uint32_t i,
                                    Vec3* radiance) {
  const uint32_t slot = w.miss_queue[i];
  path_shade_miss(kd, &w.paths[slot]);
  wavefront_retire(kd, batch, w, round, slot, radiance);
}

// shade, entry i of the hit queue.
TANDEM_HD void wavefront_shade_hit(const KernelData& kd, const TileBatch& batch,
                                   const WavefrontArrays& w, uint32_t round, uint32_t i,
                                   Vec3* radiance) {
  const uint32_t slot = w.hit_queue[i];
  PathState& p = w.paths[slot];
  if (path_shade_hit(kd, w.hits[slot], &p, &w.shadows[slot])) {
    // The light sample's result comes before the path's next hit: connect
    // decides where the path goes.
    wavefront_push(w.shadow_queue, &w.counters[kWaveShadow], slot);
  } else if (path_alive(p)) {
    wavefront_push(wavefront_next_extend_queue(w, round), &w.counters[kWaveNextExtend], slot);
  } else {
    wavefront_retire(kd, batch, w, round, slot, radiance);
  }
}

// connect, entry i of the shadow queue: the shadow ray, then what its
// answer means. A path that ended goes to the retire queue: retiring
// generates the next camera ray, which would bloat this traversal kernel.
TANDEM_HD const ShadowRay& wavefront_connect_ray(const WavefrontArrays& w, uint32_t i) {
  return w.shadows[w.shadow_queue[i]];
}
TANDEM_HD void wavefront_connect_done(const WavefrontArrays& w, uint32_t round, uint32_t i,
                                      bool occluded) {
  const uint32_t slot = w.shadow_queue[i];
  PathState& p = w.paths[slot];
  ++p.rays;
  path_shadow_result(w.shadows[slot], occluded, &p);
  if (path_alive(p))
    wavefront_push(wavefront_next_extend_queue(w, round), &w.counters[kWaveNextExtend], slot);
  else
    wavefront_push(w.retire_queue, &w.counters[kWaveRetire], slot);
}
template <class Tracer>
TANDEM_HD void wavefront_connect(const Tracer& tracer, const WavefrontArrays& w, uint32_t round,
                                 uint32_t i) {
  const ShadowRay& shadow = wavefront_connect_ray(w, i);
  wavefront_connect_done(w, round, i, tracer.occluded(shadow.ray, shadow.alpha_key));
}

// retire, entry i of the retire queue.
TANDEM_HD void wavefront_retire_ended(const KernelData& kd, const TileBatch& batch,
                                      const WavefrontArrays& w, uint32_t round, uint32_t i,
                                      Vec3* radiance) {
  wavefront_retire(kd, batch, w, round, w.retire_queue[i], radiance);
}

TANDEM_KERNEL_END
}  // namespace tandem
