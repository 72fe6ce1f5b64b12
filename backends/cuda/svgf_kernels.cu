// The denoiser on the device: one thread per pixel for the feature pass and
// each filter stage, running the per-pixel functions of
// core/kernel/features.h and core/kernel/svgf.h.
#include <chrono>
#include <vector>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/device_common.cuh"
#include "backends/cuda/svgf_device.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/svgf.h"

namespace tandem {

namespace {

constexpr uint32_t kSvgfBlock = 16;  // 16x16 threads: neighbouring pixels share cache lines

__global__ void features_kernel(const KernelData* __restrict__ kd_global, FeaturePass pass,
                                PixelFeatures* __restrict__ out) {
  __shared__ KernelData kd;
  load_kernel_data(&kd, kd_global);
  const uint32_t x = blockIdx.x * blockDim.x + threadIdx.x;
  const uint32_t y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= kd.constants.camera.width || y >= kd.constants.camera.height) return;
  out[size_t(y) * kd.constants.camera.width + x] =
      compute_pixel_features(kd, BvhTracer{&kd}, pass, x, y);
}

__global__ void temporal_kernel(SvgfParams p, SvgfTemporalBuffers b) {
  const uint32_t x = blockIdx.x * blockDim.x + threadIdx.x,
                 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x < p.width && y < p.height) svgf_temporal_pixel(p, b, x, y);
}
__global__ void variance_kernel(SvgfParams p, SvgfVarianceBuffers b) {
  const uint32_t x = blockIdx.x * blockDim.x + threadIdx.x,
                 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x < p.width && y < p.height) svgf_variance_pixel(p, b, x, y);
}
// One a-trous iteration; `out` (when set) receives the illumination, and
// `radiance` (when set: the last iteration) the albedo-modulated result.
__global__ void atrous_kernel(SvgfParams p, SvgfAtrousBuffers b, uint32_t step, Vec4* out,
                              const PixelFeatures* f, Vec3* radiance) {
  const uint32_t x = blockIdx.x * blockDim.x + threadIdx.x,
                 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= p.width || y >= p.height) return;
  const size_t i = size_t(y) * p.width + x;
  const Vec4 v = svgf_atrous_pixel<true>(p, b, step, x, y);
  if (out) out[i] = v;
  if (radiance) radiance[i] = svgf_modulate_pixel(f[i], v);
}
__global__ void modulate_kernel(SvgfParams p, const PixelFeatures* f, const Vec4* illum,
                                Vec3* out) {
  const uint32_t x = blockIdx.x * blockDim.x + threadIdx.x,
                 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= p.width || y >= p.height) return;
  const size_t i = size_t(y) * p.width + x;
  out[i] = svgf_modulate_pixel(f[i], illum[i]);
}

dim3 grid_for(uint32_t w, uint32_t h) {
  return dim3((w + kSvgfBlock - 1) / kSvgfBlock, (h + kSvgfBlock - 1) / kSvgfBlock);
}

// A device allocation freed when it goes out of scope.
template <class T>
struct DeviceArray {
  T* p = nullptr;
  explicit DeviceArray(size_t n) { TANDEM_CUDA_CHECK(cudaMalloc(&p, n * sizeof(T) + 16)); }
  ~DeviceArray() { cudaFree(p); }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
};

}  // namespace

void launch_features(const KernelData* kd, const FeaturePass& pass, uint32_t width, uint32_t height,
                     PixelFeatures* out, cudaStream_t stream) {
  if (width == 0 || height == 0) return;
  features_kernel<<<grid_for(width, height), dim3(kSvgfBlock, kSvgfBlock), 0, stream>>>(kd, pass,
                                                                                        out);
  TANDEM_CUDA_CHECK_LAUNCH("features_kernel");
}

bool svgf_cuda_available(std::string* reason) {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess || count == 0) {
    if (reason) *reason = e != cudaSuccess ? cudaGetErrorString(e) : "no CUDA device";
    return false;
  }
  return true;
}

