// Counter-based random numbers.
//
// Every random number is a pure function of (pixel, sample index, frame seed,
// dimension). No state is carried between pixels or threads, so an image does
// not depend on thread count, tile order, or which backend rendered a tile:
// the CPU, host and CUDA backends draw exactly the same numbers for a path.
#pragma once

#include "core/kernel/defines.h"
#include "core/kernel/math.h"
#include "core/kernel/rng_tables.h"

namespace tandem {

// 32-bit integer finaliser with low avalanche bias (constants found by
// Chris Wellons' hash-prospector search, published as public domain).
TANDEM_HD_INLINE uint32_t hash_u32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

TANDEM_HD_INLINE uint32_t hash_combine(uint32_t seed, uint32_t v) {
  return hash_u32(seed ^ hash_u32(v));
}

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
  uint32_t key;              // hash of (pixel, frame seed)
  uint32_t sample;           // sample index within the pixel
  uint32_t sample_reversed;  // its bit reversal, which every draw starts from
};

TANDEM_HD_INLINE PathRng make_path_rng(uint32_t pixel_index, uint32_t sample_index, uint32_t seed) {
  return {hash_combine(hash_u32(seed ^ 0x9e3779b9u), pixel_index), sample_index,
          reverse_bits_u32(sample_index)};
}

// Uniform random bits with no stratification (keys for stochastic alpha).
TANDEM_HD_INLINE uint32_t rng_bits(const PathRng& r, uint32_t dimension) {
  return hash_combine(r.key ^ hash_u32(dimension * 0x632be5abu + 0x85ebca6bu), r.sample);
}

// --- Low-discrepancy samples ----------------------------------------------
// Sampling decisions draw from the first two dimensions of the Sobol
// sequence, randomised with hash-based Owen scrambling (Burley 2020,
// "Practical Hash-based Owen Scrambling"): each pair of dimensions that is
// used together (pixel jitter, lens, light uv, BSDF uv) gets its own
// per-pixel scramble and its own shuffle of the sample index, so pairs are
// decorrelated while each pair stays stratified over any power-of-two prefix
// of the samples, including when samples accumulate over many frames. One-
// dimensional decisions (light selection, lobe, roulette) use the scrambled
// van der Corput sequence the same way. Everything remains a pure function of
// (pixel, sample, seed, dimension).

// A random permutation of 32-bit integers in which each bit is flipped
// depending only on the bits below it (the Laine & Karras 2011 form, in the
// improved variant of Burley 2020). Applied to bit-reversed input it is a
// nested uniform (Owen) scramble: owen(x) = reverse(lk_permute(reverse(x))).
// Split in three so that the CPU's cached draws can compute the parts that
// depend only on the input (the sample) or only on the seed once:
// lk_permute(x, seed) = lk_permute_rest(lk_permute_mix(x), seed, lk_permute_mult(seed)).
TANDEM_HD_INLINE uint32_t lk_permute_mix(uint32_t x) {
  return x ^ x * 0x3d20adeau;
}
TANDEM_HD_INLINE uint32_t lk_permute_mult(uint32_t seed) {
  return (seed >> 16) | 1u;
}
TANDEM_HD_INLINE uint32_t lk_permute_rest(uint32_t mixed, uint32_t seed, uint32_t mult) {
  uint32_t x = (mixed + seed) * mult;
  x ^= x * 0x05526c56u;
  x ^= x * 0x53a22864u;
  return x;
}
TANDEM_HD_INLINE uint32_t lk_permute(uint32_t x, uint32_t seed) {
  return lk_permute_rest(lk_permute_mix(x), seed, lk_permute_mult(seed));
}

// Second Sobol dimension (primitive polynomial x + 1), whose generator matrix
// is Pascal's triangle mod 2; the first dimension is the bit reversal of the
// index.
TANDEM_HD_INLINE uint32_t sobol_dimension1(uint32_t index) {
  return reverse_bits_u32(pascal_mod2(index));
}

// The pair a dimension belongs to (first dimension of the pair) and its
// component in it (0 or 1); dimensions used alone are pairs of one.
TANDEM_HD_INLINE void rng_pair_of(uint32_t dimension, uint32_t* pair, uint32_t* component) {
  uint32_t first = dimension;
  if (dimension < kDimBounceBase) {
    first = dimension & ~1u;  // jitter (0, 1), lens (2, 3)
  } else {
    const uint32_t which = (dimension - kDimBounceBase) % kDimsPerBounce;
    if (which == kBounceLightV || which == kBounceBsdfV) first = dimension - 1;
  }
  *pair = first;
  *component = dimension - first;
}

