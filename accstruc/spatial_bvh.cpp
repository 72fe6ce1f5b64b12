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
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "accstruc/bvh_builder.h"

namespace tandem {

namespace {

struct Ref {
  Aabb box;
  uint32_t id;
};

constexpr uint32_t kObjectBins = 16;
constexpr uint32_t kSpatialBins = 16;
constexpr uint32_t kParallelRefs = 4096;
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
      if (aabb_valid(boxes_[i])) refs.push_back({boxes_[i], i});
    }
    if (refs.empty()) return tree;
    const uint32_t n = uint32_t(refs.size());
    const uint64_t budget = uint64_t(double(std::max(0.0f, s_.spatial_split_budget)) * double(n));
    const uint64_t capacity = 2 * (uint64_t(n) + budget);
    nodes_.resize(capacity);
    leaf_refs_.resize(capacity);
    node_count_ = 1;
    Aabb root_box;
    for (const Ref& r : refs)
      root_box.grow(r.box);
    root_area_ = root_box.half_area();
    build(0, std::move(refs), root_box, budget, 1);
    nodes_.resize(node_count_.load());
    // Leaf order: depth-first, so every subtree's references are contiguous.
    tree.prims.reserve(n + budget);
    tree.ref_boxes.reserve(n + budget);
    assign_ranges(0, tree);
    tree.nodes = std::move(nodes_);
    tree.root = 0;
    tree.depth = max_depth_.load();
    return tree;
  }

 private:
  void triangle(uint32_t id, Vec3 out[3]) const {
    const KTriangle& t = triangles_[id];
    out[0] = positions_[t.v0];
    out[1] = positions_[t.v1];
    out[2] = positions_[t.v2];
  }

  void assign_ranges(uint32_t node, BuildTree& tree) {
    BuildNode& n = nodes_[node];
    n.first = uint32_t(tree.prims.size());
    if (n.is_leaf()) {
      for (const Ref& r : leaf_refs_[node]) {
        tree.prims.push_back(r.id);
        tree.ref_boxes.push_back(r.box);
      }
      std::vector<Ref>().swap(leaf_refs_[node]);
    } else {
      assign_ranges(n.child[0], tree);
      assign_ranges(n.child[1], tree);
    }
    n.count = uint32_t(tree.prims.size()) - n.first;
  }

  void make_leaf(uint32_t node, std::vector<Ref>&& refs, const Aabb& box, uint32_t depth) {
    nodes_[node].box = box;
    leaf_refs_[node] = std::move(refs);
    uint32_t seen = max_depth_.load(std::memory_order_relaxed);
    while (depth > seen && !max_depth_.compare_exchange_weak(seen, depth)) {
    }
  }

  ObjectSplit find_object_split(const std::vector<Ref>& refs, double parent) const {
    ObjectSplit best;
    Aabb cbox;
    for (const Ref& r : refs)
      cbox.grow(r.box.center());
    best.cbox = cbox;
    const uint32_t k =
        std::min<uint32_t>(kObjectBins, std::max<uint32_t>(4u, uint32_t(refs.size())));
    for (int a = 0; a < 3; ++a) {
      const float lo = lo_of(cbox, a), ext = hi_of(cbox, a) - lo;
      if (!(ext > 0.0f)) continue;
      const float scale = float(k) / ext;
      if (!(scale < kFloatMax)) continue;
      Aabb bin_box[kObjectBins];
      uint32_t bin_count[kObjectBins] = {};
      for (const Ref& r : refs) {
        const uint32_t b = bin_of(component(r.box.center(), a), lo, scale, k);
        bin_box[b].grow(r.box);
        ++bin_count[b];
      }
      sweep(bin_box, bin_count, k, parent,
            [&](uint32_t i, double cost, const Aabb& l, const Aabb& r) {
              if (best.axis < 0 || cost < best.cost) {
                best.axis = a;
                best.bin = i;
                best.cost = cost;
                best.left = l;
                best.right = r;
              }
            });
    }
    return best;
  }

  static uint32_t bin_of(float x, float lo, float scale, uint32_t k) {
    const int32_t b = int32_t((x - lo) * scale);
    return b <= 0 ? 0u : (uint32_t(b) < k ? uint32_t(b) : k - 1);
  }

  // Evaluates every plane between bins; f(i, cost, left box, right box) for
  // the split into bins [0, i] and (i, k).
  template <class F>
  void sweep(const Aabb* bin_box, const uint32_t* left_count, const uint32_t* right_count,
             uint32_t k, double parent, F f) const {
    Aabb right_box[kSpatialBins > kObjectBins ? kSpatialBins : kObjectBins];
    uint32_t rcnt[kSpatialBins > kObjectBins ? kSpatialBins : kObjectBins];
    Aabb acc;
    uint32_t c = 0;
    for (uint32_t i = k; i-- > 1;) {
      acc.grow(bin_box[i]);
      c += right_count[i];
      right_box[i] = acc;
      rcnt[i] = c;
    }
    Aabb left;
    uint32_t lc = 0;
    const double ct = s_.traversal_cost, ci = s_.intersection_cost;
    for (uint32_t i = 0; i + 1 < k; ++i) {
      left.grow(bin_box[i]);
      lc += left_count[i];
      if (lc == 0 || rcnt[i + 1] == 0) continue;
      const double cost = ct * parent + ci * (double(left.half_area()) * lc +
                                              double(right_box[i + 1].half_area()) * rcnt[i + 1]);
      f(i, cost, left, right_box[i + 1]);
    }
  }
  template <class F>
  void sweep(const Aabb* bin_box, const uint32_t* count, uint32_t k, double parent, F f) const {
    sweep(bin_box, count, count, k, parent, f);
  }

  // The boxes of the triangle's pieces in bins b0..b1 (within ref), grown
  // into bin_box: every vertex goes to its bin, every crossing of an edge
  // with an inner plane to the bins on both sides. For the cost estimate
  // only (no padding; the split itself clips with clip_triangle).
  static void bin_pieces(const Vec3 t[3], const Aabb& ref, int a, const float* planes, float lo,
                         float scale, uint32_t b0, uint32_t b1, Aabb* bin_box) {
    Aabb piece[kSpatialBins];
    for (int i = 0; i < 3; ++i) {
      const uint32_t b = std::clamp(bin_of(component(t[i], a), lo, scale, kSpatialBins), b0, b1);
      piece[b].grow(t[i]);
      Vec3 p = t[i], q = t[(i + 1) % 3];
      float pa = component(p, a), qa = component(q, a);
      if (pa > qa) {
        std::swap(p, q);
        std::swap(pa, qa);
      }
      for (uint32_t j = b0 + 1; j <= b1; ++j) {
        const float plane = planes[j];
        if (!(pa < plane && plane < qa)) continue;
        const Vec3 x = p + (q - p) * ((plane - pa) / (qa - pa));
        piece[j - 1].grow(x);
        piece[j].grow(x);
      }
    }
    for (uint32_t b = b0; b <= b1; ++b) {
      Aabb c = intersect(piece[b], ref);
      set_lo(c, a, std::max(lo_of(c, a), planes[b]));
      set_hi(c, a, std::min(hi_of(c, a), planes[b + 1]));
      if (!c.empty()) bin_box[b].grow(c);
    }
  }

  SpatialSplit find_spatial_split(const std::vector<Ref>& refs, const Aabb& box) const {
    SpatialSplit best;
    const uint32_t k = kSpatialBins;
    for (int a = 0; a < 3; ++a) {
      const float lo = lo_of(box, a), ext = hi_of(box, a) - lo;
      if (!(ext > 0.0f)) continue;
      const float scale = float(k) / ext;
      if (!(scale < kFloatMax)) continue;
      float planes[kSpatialBins + 1];
      for (uint32_t i = 0; i <= k; ++i)
        planes[i] = lo + ext * (float(i) / float(k));
      planes[k] = hi_of(box, a);
      Aabb bin_box[kSpatialBins];
      uint32_t enter[kSpatialBins] = {}, leave[kSpatialBins] = {};
      for (const Ref& r : refs) {
        const uint32_t b0 = bin_of(lo_of(r.box, a), lo, scale, k);
        const uint32_t b1 = bin_of(hi_of(r.box, a), lo, scale, k);
        ++enter[b0];
        ++leave[b1];
        if (b0 == b1) {
          bin_box[b0].grow(r.box);
          continue;
        }
        Vec3 t[3];
        triangle(r.id, t);
        bin_pieces(t, r.box, a, planes, lo, scale, b0, b1, bin_box);
      }
      sweep(bin_box, enter, leave, k, box.half_area(),
            [&](uint32_t i, double cost, const Aabb&, const Aabb&) {
              if (best.axis < 0 || cost < best.cost) {
                best.axis = a;
                best.plane = planes[i + 1];
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
      if (hi_of(r.box, a) <= plane) {
        left.push_back(r);
        lbox.grow(r.box);
      } else if (lo_of(r.box, a) >= plane) {
        right.push_back(r);
        rbox.grow(r.box);
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
      Vec3 t[3];
      triangle(r.id, t);
      const Aabb lc = clip_triangle(t, r.box, a, -std::numeric_limits<float>::infinity(), plane);
      const Aabb rc = clip_triangle(t, r.box, a, plane, std::numeric_limits<float>::infinity());
      if (lc.empty()) {
        right.push_back(r);
        rbox.grow(r.box);
        --nl;
        continue;
      }
      if (rc.empty()) {
        left.push_back(r);
        lbox.grow(r.box);
        --nr;
        continue;
      }
      // Reference unsplitting (Stich et al., section 4.3).
      Aabb l_split = lbox, r_split = rbox, l_whole = lbox, r_whole = rbox;
      l_split.grow(lc);
      r_split.grow(rc);
      l_whole.grow(r.box);
      r_whole.grow(r.box);
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
        left.push_back({lc, r.id});
        right.push_back({rc, r.id});
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
          sp = find_spatial_split(refs, box);
        }
      } else if (budget > 0 && os.axis < 0 && n > s_.max_leaf_size) {
        sp = find_spatial_split(refs, box);
      }
      if (n <= s_.max_leaf_size &&
          leaf_cost <= std::min(best_cost, sp.axis >= 0 ? sp.cost : best_cost)) {
        return make_leaf(node, std::move(refs), box, depth);
      }
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
          if (bin_of(component(r.box.center(), os.axis), lo, scale, k) <= os.bin) {
            left.push_back(r);
            lbox.grow(r.box);
          } else {
            right.push_back(r);
            rbox.grow(r.box);
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
        cbox.grow(r.box.center());
      const Vec3 e = cbox.extent();
      const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
      const uint32_t mid = n / 2;
      std::nth_element(
          refs.begin(), refs.begin() + mid, refs.end(), [&](const Ref& x, const Ref& y) {
            const float cx = component(x.box.center(), axis), cy = component(y.box.center(), axis);
            return cx < cy || (cx == cy && x.id < y.id);
          });
      left.assign(refs.begin(), refs.begin() + mid);
      right.assign(refs.begin() + mid, refs.end());
      lbox = rbox = Aabb{};
      for (const Ref& r : left)
        lbox.grow(r.box);
      for (const Ref& r : right)
        rbox.grow(r.box);
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
  std::vector<BuildNode> nodes_;
  std::vector<std::vector<Ref>> leaf_refs_;
  std::atomic<uint32_t> node_count_{0};
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
