// The CUDA backend's kernels, by name: what DeviceOps::launch() takes and
// what both executors (the CUDA GPU and the simulated device's emulated
// grid) register. Plain types only, no kernel headers: the emulated build's
// files include it next to their own copy of the kernel code.
#pragma once

#include <cstdint>

namespace tandem {

// X(enumerator, name): every kernel of device_kernels.h.
#define TANDEM_DEVICE_KERNELS(X)        \
  X(Megakernel, "megakernel")           \
  X(WaveFill, "wave_fill")              \
  X(WaveBeginRound, "wave_begin_round") \
  X(WaveExtend, "wave_extend")          \
  X(WaveShadeMiss, "wave_shade_miss")   \
  X(WaveShadeHit, "wave_shade_hit")     \
  X(WaveConnect, "wave_connect")        \
  X(WaveRetire, "wave_retire")          \
  X(WaveCountRays, "wave_count_rays")   \
  X(TraceRays, "trace_rays")            \
  X(ReduceSamples, "reduce_samples")    \
  X(AccumulateFilm, "accumulate_film")  \
  X(ResolveFilm, "resolve_film")        \
  X(ToneMapFilm, "tone_map_film")       \
  X(Features, "features")               \
  X(SvgfTemporal, "svgf_temporal")      \
  X(SvgfVariance, "svgf_variance")      \
  X(SvgfAtrous, "svgf_atrous")          \
  X(SvgfModulate, "svgf_modulate")

// X(name): the .cu files, each of which registers its kernels with
// TANDEM_KERNEL_REGISTRY(name) (device_exec.h) in both executors' tables.
#define TANDEM_DEVICE_KERNEL_FILES(X) X(megakernel) X(ray_query) X(wavefront) X(film) X(svgf)

enum class DeviceKernel : uint32_t {
#define TANDEM_DEVICE_KERNEL_ENUMERATOR(name, text) k##name,
  TANDEM_DEVICE_KERNELS(TANDEM_DEVICE_KERNEL_ENUMERATOR)
#undef TANDEM_DEVICE_KERNEL_ENUMERATOR
};
#define TANDEM_DEVICE_KERNEL_ONE(name, text) +1
constexpr uint32_t kDeviceKernelCount = 0 TANDEM_DEVICE_KERNELS(TANDEM_DEVICE_KERNEL_ONE);
#undef TANDEM_DEVICE_KERNEL_ONE

inline const char* device_kernel_name(DeviceKernel kernel) {
  static constexpr const char* kNames[] = {
#define TANDEM_DEVICE_KERNEL_NAME(name, text) text,
      TANDEM_DEVICE_KERNELS(TANDEM_DEVICE_KERNEL_NAME)
#undef TANDEM_DEVICE_KERNEL_NAME
  };
  const auto i = uint32_t(kernel);
  return i < kDeviceKernelCount ? kNames[i] : "unknown kernel";
}

// A launch's grid (in blocks) and block (in threads), as CUDA's dim3.
struct DeviceDim3 {
  uint32_t x = 1, y = 1, z = 1;
  uint64_t count() const { return uint64_t(x) * y * z; }
};
struct LaunchDims {
  DeviceDim3 grid, block;
};

}  // namespace tandem