// A pair's own seed and its shuffle of the sample index:
// index = owen(sample) = reverse(shuffle), shuffle = lk_permute(reverse(sample)).
// The draws take the shuffle and reverse it themselves: the second
// component wants pascal_mod2(index), which the CPU looks up from the
// shuffle directly (rng_tables.h).
TANDEM_HD_INLINE uint32_t rng_pair_seed(const PathRng& r, uint32_t pair) {
  // r.key is already a hash of (pixel, seed): one more round per pair suffices.
  return hash_u32(r.key ^ (pair * 0x9e3779b9u + 0x632be5abu));
}
TANDEM_HD_INLINE uint32_t rng_pair_shuffle(const PathRng& r, uint32_t pair_seed) {
  return lk_permute(r.sample_reversed, pair_seed);
}

// The scramble of component c of a pair (a function of the pixel and the
// dimension only, not of the sample).
TANDEM_HD_INLINE uint32_t rng_component_seed(uint32_t pair_seed, uint32_t component) {
  return hash_u32(pair_seed + component + 1u);
}

// Component c of the pair: point = sobol_c(index), value = owen(point), with
// the reversals that cancel left out: reverse(sobol_0(i)) = i and
// reverse(sobol_1(i)) = pascal_mod2(i), for index = reverse(shuffle).
TANDEM_HD_INLINE float rng_pair_component_seeded(uint32_t shuffle, uint32_t component_seed,
                                                 uint32_t component) {
  const uint32_t reversed_point =
      component == 0 ? reverse_bits_u32(shuffle) : pascal_mod2_of_reversed(shuffle);
  return unit_float_of_reversed(lk_permute(reversed_point, component_seed));
}
TANDEM_HD_INLINE float rng_pair_component(uint32_t shuffle, uint32_t pair_seed,
                                          uint32_t component) {
  return rng_pair_component_seeded(shuffle, rng_component_seed(pair_seed, component), component);
}

TANDEM_HD_INLINE float rng_1d(const PathRng& r, uint32_t dimension) {
  uint32_t pair, component;
  rng_pair_of(dimension, &pair, &component);
  const uint32_t seed = rng_pair_seed(r, pair);
  return rng_pair_component(rng_pair_shuffle(r, seed), seed, component);
}

// rng_1d of a dimension that is not part of a pair (light selection, lobe,
// roulette: rng_pair_of gives (dimension, 0) for them), without looking
// that up: the same number.
TANDEM_HD_INLINE float rng_1d_unpaired(const PathRng& r, uint32_t dimension) {
  const uint32_t seed = rng_pair_seed(r, dimension);
  return rng_pair_component(rng_pair_shuffle(r, seed), seed, 0);
}

// Both dimensions of the pair starting at `first` (pixel jitter, lens, light
// or BSDF uv) at the cost of little more than one: exactly
// {rng_1d(r, first), rng_1d(r, first + 1)}.
TANDEM_HD_INLINE Vec2 rng_2d(const PathRng& r, uint32_t first) {
  const uint32_t seed = rng_pair_seed(r, first);
  const uint32_t shuffle = rng_pair_shuffle(r, seed);
  return {rng_pair_component(shuffle, seed, 0), rng_pair_component(shuffle, seed, 1)};
}

TANDEM_HD_INLINE uint32_t bounce_dimension(uint32_t bounce, uint32_t which) {
  return kDimBounceBase + bounce * kDimsPerBounce + which;
}

// The integrator's draws, by bounce and BounceDimension. PixelRngCache (a
// CPU-side cache of the sample-independent hashes) has the same three with
// the same results.
TANDEM_HD_INLINE Vec2 bounce_rng_2d(const PathRng& r, uint32_t bounce, uint32_t which) {
  return rng_2d(r, bounce_dimension(bounce, which));
}
TANDEM_HD_INLINE float bounce_rng_1d(const PathRng& r, uint32_t bounce, uint32_t which) {
  return rng_1d_unpaired(r, bounce_dimension(bounce, which));
}
TANDEM_HD_INLINE uint32_t bounce_rng_bits(const PathRng& r, uint32_t bounce, uint32_t which) {
  return rng_bits(r, bounce_dimension(bounce, which));
}

// The draws of one bounce, with the bounce fixed: the integrator takes this
// once per hit (rng_at_bounce) and draws from it, so that the CPU's cached
// generator looks its bounce up once per hit rather than once per draw.
struct PathBounceRng {
  PathRng rng;
  uint32_t bounce;
};
TANDEM_HD_INLINE PathBounceRng rng_at_bounce(const PathRng& r, uint32_t bounce) {
  return {r, bounce};
}
TANDEM_HD_INLINE Vec2 bounce_rng_2d(const PathBounceRng& b, uint32_t which) {
  return bounce_rng_2d(b.rng, b.bounce, which);
}
TANDEM_HD_INLINE float bounce_rng_1d(const PathBounceRng& b, uint32_t which) {
  return bounce_rng_1d(b.rng, b.bounce, which);
}
TANDEM_HD_INLINE uint32_t bounce_rng_bits(const PathBounceRng& b, uint32_t which) {
  return bounce_rng_bits(b.rng, b.bounce, which);
}

