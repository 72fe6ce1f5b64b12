// Runs the kernels' own math (sincos_pi, the sRGB decode table) on the GPU,
// for tests/cuda_kernel_math_test.cpp to compare with the host bit for bit.
#pragma once

#include <vector>

#include "core/kernel/trig.h"

namespace tandem {

// sincos_pi of every x on the device, and srgb8_to_linear(0..255). Throws
// CudaError when a runtime call fails.
void device_sincos_pi(const std::vector<float>& x, std::vector<SinCos>* out);
void device_srgb8_to_linear(std::vector<float>* out);

}  // namespace tandem
