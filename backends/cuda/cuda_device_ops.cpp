#include "backends/cuda/cuda_device_ops.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/cuda_kernel_table.h"

namespace tandem {

namespace {

cudaStream_t cu(DeviceStream s) {
  return reinterpret_cast<cudaStream_t>(s);
}
cudaEvent_t cu(DeviceEvent e) {
  return reinterpret_cast<cudaEvent_t>(e);
}

class CudaDevice final : public DeviceOps {
 public:
  CudaDevice() {
    TANDEM_CUDA_CHECK(cudaSetDevice(0));
    TANDEM_CUDA_CHECK(cudaGetDeviceProperties(&props_, 0));
  }
  CudaDevice(const CudaDevice&) = delete;
  CudaDevice& operator=(const CudaDevice&) = delete;

  std::string name() const override { return props_.name; }

  void* alloc(size_t bytes) override {
    void* p = nullptr;
    TANDEM_CUDA_CHECK(cudaMalloc(&p, bytes));
    return p;
  }
  void free(void* p) override { TANDEM_CUDA_CHECK(cudaFree(p)); }
  void* alloc_async(size_t bytes, DeviceStream s) override {
    void* p = nullptr;
    TANDEM_CUDA_CHECK(cudaMallocAsync(&p, bytes, cu(s)));
    return p;
  }
  void free_async(void* p, DeviceStream s) override { TANDEM_CUDA_CHECK(cudaFreeAsync(p, cu(s))); }
  void* alloc_pinned(size_t bytes) override {
    void* p = nullptr;
    TANDEM_CUDA_CHECK(cudaMallocHost(&p, bytes));
    return p;
  }
  void free_pinned(void* p) override { TANDEM_CUDA_CHECK(cudaFreeHost(p)); }

  DeviceStream create_stream() override {
    cudaStream_t s = nullptr;
    TANDEM_CUDA_CHECK(cudaStreamCreateWithFlags(&s, cudaStreamNonBlocking));
    return reinterpret_cast<DeviceStream>(s);
  }
  void destroy_stream(DeviceStream s) override { TANDEM_CUDA_CHECK(cudaStreamDestroy(cu(s))); }
  DeviceEvent create_event(bool timing) override {
    cudaEvent_t e = nullptr;
    // Blocking: cudaEventSynchronize sleeps instead of spinning.
    const unsigned flags = cudaEventBlockingSync | (timing ? 0u : cudaEventDisableTiming);
    TANDEM_CUDA_CHECK(cudaEventCreateWithFlags(&e, flags));
    return reinterpret_cast<DeviceEvent>(e);
  }
  void destroy_event(DeviceEvent e) override { TANDEM_CUDA_CHECK(cudaEventDestroy(cu(e))); }
  void record(DeviceEvent e, DeviceStream s) override {
    TANDEM_CUDA_CHECK(cudaEventRecord(cu(e), cu(s)));
  }
  void wait(DeviceStream s, DeviceEvent e) override {
    TANDEM_CUDA_CHECK(cudaStreamWaitEvent(cu(s), cu(e), 0));
  }
  void synchronize(DeviceEvent e) override { TANDEM_CUDA_CHECK(cudaEventSynchronize(cu(e))); }
  void synchronize(DeviceStream s) override { TANDEM_CUDA_CHECK(cudaStreamSynchronize(cu(s))); }
  double elapsed_seconds(DeviceEvent from, DeviceEvent to) override {
    float ms = 0.0f;
    TANDEM_CUDA_CHECK(cudaEventElapsedTime(&ms, cu(from), cu(to)));
    return double(ms) * 1e-3;
  }

  void copy_to_device(void* dst, const void* src, size_t bytes, DeviceStream s) override {
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, cu(s)));
  }
  void copy_to_host(void* dst, const void* src, size_t bytes, DeviceStream s) override {
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, cu(s)));
  }
  void zero(void* dst, size_t bytes, DeviceStream s) override {
    TANDEM_CUDA_CHECK(cudaMemsetAsync(dst, 0, bytes, cu(s)));
  }

  DeviceProperties properties() const override {
    return {uint32_t(props_.multiProcessorCount), uint32_t(props_.maxThreadsPerMultiProcessor)};
  }
  uint32_t resident_blocks(DeviceKernel kernel, uint32_t block_threads) override {
    // Asked for every wavefront batch: the driver's answer is cached.
    std::lock_guard<std::mutex> lock(mutex_);
    uint32_t& cached = resident_[{kernel, block_threads}];
    if (cached == 0) {
      int per_sm = 0;
      TANDEM_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, function(kernel),
                                                                      int(block_threads), 0));
      cached = uint32_t(std::max(per_sm, 1));
    }
    return cached;
  }
  void launch(DeviceKernel kernel, const LaunchDims& d, const void* args, size_t args_bytes,
              DeviceStream s) override {
    const CudaKernelTable::Kernel& k = cuda_kernels().kernels[uint32_t(kernel)];
    if (args_bytes != k.args_bytes)
      throw std::logic_error(std::string("launch of ") + device_kernel_name(kernel) +
                             " with arguments of the wrong size");
    // The kernel's one parameter is its Args struct, copied at the launch.
    void* params[] = {const_cast<void*>(args)};
    TANDEM_CUDA_CHECK(cudaLaunchKernel(function(kernel), dim3(d.grid.x, d.grid.y, d.grid.z),
                                       dim3(d.block.x, d.block.y, d.block.z), params, 0, cu(s)));
  }

 private:
  static const void* function(DeviceKernel kernel) {
    return cuda_kernels().kernels[uint32_t(kernel)].function;
  }

  cudaDeviceProp props_{};
  std::mutex mutex_;
  std::map<std::pair<DeviceKernel, uint32_t>, uint32_t> resident_;
};

}  // namespace

const CudaKernelTable& cuda_kernels() {
  static const CudaKernelTable table = [] {
    CudaKernelTable t;
#define TANDEM_CALL_CUDA_REGISTRY(name) register_cuda_kernels_##name(t);
    TANDEM_DEVICE_KERNEL_FILES(TANDEM_CALL_CUDA_REGISTRY)
#undef TANDEM_CALL_CUDA_REGISTRY
    return t;
  }();
  return table;
}

cudaError_t cuda_probe_kernel_image() {
  cudaFuncAttributes attributes;
  return cudaFuncGetAttributes(
      &attributes, cuda_kernels().kernels[uint32_t(DeviceKernel::kResolveFilm)].function);
}

std::shared_ptr<DeviceOps> make_cuda_device(std::string* reason) {
  if (!cuda_query_device(reason)) return nullptr;
  return std::make_shared<CudaDevice>();
}

}  // namespace tandem
