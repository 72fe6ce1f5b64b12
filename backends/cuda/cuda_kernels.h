// Host-side declarations of the CUDA backend's kernel launchers. Each .cu
// file holds a few kernels and includes only the kernel headers it needs, so
// nvcc compiles the heavy integrator instantiations in parallel and a change
// to the film code does not recompile the path tracer.
//
// All launchers enqueue on `stream` and check the launch (cuda_check.h);
// none synchronises.
#pragma once

#include <cuda_runtime_api.h>

#include <cstdint>

#include "core/kernel/kernel_data.h"

namespace tandem {

// A tile of a batch; pixel_offset is the sum of pixel counts of the tiles
// before it, so pixel i of the batch lives in the tile whose range holds i.
struct DeviceTile {
  uint32_t x0, y0, x1, y1;
  uint32_t pixel_offset;
};
static_assert(sizeof(DeviceTile) == 20, "GPU layout: copied byte for byte");

// A batch of tiles and a chunk of samples: work item i is sample
// sample_begin + i / pixel_count of batch pixel i % pixel_count, so
// neighbouring threads trace neighbouring pixels (coherent camera rays).
struct TileBatch {
  const DeviceTile* tiles = nullptr;  // device
  uint32_t tile_count = 0;
  uint32_t pixel_count = 0;
  uint32_t sample_begin = 0;
  uint32_t sample_count = 0;
  TANDEM_HD uint64_t items() const { return uint64_t(pixel_count) * sample_count; }
};

// Megakernel: one thread per pixel sample runs render_pixel_sample with
// BvhTracer and writes the sample's radiance to radiance[item]; rays traced
// are added to *ray_count.
void launch_megakernel(const KernelData* kd, const TileBatch& batch, Vec3* radiance,
                       unsigned long long* ray_count, cudaStream_t stream);

// Wavefront variant (Laine, Karras & Aila 2013), see wavefront.cu for which
// stages are separate kernels. Same outputs as launch_megakernel, bit for
// bit. `scratch` must come from WavefrontScratch::ensure().
struct WavefrontScratch {
  Ray* rays = nullptr;
  uint32_t* alpha_keys = nullptr;
  Hit* hits = nullptr;
  uint32_t* queues = nullptr;    // hit queue at [0, n), miss queue at [n, 2n)
  uint32_t* counters = nullptr;  // work counter, hit count, miss count
  uint64_t capacity = 0;         // items
  void ensure(uint64_t items);
  void release();
};
void launch_wavefront(const KernelData* kd, const TileBatch& batch, WavefrontScratch& scratch,
                      Vec3* radiance, unsigned long long* ray_count, cudaStream_t stream);

// Closest hits (any_hit = false) or occlusion (any_hit = true: a valid hit
// means occluded) of n rays with Tandem's BVH, with persistent threads
// (Aila & Laine 2009). When hit_queue/miss_queue are given, item indices are
// appended to them (compacted) with counts in queue_counts[0..1].
// `work_counter` must be zero on entry.
void launch_trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* alpha_keys,
                       uint32_t n, bool any_hit, Hit* hits, uint32_t* work_counter,
                       uint32_t* hit_queue, uint32_t* miss_queue, uint32_t* queue_counts,
                       cudaStream_t stream);

// Sums the chunk's samples of each batch pixel, in sample order and in
// double precision, onto pixel_sums (3 doubles per batch pixel, which the
// caller zeroes before the first chunk): the same order and precision as
// the CPU's tile loop, so equal samples give equal pixels.
void launch_reduce_samples(const TileBatch& batch, const Vec3* radiance, double* pixel_sums,
                           cudaStream_t stream);

// Device-resident film for GPU-only output: per pixel a double RGB sum and
// a sample count, like the host Film.
struct DeviceFilmView {
  double* sums = nullptr;
  uint32_t* samples = nullptr;
  uint32_t width = 0, height = 0;
};
// Adds a batch's pixel_sums (sample_count samples each) to the film.
void launch_accumulate_film(const TileBatch& batch, const double* pixel_sums, uint32_t sample_count,
                            DeviceFilmView film, cudaStream_t stream);
// Mean radiance per pixel, 3 floats per pixel, row 0 = top.
void launch_resolve_film(DeviceFilmView film, float* rgb, cudaStream_t stream);
// Exposure + tone curve (core/kernel/tone_map.h) + sRGB to 8-bit RGB.
void launch_tone_map_film(DeviceFilmView film, float exposure_scale, uint32_t curve, uint8_t* rgb8,
                          cudaStream_t stream);

// cudaSuccess when this build holds a kernel image (SASS or PTX) the
// current device can run; cudaErrorNoKernelImageForDevice (or similar)
// otherwise.
cudaError_t cuda_probe_kernel_image();

}  // namespace tandem
