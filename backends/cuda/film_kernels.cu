// Per-pixel reduction of a batch's samples, the device-resident film for
// GPU-only output, and tone mapping to 8 bits on the GPU.
#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "core/kernel/tone_map.h"

namespace tandem {

namespace {

constexpr uint32_t kFilmThreads = 256;

__global__ void reduce_samples_kernel(TileBatch batch, const Vec3* __restrict__ radiance,
                                      double* pixel_sums) {
  const uint32_t p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= batch.pixel_count) return;
  double r = pixel_sums[3 * p], g = pixel_sums[3 * p + 1], b = pixel_sums[3 * p + 2];
  // Sample order, double precision: what render_tiles_on_cpu does.
  for (uint32_t s = 0; s < batch.sample_count; ++s) {
    const Vec3 l = radiance[uint64_t(s) * batch.pixel_count + p];
    r += double(l.x);
    g += double(l.y);
    b += double(l.z);
  }
  pixel_sums[3 * p] = r;
  pixel_sums[3 * p + 1] = g;
  pixel_sums[3 * p + 2] = b;
}

__global__ void accumulate_film_kernel(TileBatch batch, const double* __restrict__ pixel_sums,
                                       uint32_t samples, DeviceFilmView film) {
  const uint32_t p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= batch.pixel_count) return;
  uint32_t x, y;
  batch_pixel(batch, p, &x, &y);
  const size_t i = size_t(y) * film.width + x;
  film.sums[3 * i] += pixel_sums[3 * p];
  film.sums[3 * i + 1] += pixel_sums[3 * p + 1];
  film.sums[3 * i + 2] += pixel_sums[3 * p + 2];
  film.samples[i] += samples;
}

// Film::resolve's arithmetic exactly: sum * (1 / samples) in double.
__device__ __forceinline__ void film_mean(const DeviceFilmView& film, size_t i, float out[3]) {
  const uint32_t n = film.samples[i];
  const double inv = n ? 1.0 / double(n) : 0.0;
  for (int c = 0; c < 3; ++c)
    out[c] = float(film.sums[3 * i + c] * inv);
}

__global__ void resolve_film_kernel(DeviceFilmView film, float* rgb) {
  const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= size_t(film.width) * film.height) return;
  film_mean(film, i, &rgb[3 * i]);
}

__global__ void tone_map_film_kernel(DeviceFilmView film, float scale, uint32_t curve,
                                     uint8_t* rgb8) {
  const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= size_t(film.width) * film.height) return;
  float mean[3];
  film_mean(film, i, mean);
  for (int c = 0; c < 3; ++c)
    rgb8[3 * i + c] = tone_map_channel_srgb8(mean[c], scale, curve);
}

}  // namespace

void launch_reduce_samples(const TileBatch& batch, const Vec3* radiance, double* pixel_sums,
                           cudaStream_t stream) {
  if (batch.pixel_count == 0) return;
  reduce_samples_kernel<<<blocks_for(batch.pixel_count, kFilmThreads), kFilmThreads, 0, stream>>>(
      batch, radiance, pixel_sums);
  TANDEM_CUDA_CHECK_LAUNCH("reduce_samples_kernel");
}

void launch_accumulate_film(const TileBatch& batch, const double* pixel_sums, uint32_t sample_count,
                            DeviceFilmView film, cudaStream_t stream) {
  if (batch.pixel_count == 0) return;
  accumulate_film_kernel<<<blocks_for(batch.pixel_count, kFilmThreads), kFilmThreads, 0, stream>>>(
      batch, pixel_sums, sample_count, film);
  TANDEM_CUDA_CHECK_LAUNCH("accumulate_film_kernel");
}

void launch_resolve_film(DeviceFilmView film, float* rgb, cudaStream_t stream) {
  const uint64_t n = uint64_t(film.width) * film.height;
  if (n == 0) return;
  resolve_film_kernel<<<blocks_for(n, kFilmThreads), kFilmThreads, 0, stream>>>(film, rgb);
  TANDEM_CUDA_CHECK_LAUNCH("resolve_film_kernel");
}

void launch_tone_map_film(DeviceFilmView film, float exposure_scale, uint32_t curve, uint8_t* rgb8,
                          cudaStream_t stream) {
  const uint64_t n = uint64_t(film.width) * film.height;
  if (n == 0) return;
  tone_map_film_kernel<<<blocks_for(n, kFilmThreads), kFilmThreads, 0, stream>>>(
      film, exposure_scale, curve, rgb8);
  TANDEM_CUDA_CHECK_LAUNCH("tone_map_film_kernel");
}

cudaError_t cuda_probe_kernel_image() {
  cudaFuncAttributes attributes;
  return cudaFuncGetAttributes(&attributes, resolve_film_kernel);
}

}  // namespace tandem