// --- The sample-independent part of a pixel's draws, cached ---------------
// Of the five hashes of a 2-d draw (pair seed, index shuffle, two component
// scrambles, and the key's), three depend on (pixel, seed, dimension) only:
// the CPU tile loop, which renders all of a pixel's samples of a pass in a
// row, computes them once per pixel and bounce instead of once per sample.
// The draws give exactly the numbers of the PathRng functions above.
// Each seed comes with its lk_permute_mult, and the draws take the sample's
// lk_permute_mix (CachedPathRng), so that a draw computes only
// lk_permute_rest of them.
struct SingleSeeds {
  uint32_t pair, pair_mult;    // rng_pair_seed
  uint32_t comp0, comp0_mult;  // rng_component_seed(pair, 0)
};
struct PairSeeds {
  SingleSeeds first;           // the pair's seed and its first component's
  uint32_t comp1, comp1_mult;  // rng_component_seed(pair, 1)
};

TANDEM_HD_INLINE SingleSeeds make_single_seeds(uint32_t key, uint32_t dimension) {
  const PathRng r{key, 0u, 0u};
  SingleSeeds s;
  s.pair = rng_pair_seed(r, dimension);
  s.comp0 = rng_component_seed(s.pair, 0);
  s.pair_mult = lk_permute_mult(s.pair);
  s.comp0_mult = lk_permute_mult(s.comp0);
  return s;
}
TANDEM_HD_INLINE PairSeeds make_pair_seeds(uint32_t key, uint32_t pair_dimension) {
  PairSeeds s;
  s.first = make_single_seeds(key, pair_dimension);
  s.comp1 = rng_component_seed(s.first.pair, 1);
  s.comp1_mult = lk_permute_mult(s.comp1);
  return s;
}

// rng_2d and rng_1d_unpaired from the precomputed parts.
TANDEM_HD_INLINE Vec2 rng_2d_seeded(uint32_t sample_mixed, const PairSeeds& s) {
  const SingleSeeds& f = s.first;
  const uint32_t shuffle = lk_permute_rest(sample_mixed, f.pair, f.pair_mult);
  uint32_t point0, point1;
  reverse_and_pascal(shuffle, &point0, &point1);
  return {unit_float_of_reversed(lk_permute_rest(lk_permute_mix(point0), f.comp0, f.comp0_mult)),
          unit_float_of_reversed(lk_permute_rest(lk_permute_mix(point1), s.comp1, s.comp1_mult))};
}
TANDEM_HD_INLINE float rng_1d_seeded(uint32_t sample_mixed, const SingleSeeds& s) {
  const uint32_t point0 = reverse_bits_u32(lk_permute_rest(sample_mixed, s.pair, s.pair_mult));
  return unit_float_of_reversed(lk_permute_rest(lk_permute_mix(point0), s.comp0, s.comp0_mult));
}

// The seeds of the draws of one bounce (kBounceLightSelect .. kBounceRoulette;
// the alpha keys are plain hashes of the sample and are not cached).
struct BounceSeeds {
  SingleSeeds light_select;
  PairSeeds light_uv;
  SingleSeeds lobe;
  PairSeeds bsdf_uv;
  SingleSeeds roulette;
};

TANDEM_HD_NOINLINE void fill_bounce_seeds(uint32_t key, uint32_t bounce, BounceSeeds* b) {
  const uint32_t d = bounce_dimension(bounce, 0);
  b->light_select = make_single_seeds(key, d + kBounceLightSelect);
  b->light_uv = make_pair_seeds(key, d + kBounceLightU);
  b->lobe = make_single_seeds(key, d + kBounceLobe);
  b->bsdf_uv = make_pair_seeds(key, d + kBounceBsdfU);
  b->roulette = make_single_seeds(key, d + kBounceRoulette);
}

struct PixelRngCache {
  static constexpr uint32_t kMaxBounces = 16;  // deeper bounces share `deep`
  uint32_t key;                                // PathRng::key of the pixel
  uint32_t bounces_filled;                     // bounce[0 .. bounces_filled) are valid
  uint32_t deep_bounce;                        // the bounce `deep` holds (or ~0u)
  bool lens_filled;                            // only thin-lens cameras draw the lens
  PairSeeds jitter, lens;
  BounceSeeds bounce[kMaxBounces];
  BounceSeeds deep;
};

