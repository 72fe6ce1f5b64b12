// The wavefront path tracer's stages (core/kernel/wavefront.h), one kernel
// each, in the order the host driver (device_launch.cpp) launches them every
// round. extend and connect trace with persistent threads; shade_miss,
// shade_hit and retire cover the slots and stop past their queue's length.
// Queue lengths stay in device memory, so a kernel of a round after the
// batch ended reads an empty queue and returns at once, before it touches
// anything else.
#include "backends/cuda/device_exec.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/wavefront.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

template <class Exec>
TANDEM_DEVICE_FN void WaveFill::run(Exec& ex, const Args& a) {
  const KernelData& kd = load_kernel_data(ex, a.kd);
  const uint64_t slot = ex.global_x();
  if (slot < a.w.slots) wavefront_regenerate(kd, a.batch, a.w, kWavefrontFillRound, uint32_t(slot));
}

template <class Exec>
TANDEM_DEVICE_FN void WaveBeginRound::run(Exec&, const Args& a) {
  wavefront_begin_round(a.w);
}

// A stage over the `length` entries of its queue: one thread per entry, or
// (`taken`: the persistent threads' counter) persistent threads. A queue
// that is empty (the same for every thread of the grid) ends the kernel
// before it reads anything else.
template <class Exec, class F>
TANDEM_DEVICE_FN void over_queue(Exec& ex, const WaveArgs& a, WavefrontCounter length,
                                 const F& stage) {
  const uint32_t n = a.w.counters[length];
  if (n == 0) return;
  const KernelData& kd = load_kernel_data(ex, a.kd);
  const uint64_t i = ex.global_x();
  if (i < n) stage(kd, uint32_t(i));
}
template <class Exec, class F>
TANDEM_DEVICE_FN void over_queue_persistent(Exec& ex, const WaveArgs& a, WavefrontCounter length,
                                            WavefrontCounter taken, const F& stage) {
  const uint32_t n = a.w.counters[length];
  if (n == 0) return;
  const KernelData& kd = load_kernel_data(ex, a.kd);
  const BvhTracer tracer{&kd};
  persistent_loop(ex, n, &a.w.counters[taken], [&](uint32_t i) { stage(tracer, i); });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveExtend::run(Exec& ex, const Args& a) {
  over_queue_persistent(ex, a, kWaveExtend, kWaveExtendTaken, [&](const BvhTracer& t, uint32_t i) {
    wavefront_extend(t, a.w, a.round, i);
  });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveShadeMiss::run(Exec& ex, const Args& a) {
  over_queue(ex, a, kWaveMiss, [&](const KernelData& kd, uint32_t i) {
    wavefront_shade_miss(kd, a.batch, a.w, a.round, i, a.radiance);
  });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveShadeHit::run(Exec& ex, const Args& a) {
  over_queue(ex, a, kWaveHit, [&](const KernelData& kd, uint32_t i) {
    wavefront_shade_hit(kd, a.batch, a.w, a.round, i, a.radiance);
  });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveConnect::run(Exec& ex, const Args& a) {
  over_queue_persistent(ex, a, kWaveShadow, kWaveConnectTaken, [&](const BvhTracer& t, uint32_t i) {
    wavefront_connect(t, a.w, a.round, i);
  });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveRetire::run(Exec& ex, const Args& a) {
  over_queue(ex, a, kWaveRetire, [&](const KernelData& kd, uint32_t i) {
    wavefront_retire_ended(kd, a.batch, a.w, a.round, i, a.radiance);
  });
}

template <class Exec>
TANDEM_DEVICE_FN void WaveCountRays::run(Exec& ex, const Args& a) {
  ex.atomic_add(a.ray_count, static_cast<unsigned long long>(a.w.counters[kWaveRays]));
}

TANDEM_KERNEL_END
}  // namespace tandem

TANDEM_KERNEL_REGISTRY(wavefront) {
  register_kernels<WaveFill, WaveBeginRound, WaveExtend, WaveShadeMiss, WaveShadeHit, WaveConnect,
                   WaveRetire, WaveCountRays>(table);
}
