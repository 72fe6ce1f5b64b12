// Error checking for every CUDA runtime call of the CUDA device
// (cuda_device_ops.cpp, cuda_device.cpp).
//
// A CUDA error is not bad user input but a device or driver failure: it is a
// DeviceError (device_ops.h) whose fault kind says how to recover, so the
// backend factory falls back to the CPU under `--backend auto` and in
// backend lists, while `--backend cuda` lets it reach the user with the
// call, the place and CUDA's own description.
#pragma once

#include <cuda_runtime_api.h>

#include <string>

#include "backends/cuda/device_ops.h"

namespace tandem {

// How a CUDA error code maps onto the backend's recovery.
inline DeviceFault cuda_fault_kind(cudaError_t code) {
  switch (code) {
    case cudaErrorMemoryAllocation:
      return DeviceFault::kOutOfMemory;
    case cudaErrorLaunchFailure:
    case cudaErrorLaunchOutOfResources:
    case cudaErrorLaunchTimeout:
    case cudaErrorInvalidConfiguration:
      return DeviceFault::kLaunchFailure;
    case cudaErrorIllegalAddress:
    case cudaErrorMisalignedAddress:
    case cudaErrorInvalidAddressSpace:
    case cudaErrorIllegalInstruction:
    case cudaErrorInvalidPc:
    case cudaErrorHardwareStackError:
      return DeviceFault::kIllegalAddress;
    case cudaErrorNoDevice:
    case cudaErrorDevicesUnavailable:
    case cudaErrorECCUncorrectable:
    case cudaErrorInsufficientDriver:
    case cudaErrorSystemNotReady:
    case cudaErrorCudartUnloading:
      return DeviceFault::kDeviceLost;
    default:
      return DeviceFault::kOther;
  }
}

class CudaError : public DeviceError {
 public:
  CudaError(cudaError_t code, const char* call, const char* file, int line)
      : DeviceError(cuda_fault_kind(code), std::string("CUDA error in ") + call + " at " + file +
                                               ":" + std::to_string(line) + ": " +
                                               cudaGetErrorName(code) + " (" +
                                               cudaGetErrorString(code) + ")"),
        code_(code) {}
  cudaError_t code() const { return code_; }

 private:
  cudaError_t code_;
};

// Throws on anything but cudaSuccess. Out of line so the macro stays small
// in every launcher.
inline void cuda_check(cudaError_t code, const char* call, const char* file, int line) {
  if (code != cudaSuccess) throw CudaError(code, call, file, line);
}

// cudaSuccess when this build holds a kernel image (SASS or PTX) the
// current device can run; cudaErrorNoKernelImageForDevice (or similar)
// otherwise (cuda_device_ops.cpp).
cudaError_t cuda_probe_kernel_image();

}  // namespace tandem

// Wraps one runtime call: TANDEM_CUDA_CHECK(cudaMalloc(&p, n));
#define TANDEM_CUDA_CHECK(call) ::tandem::cuda_check((call), #call, __FILE__, __LINE__)

// After a <<<...>>> launch: launch-configuration errors surface only through
// cudaGetLastError (asynchronous faults surface at the next synchronising call,
// which is checked too).
#define TANDEM_CUDA_CHECK_LAUNCH(kernel_name) \
  ::tandem::cuda_check(cudaGetLastError(), "launch of " kernel_name, __FILE__, __LINE__)