TANDEM_HD_INLINE void pixel_rng_cache_reset(PixelRngCache* c, uint32_t pixel_index, uint32_t seed) {
  c->key = make_path_rng(pixel_index, 0u, seed).key;
  c->bounces_filled = 0;
  c->deep_bounce = ~0u;
  c->lens_filled = false;
  c->jitter = make_pair_seeds(c->key, kDimPixelJitter);
}

TANDEM_HD_NOINLINE void fill_lens_seeds(PixelRngCache* c) {
  c->lens = make_pair_seeds(c->key, kDimLens);
  c->lens_filled = true;
}

// A path's generator with its pixel's cache: the same numbers as `rng`.
struct CachedPathRng {
  PathRng rng;
  PixelRngCache* cache;   // filled lazily, bounce by bounce
  uint32_t sample_mixed;  // lk_permute_mix(rng.sample_reversed), shared by every draw

  TANDEM_HD_INLINE CachedPathRng(const PathRng& r, PixelRngCache* c)
      : rng(r), cache(c), sample_mixed(lk_permute_mix(r.sample_reversed)) {}
};

TANDEM_HD_INLINE const BounceSeeds* cached_bounce_seeds(const CachedPathRng& r, uint32_t bounce) {
  PixelRngCache* c = r.cache;
  if (bounce >= PixelRngCache::kMaxBounces) {
    if (c->deep_bounce != bounce) {
      fill_bounce_seeds(c->key, bounce, &c->deep);
      c->deep_bounce = bounce;
    }
    return &c->deep;
  }
  for (; c->bounces_filled <= bounce; ++c->bounces_filled)
    fill_bounce_seeds(c->key, c->bounces_filled, &c->bounce[c->bounces_filled]);
  return &c->bounce[bounce];
}

// One bounce of a cached generator (rng_at_bounce).
struct CachedBounceRng {
  const BounceSeeds* seeds;
  uint32_t sample_mixed;
  PathRng rng;  // for the alpha keys
  uint32_t bounce;
};
TANDEM_HD_INLINE CachedBounceRng rng_at_bounce(const CachedPathRng& r, uint32_t bounce) {
  return {cached_bounce_seeds(r, bounce), r.sample_mixed, r.rng, bounce};
}
TANDEM_HD_INLINE Vec2 bounce_rng_2d(const CachedBounceRng& b, uint32_t which) {
  return rng_2d_seeded(b.sample_mixed,
                       which == kBounceLightU ? b.seeds->light_uv : b.seeds->bsdf_uv);
}
TANDEM_HD_INLINE float bounce_rng_1d(const CachedBounceRng& b, uint32_t which) {
  return rng_1d_seeded(b.sample_mixed, which == kBounceLightSelect ? b.seeds->light_select
                                       : which == kBounceLobe      ? b.seeds->lobe
                                                                   : b.seeds->roulette);
}
TANDEM_HD_INLINE uint32_t bounce_rng_bits(const CachedBounceRng& b, uint32_t which) {
  return bounce_rng_bits(b.rng, b.bounce, which);
}

// The cached generator's draws by bounce, as PathRng's.
TANDEM_HD_INLINE Vec2 bounce_rng_2d(const CachedPathRng& r, uint32_t bounce, uint32_t which) {
  return bounce_rng_2d(rng_at_bounce(r, bounce), which);
}
TANDEM_HD_INLINE float bounce_rng_1d(const CachedPathRng& r, uint32_t bounce, uint32_t which) {
  return bounce_rng_1d(rng_at_bounce(r, bounce), which);
}
TANDEM_HD_INLINE uint32_t bounce_rng_bits(const CachedPathRng& r, uint32_t bounce, uint32_t which) {
  return bounce_rng_bits(r.rng, bounce, which);
}

// The camera's two pairs.
TANDEM_HD_INLINE Vec2 rng_jitter_2d(const PathRng& r) {
  return rng_2d(r, kDimPixelJitter);
}
TANDEM_HD_INLINE Vec2 rng_lens_2d(const PathRng& r) {
  return rng_2d(r, kDimLens);
}
TANDEM_HD_INLINE Vec2 rng_jitter_2d(const CachedPathRng& r) {
  return rng_2d_seeded(r.sample_mixed, r.cache->jitter);
}
TANDEM_HD_INLINE Vec2 rng_lens_2d(const CachedPathRng& r) {
  PixelRngCache* c = r.cache;
  if (!c->lens_filled) fill_lens_seeds(c);
  return rng_2d_seeded(r.sample_mixed, c->lens);
}

}  // namespace tandem
