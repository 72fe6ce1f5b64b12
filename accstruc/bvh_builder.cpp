#include "accstruc/bvh_builder.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cstring>

#include "accstruc/simd4.h"

namespace tandem {

namespace {

using simd::F4;

constexpr uint32_t kMaxBins = 64;
// Nodes with at least this many primitives bin, partition and compute bounds
// in parallel; below it one task does the whole node (TBB overhead would win).
constexpr uint32_t kParallelNodeThreshold = 1u << 15;
constexpr uint32_t kParallelGrain = 1u << 13;
// Subtrees with at least this many primitives are built as separate tasks.
constexpr uint32_t kTaskThreshold = 512;
// Nodes with at most this many primitives are split by an exact sweep
// instead of bins (see small_split).
constexpr uint32_t kSmallNode = 16;

// A primitive as the builder moves it around: its box with the primitive id
// in the fourth lane of lo. Partitioning moves these 32-byte records, not
// indices, so every pass over a node streams through contiguous memory.
struct alignas(16) PrimRef {
  float lo[4];
  float hi[4];
  uint32_t id() const {
    uint32_t v;
    std::memcpy(&v, &lo[3], 4);
    return v;
  }
  F4 vlo() const { return simd::load(lo); }
  F4 vhi() const { return simd::load(hi); }
  // Twice the centroid: binning only needs it up to a constant factor.
  F4 centroid2() const { return vlo() + vhi(); }
  float centroid2(int axis) const { return lo[axis] + hi[axis]; }
};

// Box and doubled-centroid box as vectors (w lanes unused).
struct Bounds {
  F4 lo = simd::set1(kFloatMax), hi = simd::set1(-kFloatMax);
  F4 clo = simd::set1(kFloatMax), chi = simd::set1(-kFloatMax);
  void add(const PrimRef& p) {
    const F4 l = p.vlo(), h = p.vhi(), c = l + h;
    lo = simd::min(lo, l);
    hi = simd::max(hi, h);
    clo = simd::min(clo, c);
    chi = simd::max(chi, c);
  }
  void merge(const Bounds& o) {
    lo = simd::min(lo, o.lo);
    hi = simd::max(hi, o.hi);
    clo = simd::min(clo, o.clo);
    chi = simd::max(chi, o.chi);
  }
};

using simd::half_area;

Aabb to_aabb(F4 lo, F4 hi) {
  alignas(16) float l[4], h[4];
  simd::store(l, lo);
  simd::store(h, hi);
  return {{l[0], l[1], l[2]}, {h[0], h[1], h[2]}};
}

// A node's primitive range with its bounds and doubled-centroid bounds.
struct Range {
  uint32_t begin, end;
  Bounds b;
  uint32_t size() const { return end - begin; }
  Aabb box() const { return to_aabb(b.lo, b.hi); }
  Aabb cbox2() const { return to_aabb(b.clo, b.chi); }
};

// A bin holds only the primitives' box and count: the children's centroid
// bounds are gathered by the partition pass instead, which halves the work
// per binned primitive.
struct Bin {
  F4 lo, hi;
  uint32_t count;
};

// Bins of all three axes; only the k in use are reset, so the per-node cost
// does not depend on kMaxBins.
struct BinSet {
  Bin bins[3][kMaxBins];
  void reset(uint32_t k, const bool active[3]) {
    const F4 lo = simd::set1(kFloatMax), hi = simd::set1(-kFloatMax);
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (uint32_t i = 0; i < k; ++i)
        bins[a][i] = Bin{lo, hi, 0};
    }
  }
  void merge(const BinSet& o, uint32_t k, const bool active[3]) {
    for (int a = 0; a < 3; ++a) {
      if (!active[a]) continue;
      for (uint32_t i = 0; i < k; ++i) {
        Bin& b = bins[a][i];
        b.lo = simd::min(b.lo, o.bins[a][i].lo);
        b.hi = simd::max(b.hi, o.bins[a][i].hi);
        b.count += o.bins[a][i].count;
      }
    }
  }
};

// Maps (doubled) centroids to bins along each axis. Axes whose centroid
// extent is zero (flat or coincident geometry) or too small to divide are
// inactive.
struct BinMapping {
  F4 origin, scale;
  float origin_s[3], scale_s[3];
  bool active[3];
  uint32_t k;

