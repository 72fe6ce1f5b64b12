// Directional albedo of the sheen lobe (sheen.h), which the layering in
// bsdf.h uses to dim the base by what the sheen reflected: the glTF spec's
// "albedo scaling", which keeps the sheen-over-base sum at most 1.
//
// The albedo has no closed form; tools/tables/sheen_albedo.cpp integrates
// sheen_brdf numerically on a grid and writes sheen_albedo_table.h, and
// tests/kernel_layers_test.cpp re-integrates a sample of its entries.
#pragma once

#include "core/kernel/sheen.h"
#include "core/kernel/sheen_albedo_table.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Directional albedo of sheen_brdf, integral of f cos over the hemisphere,
// bilinear in the table of sheen_albedo_table.h. Its nodes are uniform in
// sqrt(cos_theta) and sqrt(roughness - kMinSheenRoughness): the albedo
// changes fastest at grazing views and for smooth sheens (from 2.7 to 0.8
// between cos 0 and 0.03 at the smallest roughness), where a uniform grid
// was off by 15%. Roughness below kMinSheenRoughness reads the clamped
// value, like the lobe.
TANDEM_HD float sheen_albedo(float cos_theta, float roughness) {
  constexpr int n = kSheenAlbedoSize;
  const float r = (max_f(saturate(roughness), kMinSheenRoughness) - kMinSheenRoughness) *
                  (1.0f / (1.0f - kMinSheenRoughness));
  const float x = sqrtf(saturate(cos_theta)) * float(n - 1);
  const float y = sqrtf(saturate(r)) * float(n - 1);
  const int x0 = int(min_f(x, float(n - 2))), y0 = int(min_f(y, float(n - 2)));
  const float tx = x - float(x0), ty = y - float(y0);
  const int i = y0 * n + x0;
  const float a = sheen_albedo_entry(i), b = sheen_albedo_entry(i + 1);
  const float c = sheen_albedo_entry(i + n), d = sheen_albedo_entry(i + n + 1);
  return (a + (b - a) * tx) * (1.0f - ty) + (c + (d - c) * tx) * ty;
}

TANDEM_KERNEL_END
}  // namespace tandem
