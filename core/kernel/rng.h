// Counter-based random numbers.
//
// Every random number is a pure function of (pixel, sample index, frame seed,
// dimension). No state is carried between pixels or threads, so an image does
// not depend on thread count, tile order, or which backend rendered a tile:
// the CPU, host and CUDA backends draw exactly the same numbers for a path.
#pragma once

#include "core/kernel/defines.h"

namespace tandem {

// 32-bit integer finaliser with low avalanche bias (constants found by
// Chris Wellons' hash-prospector search, published as public domain).
TANDEM_HD uint32_t hash_u32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

TANDEM_HD uint32_t hash_combine(uint32_t seed, uint32_t v) { return hash_u32(seed ^ hash_u32(v)); }

// Maps 24 random bits to [0, 1): exactly representable, never returns 1.
TANDEM_HD float u32_to_unit_float(uint32_t x) { return float(x >> 8) * (1.0f / 16777216.0f); }

// Well-known dimension offsets so a sampling decision always reads the same
// stream position regardless of what the path did before (keeps CPU/GPU paths
// aligned even when code order differs slightly).
enum RngDimension : uint32_t {
  kDimPixelJitter = 0,  // 2 dims
  kDimLens = 2,         // 2 dims
  kDimBounceBase = 4,   // first bounce starts here
  kDimsPerBounce = 12,  // light select, light uv (2), bsdf lobe, bsdf uv (2), rr, alpha, spare
};
enum BounceDimension : uint32_t {
  kBounceLightSelect = 0,
  kBounceLightU = 1,
  kBounceLightV = 2,
  kBounceLobe = 3,
  kBounceBsdfU = 4,
  kBounceBsdfV = 5,
  kBounceRoulette = 6,
  kBounceAlpha = 7,  // stochastic transparency key for rays leaving this vertex
  kBounceShadowAlpha = 8,
};

struct PathRng {
  uint32_t key;     // hash of (pixel, frame seed)
  uint32_t sample;  // sample index within the pixel
};

TANDEM_HD PathRng make_path_rng(uint32_t pixel_index, uint32_t sample_index, uint32_t seed) {
  return {hash_combine(hash_u32(seed ^ 0x9e3779b9u), pixel_index), sample_index};
}

TANDEM_HD uint32_t rng_bits(const PathRng& r, uint32_t dimension) {
  return hash_combine(r.key ^ hash_u32(dimension * 0x632be5abu + 0x85ebca6bu), r.sample);
}

TANDEM_HD float rng_1d(const PathRng& r, uint32_t dimension) {
  return u32_to_unit_float(rng_bits(r, dimension));
}

TANDEM_HD uint32_t bounce_dimension(uint32_t bounce, uint32_t which) {
  return kDimBounceBase + bounce * kDimsPerBounce + which;
}

}  // namespace tandem
