// Spatial-split BVH builder for static triangle meshes (Stich, Friedrich &
// Dietrich 2009, "Spatial Splits in Bounding Volume Hierarchies"): binned
// SAH object splits, and where the best object split's children overlap by
// more than alpha of the root's area, binned spatial splits that clip the
// triangles straddling a plane into one reference per side (with reference
// unsplitting). The number of extra references is bounded by
// BuildSettings::spatial_split_budget; each node hands its unused budget to
// its children in proportion to their sizes, so the tree does not depend on
// the task scheduling.
//
// The result lists a triangle once per reference (BuildTree::prims may hold
// an id more than once, never twice in one leaf) and carries each
// reference's clipped box (BuildTree::ref_boxes), which the layouts use for
// the boxes of split leaves. A refit cannot keep such a tree (the clipped
// boxes are not functions of the triangles' boxes): meshes that deform are
// built by build_bvh() instead.
//
// Speed without changing the trees: references are 32-byte records binned
// with four-float vectors (the same min/max and products as Aabb's, so the
// same bits), all three axes in one pass; triangles are copied once into a
// contiguous vertex array; a straddling reference's pieces touch only the
// bins and planes its edges reach; large nodes bin in fixed chunks that are
// merged in order (a <-- a < b ? a : b keeps the last of equal minima in
// either order, so the bins are those of the serial pass); leaves go to one
// array instead of a vector each.
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "accstruc/bvh_builder.h"
#include "accstruc/simd4.h"
#include "accstruc/spatial_bins.h"

namespace tandem {

namespace {

using simd::F4;
using namespace spatial;

constexpr uint32_t kObjectBins = 16;
constexpr uint32_t kParallelRefs = 4096;
// Nodes with at least this many references bin in chunks of kBinChunk in
// parallel; below it one task bins the whole node.
constexpr uint32_t kParallelBinRefs = 1u << 15;
constexpr uint32_t kBinChunk = 1u << 13;
// References ahead whose triangles the spatial binning prefetches.
constexpr size_t kPrefetch = 8;
// Meshes with fewer triangles are built by build_bvh().
constexpr size_t kMinSpatialTriangles = 1024;

float lo_of(const Aabb& b, int a) {
  return a == 0 ? b.lo.x : (a == 1 ? b.lo.y : b.lo.z);
}
float hi_of(const Aabb& b, int a) {
  return a == 0 ? b.hi.x : (a == 1 ? b.hi.y : b.hi.z);
}
void set_lo(Aabb& b, int a, float v) {
  (a == 0 ? b.lo.x : (a == 1 ? b.lo.y : b.lo.z)) = v;
}
void set_hi(Aabb& b, int a, float v) {
  (a == 0 ? b.hi.x : (a == 1 ? b.hi.y : b.hi.z)) = v;
}

Aabb intersect(const Aabb& a, const Aabb& b) {
  Aabb r;
  r.lo = max_v(a.lo, b.lo);
  r.hi = min_v(a.hi, b.hi);
  return r;
}

Aabb to_aabb(F4 lo, F4 hi) {
  alignas(16) float l[4], h[4];
  simd::store(l, lo);
  simd::store(h, hi);
  return {{l[0], l[1], l[2]}, {h[0], h[1], h[2]}};
}

// Box of the part of triangle t with lo <= x_axis <= hi, within `ref`.
// Conservative: the edge crossings of the planes are padded by a few ulps in
// the other two coordinates; on the axis the box ends exactly at the planes,
// so the two sides of a split meet without a gap.
Aabb clip_triangle(const Vec3 t[3], const Aabb& ref, int axis, float lo, float hi) {
  // Padding of the cut on the axis: a few ulps of the box's magnitude, so
  // that a ray's entry into the piece cannot round past a hit that the
  // triangle test finds on the plane.
  const float mag = std::max(max_component(max_v(ref.lo * -1.0f, ref.lo)),
                             max_component(max_v(ref.hi * -1.0f, ref.hi)));
  const float cut_pad = mag * 2e-6f + 1e-30f;
  Aabb b;
  for (int i = 0; i < 3; ++i) {
    const Vec3 p = t[i], q = t[(i + 1) % 3];
    const float pa = component(p, axis), qa = component(q, axis);
    if (pa >= lo && pa <= hi) b.grow(p);
    const float planes[2] = {lo, hi};
    for (float plane : planes) {
      if (!((pa < plane && qa > plane) || (pa > plane && qa < plane))) continue;
      const float s = (plane - pa) / (qa - pa);
      const Vec3 x = p + (q - p) * s;
      Vec3 pad{std::fabs(x.x), std::fabs(x.y), std::fabs(x.z)};
      pad = pad * 1e-6f + Vec3{1e-30f, 1e-30f, 1e-30f};
      Aabb c{x - pad, x + pad};
      set_lo(c, axis, plane - cut_pad);
      set_hi(c, axis, plane + cut_pad);
      b.grow(c);
    }
  }
  b = intersect(b, ref);
  set_lo(b, axis, std::max(lo_of(b, axis), lo - cut_pad));
  set_hi(b, axis, std::min(hi_of(b, axis), hi + cut_pad));
  return b;
}

struct ObjectSplit {
  int axis = -1;
  uint32_t bin = 0;
  double cost = 0.0;
  Aabb left, right;
  Aabb cbox;  // centroid box the bins were laid over
};

struct SpatialSplit {
  int axis = -1;
  float plane = 0.0f;
  double cost = 0.0;
};

// Bins of the three axes as vectors; only the first k of each active axis
// are reset and used.
struct BinSet {
  F4 lo[3][kObjectBins];
  F4 hi[3][kObjectBins];
  uint32_t count[3][kObjectBins];
  void reset(uint32_t k, const bool active[3]) {
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (uint32_t i = 0; i < k; ++i) {
        lo[a][i] = kEmptyLo;
        hi[a][i] = kEmptyHi;
        count[a][i] = 0;
      }
    }
  }
  // Merges a later chunk's bins (see the file comment on why in order).
  void merge(const BinSet& o, uint32_t k, const bool active[3]) {
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (uint32_t i = 0; i < k; ++i) {
        lo[a][i] = simd::min(lo[a][i], o.lo[a][i]);
        hi[a][i] = simd::max(hi[a][i], o.hi[a][i]);
        count[a][i] += o.count[a][i];
      }
    }
  }
};

