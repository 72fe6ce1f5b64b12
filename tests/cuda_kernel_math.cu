// Device side of tests/cuda_kernel_math_test.cpp, compiled with the CUDA
// backend's arithmetic flags (-fmad=false) so it computes what its kernels do.
#include "backends/cuda/cuda_check.h"
#include "core/kernel/sheen_albedo.h"
#include "core/kernel/srgb_table.h"
#include "tests/cuda_kernel_math.h"

namespace tandem {
namespace {

__global__ void sincos_pi_kernel(const float* x, SinCos* out, unsigned n) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = sincos_pi(x[i]);
}

__global__ void atan2_pi_kernel(const float* y, const float* x, float* out, unsigned n) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = atan2_pi(y[i], x[i]);
}

__global__ void srgb8_kernel(float* out) {
  out[threadIdx.x] = srgb8_to_linear(threadIdx.x);
}

__global__ void sheen_kernel(const Vec3* wo, const Vec3* wi, const float* alpha, float* brdf,
                             float* albedo, unsigned n) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  brdf[i] = sheen_brdf(wo[i], wi[i], alpha[i]);
  albedo[i] = sheen_albedo(wo[i].z, alpha[i]);
}

template <typename T>
struct ScratchArray {
  T* ptr = nullptr;
  explicit ScratchArray(size_t n) { TANDEM_CUDA_CHECK(cudaMalloc(&ptr, (n ? n : 1) * sizeof(T))); }
  ~ScratchArray() { cudaFree(ptr); }
  ScratchArray(const ScratchArray&) = delete;
  ScratchArray& operator=(const ScratchArray&) = delete;
};

}  // namespace

void device_sincos_pi(const std::vector<float>& x, std::vector<SinCos>* out) {
  const unsigned n = unsigned(x.size());
  ScratchArray<float> d_x(n);
  ScratchArray<SinCos> d_out(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(d_x.ptr, x.data(), n * sizeof(float), cudaMemcpyHostToDevice));
  sincos_pi_kernel<<<(n + 255) / 256, 256>>>(d_x.ptr, d_out.ptr, n);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  out->resize(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(out->data(), d_out.ptr, n * sizeof(SinCos), cudaMemcpyDeviceToHost));
}

void device_atan2_pi(const std::vector<float>& y, const std::vector<float>& x,
                     std::vector<float>* out) {
  const unsigned n = unsigned(x.size());
  ScratchArray<float> d_y(n), d_x(n), d_out(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(d_y.ptr, y.data(), n * sizeof(float), cudaMemcpyHostToDevice));
  TANDEM_CUDA_CHECK(cudaMemcpy(d_x.ptr, x.data(), n * sizeof(float), cudaMemcpyHostToDevice));
  atan2_pi_kernel<<<(n + 255) / 256, 256>>>(d_y.ptr, d_x.ptr, d_out.ptr, n);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  out->resize(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(out->data(), d_out.ptr, n * sizeof(float), cudaMemcpyDeviceToHost));
}

void device_srgb8_to_linear(std::vector<float>* out) {
  ScratchArray<float> d_out(256);
  srgb8_kernel<<<1, 256>>>(d_out.ptr);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  out->resize(256);
  TANDEM_CUDA_CHECK(
      cudaMemcpy(out->data(), d_out.ptr, 256 * sizeof(float), cudaMemcpyDeviceToHost));
}

void device_sheen(const std::vector<Vec3>& wo, const std::vector<Vec3>& wi,
                  const std::vector<float>& alpha, std::vector<float>* brdf,
                  std::vector<float>* albedo) {
  const unsigned n = unsigned(wo.size());
  ScratchArray<Vec3> d_wo(n), d_wi(n);
  ScratchArray<float> d_alpha(n), d_brdf(n), d_albedo(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(d_wo.ptr, wo.data(), n * sizeof(Vec3), cudaMemcpyHostToDevice));
  TANDEM_CUDA_CHECK(cudaMemcpy(d_wi.ptr, wi.data(), n * sizeof(Vec3), cudaMemcpyHostToDevice));
  TANDEM_CUDA_CHECK(
      cudaMemcpy(d_alpha.ptr, alpha.data(), n * sizeof(float), cudaMemcpyHostToDevice));
  sheen_kernel<<<(n + 255) / 256, 256>>>(d_wo.ptr, d_wi.ptr, d_alpha.ptr, d_brdf.ptr, d_albedo.ptr,
                                         n);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  brdf->resize(n);
  albedo->resize(n);
  TANDEM_CUDA_CHECK(
      cudaMemcpy(brdf->data(), d_brdf.ptr, n * sizeof(float), cudaMemcpyDeviceToHost));
  TANDEM_CUDA_CHECK(
      cudaMemcpy(albedo->data(), d_albedo.ptr, n * sizeof(float), cudaMemcpyDeviceToHost));
}

}  // namespace tandem