  BinMapping(const Aabb& cbox2, uint32_t bins, bool all_axes) : k(bins) {
    const Vec3 e = cbox2.extent();
    int widest = 0;
    for (int a = 1; a < 3; ++a) {
      if (component(e, a) > component(e, widest)) widest = a;
    }
    for (int a = 0; a < 3; ++a) {
      origin_s[a] = component(cbox2.lo, a);
      const float ext = component(e, a);
      scale_s[a] = ext > 0.0f ? float(bins) / ext : 0.0f;
      active[a] = ext > 0.0f && scale_s[a] < kFloatMax && (all_axes || a == widest);
      if (!active[a]) scale_s[a] = 0.0f;
    }
    origin = simd::set(origin_s[0], origin_s[1], origin_s[2], 0.0f);
    scale = simd::set(scale_s[0], scale_s[1], scale_s[2], 0.0f);
  }
  uint32_t clamp(int32_t b) const { return b <= 0 ? 0u : (uint32_t(b) < k ? uint32_t(b) : k - 1); }
  void bins_of(const PrimRef& p, uint32_t out[3]) const {
    alignas(16) int32_t b[4];
    simd::to_int((p.centroid2() - origin) * scale, b);
    for (int a = 0; a < 3; ++a)
      out[a] = clamp(b[a]);
  }
  // Same arithmetic as bins_of (lane by lane, so bit-identical), one axis:
  // used by the partition.
  uint32_t bin(const PrimRef& p, int axis) const {
    return clamp(int32_t((p.centroid2(axis) - origin_s[axis]) * scale_s[axis]));
  }
};

struct Split {
  int axis = -1;
  uint32_t bin = 0;  // left side: bins [0, bin]
  uint32_t k = 0;    // bins used
  double cost = 0.0;
};

class Builder {
 public:
  Builder(std::span<const Aabb> boxes, const BuildSettings& s) : boxes_(boxes), s_(s) {
    s_.bins = std::clamp<uint32_t>(s_.bins, 2u, kMaxBins);
    s_.max_leaf_size = std::max<uint32_t>(s_.max_leaf_size, 1u);
  }

