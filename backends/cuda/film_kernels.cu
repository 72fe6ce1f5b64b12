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
  if (p < batch.pixel_count) reduce_pixel_samples(batch, radiance, p, pixel_sums);
}

__global__ void accumulate_film_kernel(TileBatch batch, const double* __restrict__ pixel_sums,
                                       uint32_t samples, DeviceFilmView film) {
  const uint32_t p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p < batch.pixel_count) accumulate_film_pixel(batch, pixel_sums, samples, film, p);
}

__global__ void resolve_film_kernel(DeviceFilmView film, float* rgb) {
  const uint64_t i = uint64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < uint64_t(film.width) * film.height) film_pixel_mean(film, i, &rgb[3 * i]);
}

__global__ void tone_map_film_kernel(DeviceFilmView film, float scale, uint32_t curve,
                                     uint8_t* rgb8) {
  const uint64_t i = uint64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < uint64_t(film.width) * film.height) tone_map_film_pixel(film, i, scale, curve, rgb8);
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
