#include "backends/cuda/cuda_device_ops.h"

#include <cuda_runtime_api.h>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/cuda_kernels.h"

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
    TANDEM_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&host_counter_), sizeof(uint32_t)));
  }
  ~CudaDevice() override { cudaFreeHost(host_counter_); }
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

  void trace_samples(const KernelData* kd, const TileBatch& batch, CudaKernelVariant variant,
                     const WavefrontArrays& wave, Vec3* radiance, unsigned long long* rays,
                     DeviceStream s) override {
    if (variant == CudaKernelVariant::kWavefront)
      launch_wavefront(kd, batch, wave, radiance, rays, host_counter_, cu(s));
    else
      launch_megakernel(kd, batch, radiance, rays, cu(s));
  }
  // Four times the threads the GPU holds at once: the queues stay full while
  // paths end and slots are regenerated.
  uint32_t wavefront_slots() const override {
    return uint32_t(4 * props_.multiProcessorCount * props_.maxThreadsPerMultiProcessor);
  }
  void reduce_samples(const TileBatch& batch, const Vec3* radiance, double* sums,
                      DeviceStream s) override {
    launch_reduce_samples(batch, radiance, sums, cu(s));
  }
  void accumulate_film(const TileBatch& batch, const double* sums, uint32_t samples,
                       const DeviceFilmView& film, DeviceStream s) override {
    launch_accumulate_film(batch, sums, samples, film, cu(s));
  }
  void resolve_film(const DeviceFilmView& film, float* rgb, DeviceStream s) override {
    launch_resolve_film(film, rgb, cu(s));
  }
  void tone_map_film(const DeviceFilmView& film, float scale, uint32_t curve, uint8_t* rgb8,
                     DeviceStream s) override {
    launch_tone_map_film(film, scale, curve, rgb8, cu(s));
  }
  void trace_rays(const KernelData* kd, const Ray* rays, const uint32_t* keys, uint32_t n,
                  bool any_hit, Hit* hits, uint32_t* counter, DeviceStream s) override {
    launch_trace_rays(kd, rays, keys, n, any_hit, hits, counter, nullptr, nullptr, nullptr, cu(s));
  }
  void render_features(const KernelData* kd, const FeaturePass& pass, uint32_t width,
                       uint32_t height, PixelFeatures* out, DeviceStream s) override {
    launch_features(kd, pass, width, height, out, cu(s));
  }

 private:
  cudaDeviceProp props_{};
  uint32_t* host_counter_ = nullptr;  // pinned: the wavefront's queue counter
};

}  // namespace

std::shared_ptr<DeviceOps> make_cuda_device(std::string* reason) {
  if (!cuda_query_device(reason)) return nullptr;
  return std::make_shared<CudaDevice>();
}

}  // namespace tandem