  BuildTree run() {
    BuildTree tree;
    const uint32_t n = uint32_t(boxes_.size());
    std::vector<uint8_t> valid(n);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, kParallelGrain), [&](auto r) {
      for (uint32_t i = r.begin(); i < r.end(); ++i)
        valid[i] = aabb_valid(boxes_[i]);
    });
    uint32_t count = 0;
    for (uint32_t i = 0; i < n; ++i)
      count += valid[i];
    if (count == 0) return tree;
    refs_.resize(count);
    uint32_t at = 0;
    for (uint32_t i = 0; i < n; ++i) {
      if (!valid[i]) continue;
      const Aabb& b = boxes_[i];
      PrimRef& r = refs_[at++];
      r.lo[0] = b.lo.x, r.lo[1] = b.lo.y, r.lo[2] = b.lo.z;
      std::memcpy(&r.lo[3], &i, 4);
      r.hi[0] = b.hi.x, r.hi[1] = b.hi.y, r.hi[2] = b.hi.z, r.hi[3] = 0.0f;
    }
    scratch_.resize(count);
    nodes_.resize(2 * size_t(count) - 1);
    node_count_ = 1;
    Range root{0, count, {}};
    compute_bounds(root);
    build(0, root, 1);
    nodes_.resize(node_count_.load());
    tree.nodes = std::move(nodes_);
    tree.root = 0;
    tree.prims.resize(count);
    for (uint32_t i = 0; i < count; ++i)
      tree.prims[i] = refs_[i].id();
    tree.depth = max_depth_.load();
    return tree;
  }

 private:
  void compute_bounds(Range& r) const {
    if (r.size() < kParallelNodeThreshold) {
      Bounds b;
      for (uint32_t i = r.begin; i < r.end; ++i)
        b.add(refs_[i]);
      r.b = b;
      return;
    }
    const uint32_t chunks = (r.size() + kParallelGrain - 1) / kParallelGrain;
    std::vector<Bounds> partial(chunks);
    tbb::parallel_for(0u, chunks, [&](uint32_t c) {
      const uint32_t lo = r.begin + c * kParallelGrain, hi = std::min(r.end, lo + kParallelGrain);
      for (uint32_t i = lo; i < hi; ++i)
        partial[c].add(refs_[i]);
    });
    r.b = Bounds{};
    for (const Bounds& b : partial)
      r.b.merge(b);
  }

  void make_leaf(uint32_t node, const Range& r, uint32_t depth) {
    BuildNode& n = nodes_[node];
    n.box = r.box();
    n.first = r.begin;
    n.count = r.size();
    uint32_t seen = max_depth_.load(std::memory_order_relaxed);
    while (depth > seen && !max_depth_.compare_exchange_weak(seen, depth)) {
    }
  }

  static void bin_prim(const PrimRef& p, const BinMapping& map, BinSet& out) {
    uint32_t b[3];
    map.bins_of(p, b);
    const F4 lo = p.vlo(), hi = p.vhi();
    for (int a = 0; a < 3; ++a) {
      if (!map.active[a]) continue;
      Bin& bin = out.bins[a][b[a]];
      bin.lo = simd::min(bin.lo, lo);
      bin.hi = simd::max(bin.hi, hi);
      ++bin.count;
    }
  }

  // Neighbouring primitives of a node tend to fall into the same bins, and
  // updating one bin twice in a row makes each update wait for the last:
  // alternate between two bin sets to halve those dependency chains.
  void bin_range(uint32_t begin, uint32_t end, const BinMapping& map, BinSet& out) const {
    if (end - begin < 256) {
      for (uint32_t i = begin; i < end; ++i)
        bin_prim(refs_[i], map, out);
      return;
    }
    BinSet odd;
    odd.reset(map.k, map.active);
    uint32_t i = begin;
    for (; i + 1 < end; i += 2) {
      bin_prim(refs_[i], map, out);
      bin_prim(refs_[i + 1], map, odd);
    }
    if (i < end) bin_prim(refs_[i], map, out);
    out.merge(odd, map.k, map.active);
  }

  // Best SAH split of r over the bins, or axis -1 when no axis can be split.
  // Not inlined: its bins are large and must not sit in every recursive
  // frame of build().
  [[gnu::noinline]] Split find_sah_split(const Range& r) const {
    // Small nodes get fewer bins: the per-node cost of resetting and
    // sweeping bins would otherwise dominate the lower levels.
    const uint32_t k = std::min(s_.bins, std::max(4u, r.size()));
    const BinMapping map(r.cbox2(), k, s_.all_axes);
    Split best;
    if (!map.active[0] && !map.active[1] && !map.active[2]) return best;
    BinSet bins;
    bins.reset(k, map.active);
    if (r.size() >= kParallelNodeThreshold) {
      // Fixed chunks merged in order: the same bins whatever the scheduling.
      const uint32_t chunks = (r.size() + kParallelGrain - 1) / kParallelGrain;
      std::vector<BinSet> partial(chunks);
      tbb::parallel_for(0u, chunks, [&](uint32_t c) {
        partial[c].reset(k, map.active);
        const uint32_t lo = r.begin + c * kParallelGrain;
        bin_range(lo, std::min(r.end, lo + kParallelGrain), map, partial[c]);
      });
      for (const BinSet& p : partial)
        bins.merge(p, k, map.active);
    } else {
      bin_range(r.begin, r.end, map, bins);
    }
    // Sweep: right-side areas and counts from the top, then evaluate every
    // plane from the bottom. Costs are not divided by the parent's area so a
    // zero-area node (all primitives on a line) compares without NaNs.
    const double ct = s_.traversal_cost, ci = s_.intersection_cost;
    const double parent = r.box().half_area();
    for (int a = 0; a < 3; ++a) {
      if (!map.active[a]) continue;
      double right_area[kMaxBins];
      uint32_t right_count[kMaxBins];
      F4 acc_lo = simd::set1(kFloatMax), acc_hi = simd::set1(-kFloatMax);
      uint32_t cnt = 0;
      for (uint32_t i = k - 1; i > 0; --i) {
        const Bin& bin = bins.bins[a][i];
        if (bin.count) {
          acc_lo = simd::min(acc_lo, bin.lo);
          acc_hi = simd::max(acc_hi, bin.hi);
          cnt += bin.count;
        }
        right_area[i] = cnt ? half_area(acc_lo, acc_hi) : 0.0;
        right_count[i] = cnt;
      }
      F4 left_lo = simd::set1(kFloatMax), left_hi = simd::set1(-kFloatMax);
      uint32_t lcnt = 0;
      for (uint32_t i = 0; i + 1 < k; ++i) {
        const Bin& bin = bins.bins[a][i];
        if (bin.count == 0) continue;  // same planes as the previous bin
        left_lo = simd::min(left_lo, bin.lo);
        left_hi = simd::max(left_hi, bin.hi);
        lcnt += bin.count;
        const uint32_t rcnt = right_count[i + 1];
        if (rcnt == 0) continue;
        const double cost = ct * parent + ci * (double(half_area(left_lo, left_hi)) * lcnt +
                                                right_area[i + 1] * rcnt);
        if (best.axis < 0 || cost < best.cost) {
          best.axis = a;
          best.bin = i;
          best.cost = cost;
        }
      }
    }
    if (best.axis < 0) return best;
    best.k = k;
    return best;
  }

  // Partitions r so that primitives with pred(p) come first, gathering the
  // bounds of both sides on the way; returns the split point. Large ranges
  // use a blocked parallel (stable) partition.
  template <class Pred>
  uint32_t partition(const Range& r, Pred pred, Bounds* left, Bounds* right) {
    if (r.size() < kParallelNodeThreshold) {
      // Branch-free out-of-place partition: every primitive is written to
      // both ends of the scratch range and only the matching cursor moves,
      // so random left/right decisions cost no mispredictions. The right
      // side comes out reversed, which is as deterministic as any order.
      uint32_t l = r.begin, rr = r.end - 1;
      Bounds sides[2];
      for (uint32_t i = r.begin; i < r.end; ++i) {
        const PrimRef& p = refs_[i];
        const uint32_t go_left = pred(p) ? 1u : 0u;
        scratch_[l] = p;
        scratch_[rr] = p;
        l += go_left;
        rr -= 1u - go_left;
        sides[go_left].add(p);
      }
      std::copy(scratch_.begin() + r.begin, scratch_.begin() + r.end, refs_.begin() + r.begin);
      *left = sides[1];
      *right = sides[0];
      return l;
    }
    const uint32_t blocks = (r.size() + kParallelGrain - 1) / kParallelGrain;
    std::vector<uint32_t> left_before(blocks + 1, 0);
    std::vector<Bounds> lbs(blocks), rbs(blocks);
    tbb::parallel_for(0u, blocks, [&](uint32_t b) {
      const uint32_t lo = r.begin + b * kParallelGrain, hi = std::min(r.end, lo + kParallelGrain);
      uint32_t c = 0;
      for (uint32_t i = lo; i < hi; ++i) {
        if (pred(refs_[i])) {
          ++c;
          lbs[b].add(refs_[i]);
        } else {
          rbs[b].add(refs_[i]);
        }
      }
      left_before[b + 1] = c;
    });
    for (uint32_t b = 0; b < blocks; ++b)
      left_before[b + 1] += left_before[b];
    const uint32_t total_left = left_before[blocks];
    tbb::parallel_for(0u, blocks, [&](uint32_t b) {
      const uint32_t lo = r.begin + b * kParallelGrain, hi = std::min(r.end, lo + kParallelGrain);
      uint32_t l = r.begin + left_before[b];
      uint32_t rr = r.begin + total_left + (b * kParallelGrain - left_before[b]);
      for (uint32_t i = lo; i < hi; ++i)
        scratch_[pred(refs_[i]) ? l++ : rr++] = refs_[i];
    });
    tbb::parallel_for(tbb::blocked_range<uint32_t>(r.begin, r.end, kParallelGrain), [&](auto br) {
      std::copy(scratch_.begin() + br.begin(), scratch_.begin() + br.end(),
                refs_.begin() + br.begin());
    });
    *left = Bounds{};
    *right = Bounds{};
    for (uint32_t b = 0; b < blocks; ++b) {
      left->merge(lbs[b]);
      right->merge(rbs[b]);
    }
    return r.begin + total_left;
  }

  // Object median on the widest centroid axis; with coincident centroids the
  // range is simply halved. Keeps the depth logarithmic.
  uint32_t median_split(const Range& r) {
    const Vec3 e = r.cbox2().extent();
    const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
    const uint32_t mid = r.begin + r.size() / 2;
    if (component(e, axis) > 0.0f) {
      std::nth_element(refs_.begin() + r.begin, refs_.begin() + mid, refs_.begin() + r.end,
                       [&](const PrimRef& a, const PrimRef& b) {
                         const float ca = a.centroid2(axis), cb = b.centroid2(axis);
                         return ca < cb || (ca == cb && a.id() < b.id());
                       });
    }
    return mid;
  }

  // Exact SAH for a handful of primitives: sort them along the widest
  // centroid axis and try every split. Binning costs a fixed amount per node
  // (resetting and sweeping bins on three axes), which dominates the bottom
  // levels of a tree with small leaves, such as a TLAS with one instance per
  // leaf. Returns the split's cost, with left/right filled in.
  double small_split(const Range& r, Range* left, Range* right) {
    const Vec3 e = r.cbox2().extent();
    const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
    PrimRef* p = refs_.data() + r.begin;
    const uint32_t n = r.size();
    for (uint32_t i = 1; i < n; ++i) {  // insertion sort, ties by id: deterministic
      const PrimRef x = p[i];
      uint32_t j = i;
      for (; j > 0; --j) {
        const float a = p[j - 1].centroid2(axis), b = x.centroid2(axis);
        if (a < b || (a == b && p[j - 1].id() < x.id())) break;
        p[j] = p[j - 1];
      }
      p[j] = x;
    }
    Bounds suffix[kSmallNode + 1];
    for (uint32_t i = n; i-- > 0;) {
      suffix[i] = suffix[i + 1];
      suffix[i].add(p[i]);
    }
    const double ct = s_.traversal_cost, ci = s_.intersection_cost;
    const double parent = r.box().half_area();
    Bounds prefix;
    double best = 0.0;
    uint32_t best_i = 0;
    for (uint32_t i = 1; i < n; ++i) {
      prefix.add(p[i - 1]);
      const double cost =
          ct * parent + ci * (double(half_area(prefix.lo, prefix.hi)) * i +
                              double(half_area(suffix[i].lo, suffix[i].hi)) * (n - i));
      // Ties (coincident primitives) go to the most balanced split, which
      // keeps such subtrees shallow.
      const auto imbalance = [n](uint32_t k) { return k > n - k ? 2 * k - n : n - 2 * k; };
      if (best_i == 0 || cost < best || (cost == best && imbalance(i) < imbalance(best_i))) {
        best = cost;
        best_i = i;
      }
    }
    *left = Range{r.begin, r.begin + best_i, {}};
    *right = Range{r.begin + best_i, r.end, suffix[best_i]};
    for (uint32_t i = 0; i < best_i; ++i)
      left->b.add(p[i]);
    return best;
  }

  void build(uint32_t node, Range r, uint32_t depth) {
    const uint32_t n = r.size();
    if (n == 1) return make_leaf(node, r, depth);
    const bool use_sah = s_.method == SplitMethod::kBinnedSah && depth < kSahMaxDepth;
    Range left{r.begin, r.begin, {}}, right{r.begin, r.end, {}};
    bool have_bounds = false;
    if (use_sah && n <= kSmallNode) {
      const double split_cost = small_split(r, &left, &right);
      const double leaf_cost = double(s_.intersection_cost) * n * r.box().half_area();
      if (n <= s_.max_leaf_size && leaf_cost <= split_cost) return make_leaf(node, r, depth);
      have_bounds = true;
    } else if (use_sah) {
      const Split split = find_sah_split(r);
      const double leaf_cost = double(s_.intersection_cost) * n * r.box().half_area();
      if (n <= s_.max_leaf_size && (split.axis < 0 || leaf_cost <= split.cost)) {
        return make_leaf(node, r, depth);
      }
      if (split.axis >= 0) {
        const BinMapping map(r.cbox2(), split.k, s_.all_axes);
        const int axis = split.axis;
        Bounds lb, rb;
        const uint32_t mid = partition(
            r, [&](const PrimRef& p) { return map.bin(p, axis) <= split.bin; }, &lb, &rb);
        left = {r.begin, mid, lb};
        right = {mid, r.end, rb};
        have_bounds = true;
      }
    } else if (n <= s_.max_leaf_size) {
      return make_leaf(node, r, depth);
    }
    if (!have_bounds) {
      const uint32_t mid = median_split(r);
      left = {r.begin, mid, {}};
      right = {mid, r.end, {}};
      compute_bounds(left);
      compute_bounds(right);
    }
    const uint32_t children = node_count_.fetch_add(2);
    BuildNode& nd = nodes_[node];
    nd.box = r.box();
    nd.first = r.begin;
    nd.count = n;
    nd.child[0] = children;
    nd.child[1] = children + 1;
    if (n >= kTaskThreshold) {
      tbb::parallel_invoke([&] { build(children, left, depth + 1); },
                           [&] { build(children + 1, right, depth + 1); });
    } else {
      build(children, left, depth + 1);
      build(children + 1, right, depth + 1);
    }
  }

  std::span<const Aabb> boxes_;
  BuildSettings s_;
  std::vector<PrimRef> refs_, scratch_;
  std::vector<BuildNode> nodes_;
  std::atomic<uint32_t> node_count_{0};
  std::atomic<uint32_t> max_depth_{0};
};

}  // namespace

BuildTree build_bvh(std::span<const Aabb> boxes, const BuildSettings& settings) {
  return Builder(boxes, settings).run();
}

double sah_cost(const BuildTree& tree, float traversal_cost, float intersection_cost) {
  if (tree.empty()) return 0.0;
  double sum = 0.0;
  for (const BuildNode& n : tree.nodes) {
    const double a = n.box.half_area();
    sum += n.is_leaf() ? a * n.count * intersection_cost : a * traversal_cost;
  }
  const double root = tree.nodes[tree.root].box.half_area();
  return root > 0.0 ? sum / root : 0.0;
}

}  // namespace tandem