// Runs body(out, begin, end) over [0, n) after init(out): serially below
// kParallelBinRefs, else over fixed chunks in parallel (the first into out),
// merged in chunk order (merge(out, later)), so the result does not depend
// on the scheduling.
template <class T, class Init, class Body, class Merge>
void chunked(size_t n, T& out, Init init, Body body, Merge merge) {
  init(out);
  if (n < kParallelBinRefs) {
    body(out, size_t(0), n);
    return;
  }
  const size_t chunks = (n + kBinChunk - 1) / kBinChunk;
  std::vector<T> part(chunks - 1);
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    T& t = c == 0 ? out : part[c - 1];
    if (c > 0) init(t);
    body(t, c * kBinChunk, std::min(n, (c + 1) * kBinChunk));
  });
  for (const T& t : part)
    merge(out, t);
}

class SpatialBuilder {
 public:
  SpatialBuilder(std::span<const Aabb> boxes, std::span<const Vec3> positions,
                 std::span<const KTriangle> triangles, const BuildSettings& s)
      : boxes_(boxes), positions_(positions), triangles_(triangles), s_(s) {
    s_.max_leaf_size = std::max<uint32_t>(s_.max_leaf_size, 1u);
  }

  BuildTree run() {
    BuildTree tree;
    std::vector<Ref> refs;
    refs.reserve(boxes_.size());
    for (uint32_t i = 0; i < boxes_.size(); ++i) {
      if (aabb_valid(boxes_[i])) refs.push_back(Ref::make(boxes_[i], i));
    }
    if (refs.empty()) return tree;
    const uint32_t n = uint32_t(refs.size());
    const uint64_t budget = uint64_t(double(std::max(0.0f, s_.spatial_split_budget)) * double(n));
    const uint64_t capacity = 2 * (uint64_t(n) + budget);
    // The vertices of every referenced triangle (a valid box means valid
    // indices), next to each other for the spatial binning.
    tris_.resize(boxes_.size());
    tbb::parallel_for(size_t(0), refs.size(), [&](size_t i) {
      const uint32_t id = refs[i].id();
      const KTriangle& t = triangles_[id];
      const uint32_t v[3] = {t.v0, t.v1, t.v2};
      for (int j = 0; j < 3; ++j) {
        const Vec3 p = positions_[v[j]];
        float* out = tris_[id].v[j];
        out[0] = p.x, out[1] = p.y, out[2] = p.z, out[3] = 0.0f;
      }
    });
    nodes_.resize(capacity);
    // Splits never add more than the budget in all (each node passes on
    // what it did not use), so every leaf's references fit.
    leaf_store_.resize(n + budget);
    node_count_ = 1;
    Aabb root_box;
    for (const Ref& r : refs)
      root_box.grow(r.box());
    root_area_ = root_box.half_area();
    build(0, std::move(refs), root_box, budget, 1);
    nodes_.resize(node_count_.load());
    // Leaf order: depth-first, so every subtree's references are contiguous.
    tree.prims.reserve(leaf_count_.load());
    tree.ref_boxes.reserve(leaf_count_.load());
    assign_ranges(0, tree);
    tree.nodes = std::move(nodes_);
    tree.root = 0;
    tree.depth = max_depth_.load();
    return tree;
  }

