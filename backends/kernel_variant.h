// Which kernel a backend traces paths with: one megakernel that runs a whole
// path per thread, or the wavefront pipeline (one kernel per path stage).
// Kept apart from cuda_backend.h and free of CUDA headers so that the
// command line can parse --kernel in every build, CUDA or not.
#pragma once

#include <string>

namespace tandem {

enum class CudaKernelVariant { kMegakernel, kWavefront };

// Parses "megakernel" / "mega" / "wavefront" / "wave"; throws UsageError.
CudaKernelVariant parse_cuda_kernel_variant(const std::string& name);

// "megakernel" or "wavefront".
const char* kernel_variant_name(CudaKernelVariant variant);

}  // namespace tandem
