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

__global__ void light_tree_kernel(const KLightTreeNode* nodes, unsigned node_count, const Vec3* p,
                                  const Vec3* n, const float* u, const uint64_t* trails,
                                  const uint32_t* trail_lights, uint32_t* lights, float* pmfs,
                                  float* trail_pmfs, unsigned count) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= count) return;
  lights[i] = light_tree_sample(nodes, node_count, p[i], n[i], u[i], &pmfs[i]);
  trail_pmfs[i] = light_tree_pmf(nodes, node_count, trails[i], trail_lights[i], p[i], n[i]);
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

namespace {

template <typename T>
void to_device(ScratchArray<T>& d, const std::vector<T>& h) {
  TANDEM_CUDA_CHECK(cudaMemcpy(d.ptr, h.data(), h.size() * sizeof(T), cudaMemcpyHostToDevice));
}

template <typename T>
void to_host(std::vector<T>* h, const ScratchArray<T>& d, size_t n) {
  h->resize(n);
  TANDEM_CUDA_CHECK(cudaMemcpy(h->data(), d.ptr, n * sizeof(T), cudaMemcpyDeviceToHost));
}

}  // namespace

void device_light_tree(const std::vector<KLightTreeNode>& nodes, const std::vector<Vec3>& p,
                       const std::vector<Vec3>& n, const std::vector<float>& u,
                       const std::vector<uint64_t>& trails,
                       const std::vector<uint32_t>& trail_lights, std::vector<uint32_t>* lights,
                       std::vector<float>* pmfs, std::vector<float>* trail_pmfs) {
  const unsigned count = unsigned(p.size());
  ScratchArray<KLightTreeNode> d_nodes(nodes.size());
  ScratchArray<Vec3> d_p(count), d_n(count);
  ScratchArray<float> d_u(count), d_pmfs(count), d_trail_pmfs(count);
  ScratchArray<uint64_t> d_trails(count);
  ScratchArray<uint32_t> d_lights(count), d_trail_lights(count);
  to_device(d_nodes, nodes);
  to_device(d_trail_lights, trail_lights);
  to_device(d_p, p);
  to_device(d_n, n);
  to_device(d_u, u);
  to_device(d_trails, trails);
  light_tree_kernel<<<(count + 127) / 128, 128>>>(
      d_nodes.ptr, unsigned(nodes.size()), d_p.ptr, d_n.ptr, d_u.ptr, d_trails.ptr,
      d_trail_lights.ptr, d_lights.ptr, d_pmfs.ptr, d_trail_pmfs.ptr, count);
  TANDEM_CUDA_CHECK(cudaGetLastError());
  to_host(lights, d_lights, count);
  to_host(pmfs, d_pmfs, count);
  to_host(trail_pmfs, d_trail_pmfs, count);
}

}  // namespace tandem