SvgfStageSeconds svgf_run_cuda(const SvgfParams& p, const SvgfFrame& fr) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const auto start = std::chrono::steady_clock::now();
  DeviceArray<PixelFeatures> features(n), prev_features(n);
  DeviceArray<Vec3> radiance(n), output(n);
  DeviceArray<Vec2> slope(n);
  DeviceArray<SvgfGuide> guide(n);
  DeviceArray<uint32_t> material(n);
  DeviceArray<Vec4> prev_color(n), prev_moments(n), hist(n), moments(n), a(n), b(n);
  TANDEM_CUDA_CHECK(
      cudaMemcpy(features.p, fr.features, n * sizeof(PixelFeatures), cudaMemcpyHostToDevice));
  TANDEM_CUDA_CHECK(cudaMemcpy(radiance.p, fr.radiance, n * sizeof(Vec3), cudaMemcpyHostToDevice));
  if (fr.prev_features) {
    TANDEM_CUDA_CHECK(cudaMemcpy(prev_features.p, fr.prev_features, n * sizeof(PixelFeatures),
                                 cudaMemcpyHostToDevice));
    TANDEM_CUDA_CHECK(
        cudaMemcpy(prev_color.p, fr.prev_color, n * sizeof(Vec4), cudaMemcpyHostToDevice));
    TANDEM_CUDA_CHECK(
        cudaMemcpy(prev_moments.p, fr.prev_moments, n * sizeof(Vec4), cudaMemcpyHostToDevice));
  }
  const dim3 grid = grid_for(p.width, p.height), block(kSvgfBlock, kSvgfBlock);
  const SvgfTemporalBuffers tb{
      features.p,   radiance.p,     fr.prev_features ? prev_features.p : nullptr,
      prev_color.p, prev_moments.p, a.p,
      moments.p,    slope.p,        guide.p,
      material.p};
  temporal_kernel<<<grid, block>>>(p, tb);
  TANDEM_CUDA_CHECK_LAUNCH("svgf temporal");
  variance_kernel<<<grid, block>>>(
      p, SvgfVarianceBuffers{guide.p, material.p, slope.p, a.p, moments.p, b.p});
  TANDEM_CUDA_CHECK_LAUNCH("svgf variance");
  // The same ping-pong as svgf_run_cpu: b -> history -> a -> b -> ...
  const Vec4* in = b.p;
  for (uint32_t it = 0; it < p.iterations; ++it) {
    const bool last = it + 1 == p.iterations;
    Vec4* out = it == 0 ? hist.p : (last ? nullptr : (in == a.p ? b.p : a.p));
    atrous_kernel<<<grid, block>>>(p, SvgfAtrousBuffers{guide.p, material.p, slope.p, in}, 1u << it,
                                   out, features.p, last ? output.p : nullptr);
    TANDEM_CUDA_CHECK_LAUNCH("svgf a-trous");
    in = out;
  }
  if (p.iterations == 0) {
    TANDEM_CUDA_CHECK(cudaMemcpy(hist.p, b.p, n * sizeof(Vec4), cudaMemcpyDeviceToDevice));
    modulate_kernel<<<grid, block>>>(p, features.p, b.p, output.p);
    TANDEM_CUDA_CHECK_LAUNCH("svgf modulate");
  }
  TANDEM_CUDA_CHECK(
      cudaMemcpy(fr.history_color_out, hist.p, n * sizeof(Vec4), cudaMemcpyDeviceToHost));
  TANDEM_CUDA_CHECK(
      cudaMemcpy(fr.moments_out, moments.p, n * sizeof(Vec4), cudaMemcpyDeviceToHost));
  TANDEM_CUDA_CHECK(cudaMemcpy(fr.output, output.p, n * sizeof(Vec3), cudaMemcpyDeviceToHost));
  t.atrous = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return t;
}

}  // namespace tandem
