// Error checking for every CUDA runtime call of the CUDA backend.
//
// A CUDA error is not bad user input but a device or driver failure, so it
// gets its own exception type: the backend factory catches CudaError under
// `--backend auto` and falls back to the CPU, while `--backend cuda` lets it
// reach the user with the call, the place and CUDA's own description.
#pragma once

#include <cuda_runtime_api.h>

#include <stdexcept>
#include <string>

namespace tandem {

class CudaError : public std::runtime_error {
 public:
  CudaError(cudaError_t code, const char* call, const char* file, int line)
      : std::runtime_error(std::string("CUDA error in ") + call + " at " + file + ":" +
                           std::to_string(line) + ": " + cudaGetErrorName(code) + " (" +
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

}  // namespace tandem

// Wraps one runtime call: TANDEM_CUDA_CHECK(cudaMalloc(&p, n));
#define TANDEM_CUDA_CHECK(call) ::tandem::cuda_check((call), #call, __FILE__, __LINE__)

// After a <<<...>>> launch: launch-configuration errors surface only through
// cudaGetLastError (asynchronous faults surface at the next synchronising call,
// which is checked too).
#define TANDEM_CUDA_CHECK_LAUNCH(kernel_name) \
  ::tandem::cuda_check(cudaGetLastError(), "launch of " kernel_name, __FILE__, __LINE__)