 private:
  void triangle(uint32_t id, Vec3 out[3]) const {
    const Tri& t = tris_[id];
    for (int j = 0; j < 3; ++j)
      out[j] = {t.v[j][0], t.v[j][1], t.v[j][2]};
  }

  void assign_ranges(uint32_t node, BuildTree& tree) {
    BuildNode& n = nodes_[node];
    if (n.is_leaf()) {
      // make_leaf left the leaf's place in leaf_store_ in first / count.
      const uint32_t from = n.first, count = n.count;
      n.first = uint32_t(tree.prims.size());
      for (uint32_t i = from; i < from + count; ++i) {
        tree.prims.push_back(leaf_store_[i].id());
        tree.ref_boxes.push_back(leaf_store_[i].box());
      }
    } else {
      n.first = uint32_t(tree.prims.size());
      assign_ranges(n.child[0], tree);
      assign_ranges(n.child[1], tree);
    }
    n.count = uint32_t(tree.prims.size()) - n.first;
  }

  void make_leaf(uint32_t node, std::vector<Ref>&& refs, const Aabb& box, uint32_t depth) {
    const uint32_t at = leaf_count_.fetch_add(uint32_t(refs.size()));
    std::copy(refs.begin(), refs.end(), leaf_store_.begin() + at);
    BuildNode& n = nodes_[node];
    n.box = box;
    n.first = at;
    n.count = uint32_t(refs.size());
    std::vector<Ref>().swap(refs);
    uint32_t seen = max_depth_.load(std::memory_order_relaxed);
    while (depth > seen && !max_depth_.compare_exchange_weak(seen, depth)) {
    }
  }

  struct Box4 {
    F4 lo = kEmptyLo, hi = kEmptyHi;
  };

