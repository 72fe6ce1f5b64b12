// Which kernel shape the CUDA backend runs a path with. A header of its own,
// free of CUDA, so that command-line parsing works in every build.
#pragma once

#include <string>

#include "core/util/errors.h"

namespace tandem {

enum class CudaKernelVariant { kMegakernel, kWavefront };

// Parses "mega" / "megakernel" / "wave" / "wavefront"; throws UsageError.
inline CudaKernelVariant parse_cuda_kernel_variant(const std::string& name) {
  if (name == "mega" || name == "megakernel") return CudaKernelVariant::kMegakernel;
  if (name == "wave" || name == "wavefront") return CudaKernelVariant::kWavefront;
  throw UsageError("unknown kernel '" + name + "' (expected megakernel or wavefront)");
}

}  // namespace tandem
