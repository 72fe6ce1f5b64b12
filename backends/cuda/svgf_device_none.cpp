// Builds without nvcc: no device to run the denoiser on.
#include <stdexcept>

#include "backends/cuda/svgf_device.h"

namespace tandem {

bool svgf_cuda_available(std::string* reason) {
  if (reason)
    *reason =
        "this build has no CUDA device code (configured with TANDEM_CUDA=OFF or without nvcc)";
  return false;
}

SvgfStageSeconds svgf_run_cuda(const SvgfParams&, const SvgfFrame&) {
  throw std::logic_error("svgf_run_cuda: this build has no CUDA device code");
}

}  // namespace tandem
