// Is there a CUDA device this build can use? Answers with a reason a user
// can act on, because `--backend cuda` prints it and `auto` logs it.
#include <cuda_runtime_api.h>

#include <string>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/cuda_device_ops.h"

namespace tandem {

namespace {

std::string version_text(int v) {
  return std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10);
}

}  // namespace

bool cuda_query_device(std::string* reason) {
  std::string why;
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e == cudaErrorInsufficientDriver || e == cudaErrorNoDevice ||
      (e == cudaSuccess && count == 0)) {
    int driver = 0, runtime = 0;
    cudaDriverGetVersion(&driver);
    cudaRuntimeGetVersion(&runtime);
    if (driver == 0)
      why = "no NVIDIA driver is installed (no CUDA device)";
    else if (e == cudaErrorInsufficientDriver)
      why = "the NVIDIA driver is too old: it supports CUDA " + version_text(driver) +
            ", this build needs " + version_text(runtime);
    else
      why = "no CUDA device found";
  } else if (e != cudaSuccess) {
    why = std::string("CUDA is unavailable: ") + cudaGetErrorString(e);
  } else {
    cudaDeviceProp props{};
    // Before the context exists: waits block the host thread instead of
    // spinning on a core (the CPU backend renders on those cores).
    cudaSetDeviceFlags(cudaDeviceScheduleBlockingSync);
    cudaError_t q = cudaGetDeviceProperties(&props, 0);
    if (q == cudaSuccess) q = cudaSetDevice(0);
    if (q == cudaSuccess) q = cuda_probe_kernel_image();
    if (q == cudaErrorNoKernelImageForDevice || q == cudaErrorInvalidDeviceFunction) {
      why = std::string("the GPU (") + props.name + ", compute capability " +
            std::to_string(props.major) + "." + std::to_string(props.minor) +
            ") is older than this build's CUDA kernels support";
    } else if (q != cudaSuccess) {
      why = std::string("CUDA device 0 is unusable: ") + cudaGetErrorString(q);
    }
  }
  // The runtime remembers the last error; do not leave it for the next
  // checked call to trip over.
  cudaGetLastError();
  if (reason) *reason = why;
  return why.empty();
}

}  // namespace tandem
