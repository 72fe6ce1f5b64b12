#include "core/world/light_tables.h"

#include "core/kernel/environment.h"

namespace tandem {

std::vector<KAliasEntry> build_alias_table(const std::vector<double>& weights) {
  const size_t n = weights.size();
  std::vector<KAliasEntry> table(n);
  double sum = 0.0;
  for (double w : weights)
    sum += w > 0.0 ? w : 0.0;
  if (n == 0 || !(sum > 0.0)) {
    for (size_t i = 0; i < n; ++i)
      table[i] = {1.0f, uint32_t(i), n ? float(1.0 / double(n)) : 0.0f, 0.0f};
    return table;
  }
  // Vose's method: scaled probabilities split into "small" (< 1) and "large".
  std::vector<double> scaled(n);
  std::vector<uint32_t> small, large;
  for (size_t i = 0; i < n; ++i) {
    const double w = weights[i] > 0.0 ? weights[i] : 0.0;
    table[i].pdf = float(w / sum);
    table[i].alias = uint32_t(i);
    scaled[i] = w / sum * double(n);
    (scaled[i] < 1.0 ? small : large).push_back(uint32_t(i));
  }
  while (!small.empty() && !large.empty()) {
    const uint32_t s = small.back(), l = large.back();
    small.pop_back();
    table[s].threshold = float(scaled[s]);
    table[s].alias = l;
    scaled[l] = (scaled[l] + scaled[s]) - 1.0;
    if (scaled[l] < 1.0) {
      large.pop_back();
      small.push_back(l);
    }
  }
  // Leftovers are 1 up to rounding.
  for (uint32_t i : large)
    table[i].threshold = 1.0f;
  for (uint32_t i : small)
    table[i].threshold = 1.0f;
  // An entry with zero weight must never be returned by its own slot.
  for (size_t i = 0; i < n; ++i) {
    if (table[i].pdf == 0.0f && table[i].alias == i) table[i].threshold = 0.0f;
  }
  return table;
}

void build_cdf_guide(const float* cdf, uint32_t n, uint32_t* guide) {
  for (uint32_t k = 0; k < n; ++k)
    guide[k] = find_interval(cdf, n, float(k) / float(n));
  guide[n] = n - 1;
}

void build_environment_tables(KernelScene& ks) {
  KEnvironment& env = ks.constants.environment;
  const uint32_t w = env.width, h = env.height;
  ks.env_conditional_cdf.assign(size_t(h) * (w + 1), 0.0f);
  ks.env_marginal_cdf.assign(h + 1, 0.0f);
  const KernelData kd = ks.view();
  std::vector<double> row_sums(h, 0.0);
  double total = 0.0;
  for (uint32_t y = 0; y < h; ++y) {
    float* row = ks.env_conditional_cdf.data() + size_t(y) * (w + 1);
    double acc = 0.0;
    for (uint32_t x = 0; x < w; ++x) {
      acc += double(env_texel_weight(kd, x, y));
      row[x + 1] = float(acc);
    }
    row_sums[y] = acc;
    total += acc;
    for (uint32_t x = 1; x <= w; ++x)
      row[x] = acc > 0.0 ? float(row[x] / acc) : float(x) / float(w);
    row[w] = 1.0f;
  }
  double acc = 0.0;
  for (uint32_t y = 0; y < h; ++y) {
    acc += row_sums[y];
    ks.env_marginal_cdf[y + 1] = total > 0.0 ? float(acc / total) : float(y + 1) / float(h);
  }
  ks.env_marginal_cdf[h] = 1.0f;
  env.map_integral = float(total);

  ks.env_marginal_guide.assign(h + 1, 0u);
  ks.env_conditional_guide.assign(size_t(h) * (w + 1), 0u);
  if (w > 0 && h > 0) {
    build_cdf_guide(ks.env_marginal_cdf.data(), h, ks.env_marginal_guide.data());
    for (uint32_t y = 0; y < h; ++y) {
      build_cdf_guide(ks.env_conditional_cdf.data() + size_t(y) * (w + 1), w,
                      ks.env_conditional_guide.data() + size_t(y) * (w + 1));
    }
  }
}

}  // namespace tandem
