// The CUDA backend's kernels: for each one its arguments (one POD struct,
// passed by value as the kernel's only parameter), its block size and the
// launch bounds it is compiled with, and the declaration of its body, which
// is a template on the execution policy (device_exec.h) defined in a .cu
// file. The host driver (device_launch.h) launches them through
// DeviceOps::launch() with this file's block sizes, and the simulated device
// (sim_device.cpp) records the memory each one touches from its arguments.
// POD structs only; compiled by g++ (host), nvcc and the emulated build.
#pragma once

#include <cstdint>
#include <type_traits>

#include "backends/cuda/batch.h"
#include "backends/cuda/device_kernel_ids.h"
#include "core/kernel/features.h"
#include "core/kernel/kernel_data.h"
#include "core/kernel/svgf.h"
#include "core/kernel/tile_batch.h"
#include "core/kernel/wavefront.h"

// What a kernel body is compiled as: device code under nvcc, a plain
// function in the emulated build.
#if defined(__CUDACC__)
#define TANDEM_DEVICE_FN __device__ __forceinline__
#else
#define TANDEM_DEVICE_FN inline
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

struct MegakernelArgs {
  const KernelData* kd;
  TileBatch batch;
  Vec3* radiance;  // per item of the batch
  unsigned long long* ray_count;
};

// Every stage of the wavefront (core/kernel/wavefront.h) takes the same.
struct WaveArgs {
  const KernelData* kd;
  TileBatch batch;
  WavefrontArrays w;  // w.slots: the slots of this batch
  uint32_t round;
  Vec3* radiance;
  unsigned long long* ray_count;  // WaveCountRays
};

struct TraceRaysArgs {
  const KernelData* kd;
  const Ray* rays;
  const uint32_t* alpha_keys;  // or null
  Hit* hits;
  uint32_t* work_counter;  // zero on entry: the persistent threads' queue position
  uint32_t n;
  uint32_t any_hit;  // 1: occlusion queries (a valid hit means occluded)
};

struct ReduceSamplesArgs {
  TileBatch batch;
  const Vec3* radiance;
  double* pixel_sums;  // 3 per batch pixel, added to
};

struct AccumulateFilmArgs {
  TileBatch batch;
  const double* pixel_sums;
  DeviceFilmView film;
  uint32_t sample_count;
};

struct ResolveFilmArgs {
  DeviceFilmView film;
  float* rgb;  // 3 per film pixel
};

struct ToneMapFilmArgs {
  DeviceFilmView film;
  uint8_t* rgb8;  // 3 per film pixel
  float exposure_scale;
  uint32_t curve;  // ToneMap
};

struct FeaturesArgs {
  const KernelData* kd;  // its camera is width x height
  FeaturePass pass;      // prev_object_to_world in device memory, or null
  PixelFeatures* out;    // width * height
  uint32_t width, height;
};

struct SvgfTemporalArgs {
  SvgfParams params;
  SvgfTemporalBuffers buffers;
};
struct SvgfVarianceArgs {
  SvgfParams params;
  SvgfVarianceBuffers buffers;
};
// One a-trous iteration: `out` (when set) receives the illumination, and
// `radiance` (when set: the last iteration) the albedo-modulated result.
struct SvgfAtrousArgs {
  SvgfParams params;
  SvgfAtrousBuffers buffers;
  Vec4* out;
  const PixelFeatures* features;
  Vec3* radiance;
  uint32_t step;
};
struct SvgfModulateArgs {
  SvgfParams params;
  const PixelFeatures* features;
  const Vec4* illumination;
  Vec3* out;
};

// A kernel: its id, arguments, block size and launch bounds, and its body.
// The bounds: at most kThreads threads per block, and at least kMinBlocks
// blocks resident per multiprocessor, which caps its registers at 65536 /
// (kThreads * kMinBlocks); kMinBlocks 0 states the block size only and
// leaves the registers to ptxas.
#define TANDEM_DEVICE_KERNEL_TRAITS(name, args_type, threads, min_blocks) \
  using Args = args_type;                                                 \
  static constexpr DeviceKernel kId = DeviceKernel::k##name;              \
  static constexpr uint32_t kThreads = threads;                           \
  static constexpr uint32_t kMinBlocks = min_blocks;                      \
  template <class Exec>                                                   \
  TANDEM_DEVICE_FN static void run(Exec& ex, const Args& a);

