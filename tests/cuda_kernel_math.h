// Runs the kernels' own math (sincos_pi, the sRGB decode table) on the GPU,
// for tests/cuda_kernel_math_test.cpp to compare with the host bit for bit.
#pragma once

#include <vector>

#include "core/kernel/light_tree.h"
#include "core/kernel/math.h"
#include "core/kernel/trig.h"

namespace tandem {

// sincos_pi of every x on the device, and srgb8_to_linear(0..255). Throws
// CudaError when a runtime call fails.
void device_sincos_pi(const std::vector<float>& x, std::vector<SinCos>* out);
// atan2_pi(y[i], x[i]) on the device.
void device_atan2_pi(const std::vector<float>& y, const std::vector<float>& x,
                     std::vector<float>* out);
void device_srgb8_to_linear(std::vector<float>* out);
// The sheen lobe (sheen_brdf(wo[i], wi[i], alpha[i])) and its tabulated
// albedo (sheen_albedo(wo[i].z, alpha[i])) on the device: they rest on the
// plain-float exp2/log2 of core/kernel/exp_log.h.
void device_sheen(const std::vector<Vec3>& wo, const std::vector<Vec3>& wi,
                  const std::vector<float>& alpha, std::vector<float>* brdf,
                  std::vector<float>* albedo);

// The light tree's choice at point p[i] (normal n[i]) for u[i]: the light
// and its pmf, and the pmf recomputed from trails[i] (light_tree.h).
void device_light_tree(const std::vector<KLightTreeNode>& nodes, const std::vector<Vec3>& p,
                       const std::vector<Vec3>& n, const std::vector<float>& u,
                       const std::vector<uint64_t>& trails,
                       const std::vector<uint32_t>& trail_lights, std::vector<uint32_t>* lights,
                       std::vector<float>* pmfs, std::vector<float>* trail_pmfs);

}  // namespace tandem
