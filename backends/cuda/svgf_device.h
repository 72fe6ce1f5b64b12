// The denoiser's kernels on the CUDA device: the feature pass
// (core/kernel/features.h) and one frame of the variance-guided filter
// (core/kernel/svgf.h), the same per-pixel code the CPU runs
// (backends/cpu_loops/cpu_features.h, core/render/svgf_cpu.h).
#pragma once

#include <string>

#include "core/render/svgf_cpu.h"

namespace tandem {

// Whether this build has the CUDA device code and a device can run it;
// *reason says why not.
bool svgf_cuda_available(std::string* reason);

// One frame of the filter on the device, in the stage order of
// svgf_run_cpu: the host buffers of `frame` are copied to the device, the
// stages run there and the outputs (history_color_out, moments_out, output)
// are copied back. The two agree within float rounding (the device's expf
// and powf). Throws DeviceError on a device failure, std::logic_error in a
// build without the device code.
SvgfStageSeconds svgf_run_cuda(const SvgfParams& params, const SvgfFrame& frame);

}  // namespace tandem
