#include "backends/kernel_variant.h"

#include "core/util/errors.h"

namespace tandem {

CudaKernelVariant parse_cuda_kernel_variant(const std::string& name) {
  if (name == "mega" || name == "megakernel") return CudaKernelVariant::kMegakernel;
  if (name == "wave" || name == "wavefront") return CudaKernelVariant::kWavefront;
  throw UsageError("unknown kernel '" + name +
                   "' (expected megakernel or wavefront; mega and wave for short)");
}

const char* kernel_variant_name(CudaKernelVariant variant) {
  return variant == CudaKernelVariant::kWavefront ? "wavefront" : "megakernel";
}

}  // namespace tandem