// megakernel.cu: one thread per pixel sample runs the whole path. Four
// blocks per multiprocessor cap it at 128 registers, which the integrator
// fits without spilling.
struct Megakernel {
  TANDEM_DEVICE_KERNEL_TRAITS(Megakernel, MegakernelArgs, 128, 4)
};

// wavefront.cu: the stages of core/kernel/wavefront.h. The two traversal
// kernels at 8 blocks (64 registers, 50% occupancy on sm_90: traversal is
// bound by memory latency, which more resident warps hide); shade_hit, the
// BSDF's kernel, at 4 (the 104 registers the clear coat and sheen layers
// need without spilling).
struct WaveFill {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveFill, WaveArgs, 128, 0)
};
struct WaveBeginRound {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveBeginRound, WaveArgs, 1, 0)
};
struct WaveExtend {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveExtend, WaveArgs, 128, 8)
};
struct WaveShadeMiss {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveShadeMiss, WaveArgs, 128, 0)
};
struct WaveShadeHit {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveShadeHit, WaveArgs, 128, 4)
};
struct WaveConnect {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveConnect, WaveArgs, 128, 8)
};
struct WaveRetire {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveRetire, WaveArgs, 128, 0)
};
struct WaveCountRays {
  TANDEM_DEVICE_KERNEL_TRAITS(WaveCountRays, WaveArgs, 1, 0)
};

// ray_query.cu: closest hits or occlusion of an array of rays, with
// persistent threads, for tests and benchmarks (the traversal of extend).
struct TraceRays {
  TANDEM_DEVICE_KERNEL_TRAITS(TraceRays, TraceRaysArgs, 128, 8)
};

// film_kernels.cu: the per-pixel reduction of a batch's samples, the
// device film and its tone mapping.
struct ReduceSamples {
  TANDEM_DEVICE_KERNEL_TRAITS(ReduceSamples, ReduceSamplesArgs, 256, 0)
};
struct AccumulateFilm {
  TANDEM_DEVICE_KERNEL_TRAITS(AccumulateFilm, AccumulateFilmArgs, 256, 0)
};
struct ResolveFilm {
  TANDEM_DEVICE_KERNEL_TRAITS(ResolveFilm, ResolveFilmArgs, 256, 0)
};
struct ToneMapFilm {
  TANDEM_DEVICE_KERNEL_TRAITS(ToneMapFilm, ToneMapFilmArgs, 256, 0)
};

// svgf_kernels.cu: the denoiser's feature pass and filter stages, one
// thread per pixel in 16 x 16 blocks (neighbouring pixels share cache
// lines).
constexpr uint32_t kSvgfBlockSide = 16;
struct Features {
  TANDEM_DEVICE_KERNEL_TRAITS(Features, FeaturesArgs, 256, 0)
};
struct SvgfTemporal {
  TANDEM_DEVICE_KERNEL_TRAITS(SvgfTemporal, SvgfTemporalArgs, 256, 0)
};
struct SvgfVariance {
  TANDEM_DEVICE_KERNEL_TRAITS(SvgfVariance, SvgfVarianceArgs, 256, 0)
};
struct SvgfAtrous {
  TANDEM_DEVICE_KERNEL_TRAITS(SvgfAtrous, SvgfAtrousArgs, 256, 0)
};
struct SvgfModulate {
  TANDEM_DEVICE_KERNEL_TRAITS(SvgfModulate, SvgfModulateArgs, 256, 0)
};

#undef TANDEM_DEVICE_KERNEL_TRAITS

// Arguments are copied byte for byte into the launch (and, on the
// simulated device, kept until the kernel runs).
static_assert(std::is_trivially_copyable_v<MegakernelArgs> &&
                  std::is_trivially_copyable_v<WaveArgs> &&
                  std::is_trivially_copyable_v<TraceRaysArgs> &&
                  std::is_trivially_copyable_v<FeaturesArgs> &&
                  std::is_trivially_copyable_v<SvgfAtrousArgs>,
              "kernel arguments are PODs");

TANDEM_KERNEL_END
}  // namespace tandem