  ObjectSplit find_object_split(const std::vector<Ref>& refs, double parent) const {
    ObjectSplit best;
    const F4 half = simd::set1(0.5f);
    Box4 c4;
    chunked(
        refs.size(), c4, [](Box4& b) { b = Box4{}; },
        [&](Box4& b, size_t lo, size_t hi) {
          for (size_t i = lo; i < hi; ++i) {
            const F4 c = (refs[i].vlo() + refs[i].vhi()) * half;
            b.lo = simd::min(b.lo, c);
            b.hi = simd::max(b.hi, c);
          }
        },
        [](Box4& into, const Box4& o) {
          into.lo = simd::min(into.lo, o.lo);
          into.hi = simd::max(into.hi, o.hi);
        });
    const Aabb cbox = to_aabb(c4.lo, c4.hi);
    best.cbox = cbox;
    const uint32_t k =
        std::min<uint32_t>(kObjectBins, std::max<uint32_t>(4u, uint32_t(refs.size())));
    bool active[3];
    float origin[3], scale[3];
    for (int a = 0; a < 3; ++a) {
      origin[a] = lo_of(cbox, a);
      const float ext = hi_of(cbox, a) - origin[a];
      scale[a] = ext > 0.0f ? float(k) / ext : 0.0f;
      active[a] = ext > 0.0f && scale[a] < kFloatMax;
      if (!active[a]) scale[a] = 0.0f;
    }
    if (!active[0] && !active[1] && !active[2]) return best;
    const F4 origin4 = simd::set(origin[0], origin[1], origin[2], 0.0f);
    const F4 scale4 = simd::set(scale[0], scale[1], scale[2], 0.0f);
    BinSet bins;
    chunked(
        refs.size(), bins, [&](BinSet& b) { b.reset(k, active); },
        [&](BinSet& b, size_t lo, size_t hi) {
          for (size_t i = lo; i < hi; ++i) {
            const F4 rlo = refs[i].vlo(), rhi = refs[i].vhi();
            alignas(16) int32_t bi[4];
            simd::to_int(((rlo + rhi) * half - origin4) * scale4, bi);
            for (int a = 0; a < 3; ++a) {
              if (!active[a]) continue;
              const uint32_t j = clamp_bin(bi[a], k);
              b.lo[a][j] = simd::min(b.lo[a][j], rlo);
              b.hi[a][j] = simd::max(b.hi[a][j], rhi);
              ++b.count[a][j];
            }
          }
        },
        [&](BinSet& into, const BinSet& o) { into.merge(o, k, active); });
    F4 left_lo = kEmptyLo, left_hi = kEmptyHi, right_lo = kEmptyLo, right_hi = kEmptyHi;
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      sweep(bins.lo[a], bins.hi[a], bins.count[a], bins.count[a], k, parent,
            [&](uint32_t i, double cost, F4 ll, F4 lh, F4 rl, F4 rh) {
              if (best.axis < 0 || cost < best.cost) {
                best.axis = a;
                best.bin = i;
                best.cost = cost;
                left_lo = ll, left_hi = lh, right_lo = rl, right_hi = rh;
              }
            });
    }
    if (best.axis >= 0) {
      best.left = to_aabb(left_lo, left_hi);
      best.right = to_aabb(right_lo, right_hi);
    }
    return best;
  }

  // Evaluates every plane between bins; f(i, cost, left box, right box) for
  // the split into bins [0, i] and (i, k), boxes as (lo, hi) vectors. The
  // areas are Aabb::half_area's: the same products in the same order, and
  // 0 for an empty box.
  template <class F>
  void sweep(const F4* lo, const F4* hi, const uint32_t* left_count, const uint32_t* right_count,
             uint32_t k, double parent, F f) const {
    constexpr uint32_t kMax = kSpatialBins > kObjectBins ? kSpatialBins : kObjectBins;
    const auto area = [](F4 l, F4 h) { return simd::le3(l, h) ? simd::half_area(l, h) : 0.0f; };
    F4 right_lo[kMax], right_hi[kMax];
    float right_area[kMax];
    uint32_t rcnt[kMax];
    F4 acc_lo = kEmptyLo, acc_hi = kEmptyHi;
    uint32_t c = 0;
    for (uint32_t i = k; i-- > 1;) {
      acc_lo = simd::min(acc_lo, lo[i]);
      acc_hi = simd::max(acc_hi, hi[i]);
      c += right_count[i];
      right_lo[i] = acc_lo;
      right_hi[i] = acc_hi;
      right_area[i] = area(acc_lo, acc_hi);
      rcnt[i] = c;
    }
    F4 left_lo = kEmptyLo, left_hi = kEmptyHi;
    uint32_t lc = 0;
    const double ct = s_.traversal_cost, ci = s_.intersection_cost;
    for (uint32_t i = 0; i + 1 < k; ++i) {
      left_lo = simd::min(left_lo, lo[i]);
      left_hi = simd::max(left_hi, hi[i]);
      lc += left_count[i];
      if (lc == 0 || rcnt[i + 1] == 0) continue;
      const double cost = ct * parent + ci * (double(area(left_lo, left_hi)) * lc +
                                              double(right_area[i + 1]) * rcnt[i + 1]);
      f(i, cost, left_lo, left_hi, right_lo[i + 1], right_hi[i + 1]);
    }
  }

  SpatialSplit find_spatial_split(const std::vector<Ref>& refs, const Aabb& box,
                                  double object_cost) const {
    SpatialSplit best;
    const uint32_t k = kSpatialBins;
    SpatialAxes ax;
    for (int a = 0; a < 3; ++a) {
      const float lo = lo_of(box, a), ext = hi_of(box, a) - lo;
      if (!(ext > 0.0f)) continue;
      const float scale = float(k) / ext;
      if (!(scale < kFloatMax)) continue;
      ax.active[a] = true;
      ax.lo[a] = lo;
      ax.scale[a] = scale;
      const float mag = std::max(std::fabs(lo), std::fabs(hi_of(box, a)));
      ax.narrow[a] = ext >= 1e-3f * mag;
      float* planes = ax.planes[a];
      for (uint32_t i = 0; i <= k; ++i)
        planes[i] = lo + ext * (float(i) / float(k));
      std::fill(planes + k, planes + kPadded, hi_of(box, a));
    }
    if (!ax.active[0] && !ax.active[1] && !ax.active[2]) return best;
    ax.origin = simd::set(ax.lo[0], ax.lo[1], ax.lo[2], 0.0f);
    ax.scale4 = simd::set(ax.scale[0], ax.scale[1], ax.scale[2], 0.0f);
    // First the counts and the references within one bin: that sweep is a
    // lower bound of the axis's costs (the straddlers' pieces can only grow
    // the boxes, and the areas and costs are monotonic in them). An axis
    // whose bound is not below the object split's cost, or the best of the
    // axes before it (ties go to the first axis), cannot give the split
    // that build() takes; only the others clip their straddlers.
    const double parent = box.half_area();
    SpatialBins bins;
    chunked(
        refs.size(), bins, [&](SpatialBins& b) { b.reset(ax.active); },
        [&](SpatialBins& b, size_t lo, size_t hi) {
          for (size_t i = lo; i < hi; ++i) {
            const Ref& r = refs[i];
            alignas(16) int32_t bl[4], bh[4];
            simd::to_int((r.vlo() - ax.origin) * ax.scale4, bl);
            simd::to_int((r.vhi() - ax.origin) * ax.scale4, bh);
            for (int a = 0; a < 3; ++a) {
              if (!ax.active[a]) continue;
              const uint32_t b0 = clamp_bin(bl[a], k), b1 = clamp_bin(bh[a], k);
              ++b.enter[a][b0];
              ++b.leave[a][b1];
              if (b0 == b1) b.grow(a, b0, r);
            }
          }
        },
        [&](SpatialBins& into, const SpatialBins& o) { into.merge(o, ax.active); });
    const auto axis_sweep = [&](int a, auto f) {
      F4 lo[kSpatialBins], hi[kSpatialBins];
      bins.boxes(a, lo, hi);
      sweep(lo, hi, bins.enter[a], bins.leave[a], k, parent,
            [&](uint32_t i, double cost, F4, F4, F4, F4) { f(i, cost); });
    };
    for (int a = 0; a < 3; ++a) {
      if (!ax.active[a]) continue;
      double bound = std::numeric_limits<double>::infinity();
      axis_sweep(a, [&](uint32_t, double cost) { bound = std::min(bound, cost); });
      if (bound >= object_cost || (best.axis >= 0 && bound >= best.cost)) continue;
      const bool only[3] = {a == 0, a == 1, a == 2};
      SpatialBins pieces;
      chunked(
          refs.size(), pieces, [&](SpatialBins& b) { b.reset(only); },
          [&](SpatialBins& b, size_t lo, size_t hi) {
            const float o = ax.lo[a], sc = ax.scale[a];
            for (size_t i = lo; i < hi; ++i) {
              const Ref& r = refs[i];
              // The triangles of a node's references lie all over the
              // vertex array: fetch a few references ahead.
              if (i + kPrefetch < hi) {
                const char* ahead = reinterpret_cast<const char*>(&tris_[refs[i + kPrefetch].id()]);
                __builtin_prefetch(ahead);
                __builtin_prefetch(ahead + sizeof(Tri) - 1);
              }
              // As the first pass: same arithmetic, one lane.
              const uint32_t b0 = bin_of(r.lo[a], o, sc, k);
              const uint32_t b1 = bin_of(r.hi[a], o, sc, k);
              if (b0 == b1) continue;
              const Tri& t = tris_[r.id()];
              bin_straddler(t, r, a, ax, b0, b1, b);
            }
          },
          [&](SpatialBins& into, const SpatialBins& o) { into.merge(o, only); });
      // The pieces' counts are zero: merging adds only their boxes.
      bins.merge(pieces, only);
      axis_sweep(a, [&](uint32_t i, double cost) {
        if (best.axis < 0 || cost < best.cost) {
          best.axis = a;
          best.plane = ax.planes[a][i + 1];
          best.cost = cost;
        }
      });
    }
    return best;
  }

  // Splits refs at the plane, clipping straddling references or, where the
  // SAH says so, leaving them whole on one side. Returns false when a side
  // would be empty or the duplicates would exceed `budget`.
  bool spatial_partition(std::vector<Ref>& refs, const SpatialSplit& sp, uint64_t budget,
                         std::vector<Ref>& left, std::vector<Ref>& right, Aabb& lbox,
                         Aabb& rbox) const {
    const int a = sp.axis;
    const float plane = sp.plane;
    lbox = Aabb{};
    rbox = Aabb{};
    std::vector<uint32_t> straddle;
    for (uint32_t i = 0; i < refs.size(); ++i) {
      const Ref& r = refs[i];
      if (r.hi[a] <= plane) {
        left.push_back(r);
        lbox.grow(r.box());
      } else if (r.lo[a] >= plane) {
        right.push_back(r);
        rbox.grow(r.box());
      } else {
        straddle.push_back(i);
      }
    }
    // Far more straddlers than the budget: reference unsplitting cannot
    // bring that down enough.
    if (straddle.size() > 4 * budget) return false;
    uint64_t nl = left.size() + straddle.size(), nr = right.size() + straddle.size();
    for (uint32_t i : straddle) {
      const Ref& r = refs[i];
      const Aabb rb = r.box();
      Vec3 t[3];
      triangle(r.id(), t);
      const Aabb lc = clip_triangle(t, rb, a, -std::numeric_limits<float>::infinity(), plane);
      const Aabb rc = clip_triangle(t, rb, a, plane, std::numeric_limits<float>::infinity());
      if (lc.empty()) {
        right.push_back(r);
        rbox.grow(rb);
        --nl;
        continue;
      }
      if (rc.empty()) {
        left.push_back(r);
        lbox.grow(rb);
        --nr;
        continue;
      }
      // Reference unsplitting (Stich et al., section 4.3).
      Aabb l_split = lbox, r_split = rbox, l_whole = lbox, r_whole = rbox;
      l_split.grow(lc);
      r_split.grow(rc);
      l_whole.grow(rb);
      r_whole.grow(rb);
      const double c_split = double(l_split.half_area()) * nl + double(r_split.half_area()) * nr;
      const double c_left = double(l_whole.half_area()) * nl + double(rbox.half_area()) * (nr - 1);
      const double c_right = double(lbox.half_area()) * (nl - 1) + double(r_whole.half_area()) * nr;
      if (c_left < c_split && c_left <= c_right) {
        left.push_back(r);
        lbox = l_whole;
        --nr;
      } else if (c_right < c_split) {
        right.push_back(r);
        rbox = r_whole;
        --nl;
      } else {
        left.push_back(Ref::make(lc, r.id()));
        right.push_back(Ref::make(rc, r.id()));
        lbox = l_split;
        rbox = r_split;
      }
    }
    return !left.empty() && !right.empty() && left.size() + right.size() - refs.size() <= budget;
  }

  void build(uint32_t node, std::vector<Ref> refs, const Aabb& box, uint64_t budget,
             uint32_t depth) {
    const uint32_t n = uint32_t(refs.size());
    if (n == 1) return make_leaf(node, std::move(refs), box, depth);
    std::vector<Ref> left, right;
    Aabb lbox, rbox;
    bool split = false;
    const double leaf_cost = double(s_.intersection_cost) * n * box.half_area();
    if (depth < kSahMaxDepth) {
      const ObjectSplit os = find_object_split(refs, box.half_area());
      double best_cost = os.axis >= 0 ? os.cost : std::numeric_limits<double>::infinity();
      SpatialSplit sp;
      if (budget > 0 && os.axis >= 0) {
        const Aabb overlap = intersect(os.left, os.right);
        if (!overlap.empty() && overlap.half_area() > s_.spatial_split_alpha * root_area_) {
          sp = find_spatial_split(refs, box, best_cost);
        }
      } else if (budget > 0 && os.axis < 0 && n > s_.max_leaf_size) {
        sp = find_spatial_split(refs, box, best_cost);
      }
      if (n <= s_.max_leaf_size &&
          leaf_cost <= std::min(best_cost, sp.axis >= 0 ? sp.cost : best_cost)) {
        return make_leaf(node, std::move(refs), box, depth);
      }
      // Either partition fills at most n references per side.
      left.reserve(n);
      right.reserve(n);
      if (sp.axis >= 0 && sp.cost < best_cost) {
        split = spatial_partition(refs, sp, budget, left, right, lbox, rbox);
        if (!split) {
          left.clear();
          right.clear();
        }
      }
      if (!split && os.axis >= 0) {
        const float lo = lo_of(os.cbox, os.axis);
        const float scale = float(std::min<uint32_t>(kObjectBins, std::max<uint32_t>(4u, n))) /
                            (hi_of(os.cbox, os.axis) - lo);
        const uint32_t k = std::min<uint32_t>(kObjectBins, std::max<uint32_t>(4u, n));
        lbox = rbox = Aabb{};
        for (const Ref& r : refs) {
          if (bin_of(r.center(os.axis), lo, scale, k) <= os.bin) {
            left.push_back(r);
            lbox.grow(r.box());
          } else {
            right.push_back(r);
            rbox.grow(r.box());
          }
        }
        split = !left.empty() && !right.empty();
        if (!split) {
          left.clear();
          right.clear();
        }
      }
    } else if (n <= s_.max_leaf_size) {
      return make_leaf(node, std::move(refs), box, depth);
    }
    if (!split) {
      // Median of the widest centroid axis (or halves of coincident ones).
      Aabb cbox;
      for (const Ref& r : refs)
        cbox.grow(r.box().center());
      const Vec3 e = cbox.extent();
      const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
      const uint32_t mid = n / 2;
      std::nth_element(refs.begin(), refs.begin() + mid, refs.end(),
                       [&](const Ref& x, const Ref& y) {
                         const float cx = x.center(axis), cy = y.center(axis);
                         return cx < cy || (cx == cy && x.id() < y.id());
                       });
      left.assign(refs.begin(), refs.begin() + mid);
      right.assign(refs.begin() + mid, refs.end());
      lbox = rbox = Aabb{};
      for (const Ref& r : left)
        lbox.grow(r.box());
      for (const Ref& r : right)
        rbox.grow(r.box());
    }
    std::vector<Ref>().swap(refs);
    const uint64_t used = left.size() + right.size() - n;
    const uint64_t rest = budget - std::min(budget, used);
    const uint64_t lbudget = rest * left.size() / (left.size() + right.size());
    const uint64_t rbudget = rest - lbudget;
    const uint32_t children = node_count_.fetch_add(2);
    BuildNode& nd = nodes_[node];
    nd.box = box;
    nd.child[0] = children;
    nd.child[1] = children + 1;
    const size_t total = left.size() + right.size();
    if (total >= kParallelRefs) {
      tbb::parallel_invoke(
          [&] { build(children, std::move(left), lbox, lbudget, depth + 1); },
          [&] { build(children + 1, std::move(right), rbox, rbudget, depth + 1); });
    } else {
      build(children, std::move(left), lbox, lbudget, depth + 1);
      build(children + 1, std::move(right), rbox, rbudget, depth + 1);
    }
  }

  std::span<const Aabb> boxes_;
  std::span<const Vec3> positions_;
  std::span<const KTriangle> triangles_;
  BuildSettings s_;
  std::vector<Tri> tris_;
  std::vector<BuildNode> nodes_;
  std::vector<Ref> leaf_store_;  // leaves' references, in the order the leaves were made
  std::atomic<uint32_t> node_count_{0}, leaf_count_{0};
  std::atomic<uint32_t> max_depth_{0};
  double root_area_ = 0.0;
};

}  // namespace

BuildTree build_bvh_spatial(std::span<const Aabb> boxes, std::span<const Vec3> positions,
                            std::span<const KTriangle> triangles, const BuildSettings& settings) {
  // Small meshes stay in the caches whatever their tree, and there the
  // binned builder's exact sweep of small nodes makes the better one.
  if (boxes.size() < kMinSpatialTriangles || !(settings.spatial_split_budget > 0.0f)) {
    return build_bvh(boxes, settings);
  }
  return SpatialBuilder(boxes, positions, triangles, settings).run();
}

}  // namespace tandem
