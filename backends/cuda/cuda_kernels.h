// Host-side declarations of the CUDA device's kernel launchers. Each .cu
// file holds a few kernels and includes only the kernel headers it needs, so
// nvcc compiles the heavy integrator instantiations in parallel and a change
// to the film code does not recompile the path tracer.
//
// All launchers enqueue on `stream` and check the launch (cuda_check.h);
// none synchronises. The per-item bodies of the small kernels are in
// batch.h, shared with the simulated device.
#pragma once

#include <cuda_runtime_api.h>

#include <cstdint>

#include "backends/cuda/batch.h"
#include "core/kernel/kernel_data.h"

namespace tandem {

struct FeaturePass;    // core/kernel/features.h
struct PixelFeatures;  // core/kernel/features.h

// Megakernel: one thread per pixel sample runs render_pixel_sample with
// BvhTracer and writes the sample's radiance to radiance[item]; rays traced
// are added to *ray_count.
void launch_megakernel(const KernelData* kd, const TileBatch& batch, Vec3* radiance,
                       unsigned long long* ray_count, cudaStream_t stream);

// Wavefront variant (core/kernel/wavefront.h, one kernel per stage). Same
// outputs as launch_megakernel, bit for bit. Synchronises `stream` every
// few rounds to read the queue counter into the pinned `host_counter`.
void launch_wavefront(const KernelData* kd, const TileBatch& batch, const WavefrontArrays& wave,
                      Vec3* radiance, unsigned long long* ray_count, uint32_t* host_counter,
                      cudaStream_t stream);

// The denoiser's feature pass (core/kernel/features.h): one thread per
// pixel of a width x height film; pass.prev_object_to_world must point to
// device memory (backends/cuda/svgf_kernels.cu).
void launch_features(const KernelData* kd, const FeaturePass& pass, uint32_t width, uint32_t height,
                     PixelFeatures* out, cudaStream_t stream);

// Closest hits (any_hit = false) or occlusion (any_hit = true: a valid hit
// means occluded) of n rays with Tandem's BVH, with persistent threads
// (Aila & Laine 2009). When hit_queue/miss_queue are given, item indices are
// appended to them (compacted) with counts in queue_counts[0..1].
// `work_counter` must be zero on entry.
void launch_trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* alpha_keys,
                       uint32_t n, bool any_hit, Hit* hits, uint32_t* work_counter,
                       uint32_t* hit_queue, uint32_t* miss_queue, uint32_t* queue_counts,
                       cudaStream_t stream);

// Sums the chunk's samples of each batch pixel onto pixel_sums
// (reduce_pixel_samples), which the caller zeroes before the first chunk.
void launch_reduce_samples(const TileBatch& batch, const Vec3* radiance, double* pixel_sums,
                           cudaStream_t stream);

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
