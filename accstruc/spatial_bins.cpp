#include "accstruc/spatial_bins.h"

#include <algorithm>
#include <cmath>

namespace tandem::spatial {

namespace {

// bin_straddler for a reference in two bins (almost half of them): one
// plane, in the vertices' own layout. The axis is a template argument, so
// the coordinates sit in registers.
template <int a>
void bin_two_pieces(const Tri& t, const Ref& r, const SpatialAxes& ax, uint32_t b0,
                    SpatialBins& bins) {
  const uint32_t b1 = b0 + 1;
  const float plane = ax.planes[a][b1];
  F4 plo[2] = {kEmptyLo, kEmptyLo}, phi[2] = {kEmptyHi, kEmptyHi};
  for (int i = 0; i < 3; ++i) {
    const uint32_t b = std::clamp(bin_of(t.v[i][a], ax.lo[a], ax.scale[a], kSpatialBins), b0, b1);
    const float* p = t.v[i];
    const float* q = t.v[(i + 1) % 3];
    const F4 v = simd::load(p);
    plo[b - b0] = simd::min(plo[b - b0], v);
    phi[b - b0] = simd::max(phi[b - b0], v);
    if (p[a] > q[a]) std::swap(p, q);
    const float pa = p[a], qa = q[a];
    if (!(pa < plane && plane < qa)) continue;
    const F4 p4 = simd::load(p);
    const F4 x = p4 + (simd::load(q) - p4) * simd::set1((plane - pa) / (qa - pa));
    for (int side = 0; side < 2; ++side) {
      plo[side] = simd::min(plo[side], x);
      phi[side] = simd::max(phi[side], x);
    }
  }
  for (int side = 0; side < 2; ++side) {
    const uint32_t b = b0 + side;
    alignas(16) float l[4], h[4];
    simd::store(l, simd::max(plo[side], r.vlo()));
    simd::store(h, simd::min(phi[side], r.vhi()));
    l[a] = std::max(l[a], ax.planes[a][b]);
    h[a] = std::min(h[a], ax.planes[a][b + 1]);
    if (!(l[0] <= h[0] && l[1] <= h[1] && l[2] <= h[2])) continue;
    for (int c = 0; c < 3; ++c) {
      bins.lo[a][c][b] = min_f(bins.lo[a][c][b], l[c]);
      bins.hi[a][c][b] = max_f(bins.hi[a][c][b], h[c]);
    }
  }
}

// bin_straddler four planes or bins at a time: cross[j] is the box of the
// crossings at plane j, piece b the box of cross[b], cross[b + 1] and b's
// vertices.
template <int a>
void bin_pieces(const Tri& t, const Ref& r, const SpatialAxes& ax, uint32_t b0, uint32_t b1,
                SpatialBins& bins) {
  if (b1 == b0 + 1) return bin_two_pieces<a>(t, r, ax, b0, bins);
  constexpr uint32_t kLanes = kPadded + 4;  // groups from b0 may end past b1 + 4
  alignas(16) float cross_lo[3][kLanes], cross_hi[3][kLanes];
  const F4 empty_lo = simd::set1(kFloatMax), empty_hi = simd::set1(-kFloatMax);
  for (uint32_t g = b0; g <= b1 + 4; g += 4) {
    for (int c = 0; c < 3; ++c) {
      simd::storeu(cross_lo[c] + g, empty_lo);
      simd::storeu(cross_hi[c] + g, empty_hi);
    }
  }
  const float* planes = ax.planes[a];
  const float lo = ax.lo[a], scale = ax.scale[a];
  // Bin of x for narrowing an edge's planes: clamped in floats first, as
  // the end points may be far outside the node.
  const auto bin = [&](float x) {
    const float f = std::min((x - lo) * scale, float(kSpatialBins));
    return f > 0.0f ? std::min(uint32_t(f), kSpatialBins - 1) : 0u;
  };
  const F4 lane = simd::set(0.0f, 1.0f, 2.0f, 3.0f);
  for (int i = 0; i < 3; ++i) {
    const float* p = t.v[i];
    const float* q = t.v[(i + 1) % 3];
    if (p[a] > q[a]) std::swap(p, q);
    const float pa = p[a], qa = q[a];
    // The planes strictly between pa and qa lie within one bin of theirs
    // (the rounding of both is far below a bin where narrow is set).
    uint32_t j0 = b0 + 1, j1 = b1;
    if (ax.narrow[a]) {
      j0 = std::max(j0, bin(pa));
      j1 = std::min(j1, bin(qa) + 1);
    }
    if (j0 > j1) continue;
    const F4 pa4 = simd::set1(pa), qa4 = simd::set1(qa), len = simd::set1(qa - pa);
    const F4 last = simd::set1(float(j1));
    F4 p4[3], d4[3];
    for (int c = 0; c < 3; ++c) {
      p4[c] = simd::set1(p[c]);
      d4[c] = simd::set1(q[c] - p[c]);
    }
    for (uint32_t g = j0; g <= j1; g += 4) {
      const F4 plane = simd::loadu(planes + g);
      const F4 in = simd::mask_and(simd::mask_and(simd::lt(pa4, plane), simd::lt(plane, qa4)),
                                   simd::le(simd::set1(float(g)) + lane, last));
      if (simd::mask_bits(in) == 0) continue;
      const F4 s = (plane - pa4) / len;
      for (int c = 0; c < 3; ++c) {
        const F4 x = p4[c] + d4[c] * s;
        simd::storeu(cross_lo[c] + g,
                     simd::min(simd::loadu(cross_lo[c] + g), simd::select(in, x, empty_lo)));
        simd::storeu(cross_hi[c] + g,
                     simd::max(simd::loadu(cross_hi[c] + g), simd::select(in, x, empty_hi)));
      }
    }
  }
  alignas(16) float piece_lo[3][kLanes], piece_hi[3][kLanes];
  for (uint32_t g = b0; g <= b1; g += 4) {
    for (int c = 0; c < 3; ++c) {
      simd::storeu(piece_lo[c] + g,
                   simd::min(simd::loadu(cross_lo[c] + g), simd::loadu(cross_lo[c] + g + 1)));
      simd::storeu(piece_hi[c] + g,
                   simd::max(simd::loadu(cross_hi[c] + g), simd::loadu(cross_hi[c] + g + 1)));
    }
  }
  for (int i = 0; i < 3; ++i) {
    const uint32_t b = std::clamp(bin_of(t.v[i][a], lo, scale, kSpatialBins), b0, b1);
    for (int c = 0; c < 3; ++c) {
      piece_lo[c][b] = min_f(piece_lo[c][b], t.v[i][c]);
      piece_hi[c][b] = max_f(piece_hi[c][b], t.v[i][c]);
    }
  }
  const F4 last = simd::set1(float(b1));
  for (uint32_t g = b0; g <= b1; g += 4) {
    // As intersect(piece, ref), then max / min with the bin's planes on
    // the axis (std::max(x, p) is simd::max(p, x), ties and all).
    F4 l[3], h[3];
    for (int c = 0; c < 3; ++c) {
      l[c] = simd::max(simd::loadu(piece_lo[c] + g), simd::set1(r.lo[c]));
      h[c] = simd::min(simd::loadu(piece_hi[c] + g), simd::set1(r.hi[c]));
    }
    l[a] = simd::max(simd::loadu(planes + g), l[a]);
    h[a] = simd::min(simd::loadu(planes + g + 1), h[a]);
    const F4 keep = simd::mask_and(
        simd::mask_and(simd::le(l[0], h[0]), simd::le(l[1], h[1])),
        simd::mask_and(simd::le(l[2], h[2]), simd::le(simd::set1(float(g)) + lane, last)));
    if (simd::mask_bits(keep) == 0) continue;
    for (int c = 0; c < 3; ++c) {
      float* blo = bins.lo[a][c] + g;
      float* bhi = bins.hi[a][c] + g;
      simd::storeu(blo, simd::min(simd::loadu(blo), simd::select(keep, l[c], empty_lo)));
      simd::storeu(bhi, simd::max(simd::loadu(bhi), simd::select(keep, h[c], empty_hi)));
    }
  }
}

}  // namespace

void bin_straddler(const Tri& t, const Ref& r, int a, const SpatialAxes& ax, uint32_t b0,
                   uint32_t b1, SpatialBins& bins) {
  if (a == 0) bin_pieces<0>(t, r, ax, b0, b1, bins);
  if (a == 1) bin_pieces<1>(t, r, ax, b0, b1, bins);
  if (a == 2) bin_pieces<2>(t, r, ax, b0, b1, bins);
}

}  // namespace tandem::spatial
