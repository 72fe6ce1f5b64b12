// Device side of tests/cuda_kernel_math_test.cpp, compiled with the CUDA
// backend's arithmetic flags (-fmad=false) so it computes what its kernels do.
#include "backends/cuda/cuda_check.h"
#include "core/kernel/srgb_table.h"
#include "tests/cuda_kernel_math.h"

namespace tandem {
namespace {

__global__ void sincos_pi_kernel(const float* x, SinCos* out, unsigned n) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = sincos_pi(x[i]);
}

__global__ void srgb8_kernel(float* out) {
  out[threadIdx.x] = srgb8_to_linear(threadIdx.x);
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

void device_srgb8_to_linear(std::vector<float>* out) {
  ScratchArray<float> d_out(256);
  srgb8_kernel<<<1, 256>>>(d_out.ptr);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  out->resize(256);
  TANDEM_CUDA_CHECK(
      cudaMemcpy(out->data(), d_out.ptr, 256 * sizeof(float), cudaMemcpyDeviceToHost));
}

}  // namespace tandem
