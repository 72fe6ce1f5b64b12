// The wavefront pipeline of core/kernel/wavefront.h on the CPU: every stage
// a TBB loop over its queue, in the order the GPU launches its kernels. The
// host backend renders with it (--kernel wavefront) and the simulated GPU
// runs the CUDA backend's wavefront variant with it, so CI runs the GPU's
// queue logic and checks that it gives the megakernel's bits.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <vector>

#include "core/kernel/wavefront.h"

namespace tandem {

// Host storage of a pipeline's arrays.
class CpuWavefrontStorage {
 public:
  WavefrontArrays arrays(uint32_t slots) {
    if (paths_.size() < slots) {
      paths_.resize(slots);
      hits_.resize(slots);
      shadows_.resize(slots);
      for (std::vector<uint32_t>* v :
           {&slot_item_, &extend_[0], &extend_[1], &hit_, &miss_, &shadow_, &retire_})
        v->resize(slots);
    }
    WavefrontArrays w;
    w.paths = paths_.data();
    w.hits = hits_.data();
    w.shadows = shadows_.data();
    w.slot_item = slot_item_.data();
    w.extend_queues[0] = extend_[0].data();
    w.extend_queues[1] = extend_[1].data();
    w.hit_queue = hit_.data();
    w.miss_queue = miss_.data();
    w.shadow_queue = shadow_.data();
    w.retire_queue = retire_.data();
    w.counters = counters_.data();
    w.slots = slots;
    return w;
  }

 private:
  std::vector<PathState> paths_;
  std::vector<Hit> hits_;
  std::vector<ShadowRay> shadows_;
  std::vector<uint32_t> slot_item_, extend_[2], hit_, miss_, shadow_, retire_;
  std::array<uint32_t, kWaveCounterCount> counters_{};
};

namespace detail {
template <class F>
void parallel_over(uint32_t n, const F& f) {
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, 64),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      for (uint32_t i = r.begin(); i != r.end(); ++i)
                        f(i);
                    });
}
}  // namespace detail

// Traces every item of `batch` into radiance[item] with the w.slots paths
// of `w` in flight; returns the rays traced.
template <class Tracer>
uint64_t run_wavefront_on_cpu(const KernelData& kd, const Tracer& tracer, const TileBatch& batch,
                              const WavefrontArrays& w, Vec3* radiance) {
  const uint32_t slots = w.slots;
  if (slots == 0 || batch.items() == 0) return 0;
  std::fill(w.counters, w.counters + kWaveCounterCount, 0u);
  detail::parallel_over(
      slots, [&](uint32_t s) { wavefront_regenerate(kd, batch, w, kWavefrontFillRound, s); });
  for (uint32_t round = 0;; ++round) {
    wavefront_begin_round(w);
    const uint32_t n = w.counters[kWaveExtend];
    if (n == 0) break;
    detail::parallel_over(n, [&](uint32_t i) { wavefront_extend(tracer, w, round, i); });
    detail::parallel_over(w.counters[kWaveMiss], [&](uint32_t i) {
      wavefront_shade_miss(kd, batch, w, round, i, radiance);
    });
    detail::parallel_over(w.counters[kWaveHit], [&](uint32_t i) {
      wavefront_shade_hit(kd, batch, w, round, i, radiance);
    });
    detail::parallel_over(w.counters[kWaveShadow],
                          [&](uint32_t i) { wavefront_connect(tracer, w, round, i); });
    detail::parallel_over(w.counters[kWaveRetire], [&](uint32_t i) {
      wavefront_retire_ended(kd, batch, w, round, i, radiance);
    });
  }
  return w.counters[kWaveRays];
}

// The same with at most `max_slots` paths in host storage.
template <class Tracer>
uint64_t run_wavefront_on_cpu(const KernelData& kd, const Tracer& tracer, const TileBatch& batch,
                              uint32_t max_slots, CpuWavefrontStorage& storage, Vec3* radiance) {
  const uint32_t slots = uint32_t(std::min<uint64_t>(batch.items(), max_slots));
  return run_wavefront_on_cpu(kd, tracer, batch, storage.arrays(slots), radiance);
}

}  // namespace tandem
