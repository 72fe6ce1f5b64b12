// Sampling tables built on the host for the kernels: Walker alias tables
// for discrete distributions and the piecewise-constant 2D distribution of
// an environment map.
#pragma once

#include <vector>

#include "core/kernel/kernel_data.h"
#include "core/world/kernel_scene.h"

namespace tandem {

// Alias table for weights w_i >= 0 (sum > 0). Entry i keeps probability
// pdf = w_i / sum so the kernel can evaluate the pmf of a known index.
std::vector<KAliasEntry> build_alias_table(const std::vector<double>& weights);

// The guide table of a CDF of n + 1 entries (n > 0) that
// find_interval_guided starts its brackets from, n + 1 entries:
// guide[k] = find_interval(cdf, n, k / n) for k < n, guide[n] = n - 1.
void build_cdf_guide(const float* cdf, uint32_t n, uint32_t* guide);

// Fills the environment's sampling tables in `ks` from its env_texels and
// environment constants (width, height; has_map set): the marginal and
// conditional CDFs, their guide tables and the per-texel pdf, and sets
// map_integral to the sum of texel weights.
void build_environment_tables(KernelScene& ks);

}  // namespace tandem
