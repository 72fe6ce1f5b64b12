// Sampling tables built on the host for the kernels: Walker alias tables
// for discrete distributions and the piecewise-constant 2D distribution of
// an environment map.
#pragma once

#include <vector>

#include "core/kernel/kernel_data.h"

namespace tandem {

// Alias table for weights w_i >= 0 (sum > 0). Entry i keeps probability
// pdf = w_i / sum so the kernel can evaluate the pmf of a known index.
std::vector<KAliasEntry> build_alias_table(const std::vector<double>& weights);

// Fills marginal (height + 1) and conditional (height * (width + 1)) CDFs
// for the environment currently in `kd` (env_texels and constants must be
// set) and returns the sum of texel weights (KEnvironment::map_integral).
float build_environment_cdfs(const KernelData& kd, std::vector<float>& marginal,
                             std::vector<float>& conditional);

}  // namespace tandem
