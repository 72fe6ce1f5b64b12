// Internal to accstruc/spatial_bvh.cpp: the spatial builder's references
// and its spatial bins, and the binning of a reference that straddles bins
// (spatial_bins.cpp), the builder's hottest loop.
#pragma once

#include <cstdint>
#include <cstring>

#include "accstruc/bvh_builder.h"
#include "accstruc/simd4.h"

namespace tandem::spatial {

using simd::F4;

constexpr uint32_t kSpatialBins = 16;

inline const F4 kEmptyLo = simd::set1(kFloatMax), kEmptyHi = simd::set1(-kFloatMax);

// A reference: a (clipped) box of one triangle, the id in the fourth lane
// of lo (masked off before any arithmetic), hi's fourth lane zero.
struct alignas(16) Ref {
  float lo[4];
  float hi[4];
  static Ref make(const Aabb& b, uint32_t id) {
    Ref r;
    r.lo[0] = b.lo.x, r.lo[1] = b.lo.y, r.lo[2] = b.lo.z;
    std::memcpy(&r.lo[3], &id, 4);
    r.hi[0] = b.hi.x, r.hi[1] = b.hi.y, r.hi[2] = b.hi.z, r.hi[3] = 0.0f;
    return r;
  }
  uint32_t id() const {
    uint32_t v;
    std::memcpy(&v, &lo[3], 4);
    return v;
  }
  F4 vlo() const { return simd::xyz(simd::load(lo)); }
  F4 vhi() const { return simd::load(hi); }
  Aabb box() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
  // As Aabb::center(), one axis.
  float center(int a) const { return (lo[a] + hi[a]) * 0.5f; }
};

// A triangle's vertices, fourth lanes zero.
struct alignas(16) Tri {
  float v[3][4];
};

// Bin b clamped to [0, k); the bin of coordinate x of k bins from lo.
inline uint32_t clamp_bin(int32_t b, uint32_t k) {
  return b <= 0 ? 0u : (uint32_t(b) < k ? uint32_t(b) : k - 1);
}
inline uint32_t bin_of(float x, float lo, float scale, uint32_t k) {
  return clamp_bin(int32_t((x - lo) * scale), k);
}

// Spatial bins as structures of arrays, [axis][coordinate][bin], so that
// four bins' pieces are clipped and grown at once; padded for 4-wide
// access past the last bin (the padding stays empty).
constexpr uint32_t kPadded = kSpatialBins + 4;
struct SpatialBins {
  alignas(16) float lo[3][3][kPadded];
  alignas(16) float hi[3][3][kPadded];
  uint32_t enter[3][kSpatialBins], leave[3][kSpatialBins];
  void reset(const bool active[3]) {
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (int c = 0; c < 3; ++c) {
        std::fill_n(lo[a][c], kPadded, kFloatMax);
        std::fill_n(hi[a][c], kPadded, -kFloatMax);
      }
      std::fill_n(enter[a], kSpatialBins, 0u);
      std::fill_n(leave[a], kSpatialBins, 0u);
    }
  }
  // Merges a later chunk's bins (see the file comment on why in order).
  void merge(const SpatialBins& o, const bool active[3]) {
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (int c = 0; c < 3; ++c) {
        for (uint32_t i = 0; i < kSpatialBins; i += 4) {
          simd::storeu(lo[a][c] + i,
                       simd::min(simd::loadu(lo[a][c] + i), simd::loadu(o.lo[a][c] + i)));
          simd::storeu(hi[a][c] + i,
                       simd::max(simd::loadu(hi[a][c] + i), simd::loadu(o.hi[a][c] + i)));
        }
      }
      for (uint32_t i = 0; i < kSpatialBins; ++i) {
        enter[a][i] += o.enter[a][i];
        leave[a][i] += o.leave[a][i];
      }
    }
  }
  // A whole reference into one bin, as Aabb::grow.
  void grow(int a, uint32_t b, const Ref& r) {
    for (int c = 0; c < 3; ++c) {
      lo[a][c][b] = min_f(lo[a][c][b], r.lo[c]);
      hi[a][c][b] = max_f(hi[a][c][b], r.hi[c]);
    }
  }
  void boxes(int a, F4* out_lo, F4* out_hi) const {
    for (uint32_t i = 0; i < kSpatialBins; ++i) {
      out_lo[i] = simd::set(lo[a][0][i], lo[a][1][i], lo[a][2][i], 0.0f);
      out_hi[i] = simd::set(hi[a][0][i], hi[a][1][i], hi[a][2][i], 0.0f);
    }
  }
};

// The spatial bins' planes along each axis of a node's box.
struct SpatialAxes {
  bool active[3] = {false, false, false};
  // Whether an edge's plane range may be narrowed by its end points' bins:
  // the bins are wide against the rounding of the coordinates.
  bool narrow[3] = {false, false, false};
  float lo[3] = {0, 0, 0}, scale[3] = {0, 0, 0};
  // planes[a][i], i <= kSpatialBins; the padding repeats the last.
  alignas(16) float planes[3][kPadded];
  F4 origin, scale4;
};

// Grows the bins b0..b1 (b0 < b1) of axis a by the boxes of the triangle's
// pieces in them (within the reference's box): every vertex goes to its
// bin, every crossing of an edge with an inner plane to the bins on both
// sides. For the cost estimate only (no padding; a split itself clips with
// the builder's clip_triangle). The values are those of a serial loop over
// edges and planes with Aabb::grow; only the order of the min / max
// differs, which can at most flip the sign of a zero: no cost changes.
void bin_straddler(const Tri& t, const Ref& r, int a, const SpatialAxes& ax, uint32_t b0,
                   uint32_t b1, SpatialBins& bins);

}  // namespace tandem::spatial
