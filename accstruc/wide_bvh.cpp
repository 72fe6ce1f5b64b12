// The 8-wide compressed layout (Ylitie, Karras & Laine 2017) made from the
// binary build tree: collapse, slot ordering, quantisation and refit.
#include "accstruc/wide_bvh.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <stdexcept>
#include <utility>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tandem {

namespace {

// Largest exponent whose scale keeps 255 * 2^e far from overflow.
constexpr int kMaxExponent = 119;
constexpr int kMinExponent = -126;

float exp2_int(int e) {
  return uint_as_float(uint32_t(e + 127) << 23);
}

// Plane value exactly as the traversal decodes it (wide_child_box).
float decode(float origin, uint32_t q, float scale) {
  return origin + float(q) * scale;
}

// Smallest-ish power of two such that origin + 255 * 2^e, in float, reaches hi.
int choose_exponent(float lo, float hi) {
  const float ext = hi - lo;
  int e = kMinExponent;
  if (ext > 0.0f) {
    // frexp's exponent (ext / 255 <= 2^exp2), from the bits when the
    // quotient is a normal finite float: a refit re-quantises every node
    // every frame, and frexp is a library call.
    const float q = ext / 255.0f;
    const uint32_t biased = (float_as_uint(q) >> 23) & 0xffu;
    int exp2 = 0;
    if (biased != 0 && biased != 0xffu) {
      exp2 = int(biased) - 126;
    } else {
      std::frexp(q, &exp2);
    }
    e = std::max(exp2, kMinExponent);
  }
  while (e < kMaxExponent && decode(lo, 255, exp2_int(e)) < hi)
    ++e;
  return e;
}

// One axis's planes of the eight slots, conservatively: qlo[s] the largest q
// with origin + q * scale <= lo[s] (0 at least), qhi[s] the smallest with
// origin + q * scale >= hi[s] (255 at most); a slot not in `live` gets the
// inverted 255 / 0. floor and ceil by truncation (which is floor for the
// positive values that reach it), then stepped until the decoded plane, in
// float exactly as the traversal decodes it, holds the box.
#if !defined(__SSE2__)
void quantize_planes_scalar(float o, float sc, float inv, const float lo[kWideBvhWidth],
                            const float hi[kWideBvhWidth], uint32_t live, uint8_t qlo_out[],
                            uint8_t qhi_out[]) {
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    if (!((live >> s) & 1u)) {
      qlo_out[s] = 255;
      qhi_out[s] = 0;
      continue;
    }
    float f = (lo[s] - o) * inv;
    uint32_t qlo = f > 0.0f ? (f >= 255.0f ? 255u : uint32_t(f)) : 0u;
    while (qlo > 0 && decode(o, qlo, sc) > lo[s])
      --qlo;
    f = (hi[s] - o) * inv;
    uint32_t qhi = 0;
    if (f > 0.0f) {
      qhi = f >= 255.0f ? 255u : uint32_t(f);
      qhi += qhi < 255u && float(qhi) < f ? 1u : 0u;
    }
    while (qhi < 255 && decode(o, qhi, sc) < hi[s])
      ++qhi;
    qlo_out[s] = uint8_t(qlo);
    qhi_out[s] = uint8_t(qhi);
  }
}
#endif

// quantize_planes_scalar() four slots at a time: a refit re-quantises every
// wide node every frame, and the slot-by-slot loop with its branches was
// more than the rest of the refit (a million skinned vertices, 2026-12-03).
// The same float operations lane by lane: (x - o) * inv; max(f, 0) and
// min(., 255) clamp as the comparisons do (a NaN gives 0); cvttps truncates
// as the conversion does; the decoded planes are o + float(q) * sc.
void quantize_planes(float o, float sc, float inv, const float lo[kWideBvhWidth],
                     const float hi[kWideBvhWidth], uint32_t live, uint8_t qlo_out[],
                     uint8_t qhi_out[]) {
#if defined(__SSE2__)
  const __m128 vo = _mm_set1_ps(o), vsc = _mm_set1_ps(sc), vinv = _mm_set1_ps(inv);
  const __m128 zero = _mm_setzero_ps(), top = _mm_set1_ps(255.0f);
  const __m128i izero = _mm_setzero_si128(), itop = _mm_set1_epi32(255);
  const auto decoded = [&](__m128i q) {
    return _mm_add_ps(vo, _mm_mul_ps(_mm_cvtepi32_ps(q), vsc));
  };
  __m128i qlo[2], qhi[2];
  for (int h = 0; h < 2; ++h) {
    const __m128 l = _mm_load_ps(lo + 4 * h), u = _mm_load_ps(hi + 4 * h);
    __m128 f = _mm_mul_ps(_mm_sub_ps(l, vo), vinv);
    __m128i q = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(f, zero), top));
    for (;;) {  // while (q > 0 && decode(q) > lo) --q, per lane
      const __m128i step =
          _mm_and_si128(_mm_cmpgt_epi32(q, izero), _mm_castps_si128(_mm_cmpgt_ps(decoded(q), l)));
      if (_mm_movemask_epi8(step) == 0) break;
      q = _mm_add_epi32(q, step);
    }
    qlo[h] = q;
    f = _mm_mul_ps(_mm_sub_ps(u, vo), vinv);
    q = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(f, zero), top));
    // Round up where the truncation dropped a fraction (f > 0 and below 255).
    q = _mm_sub_epi32(q, _mm_and_si128(_mm_cmplt_epi32(q, itop),
                                       _mm_castps_si128(_mm_cmplt_ps(_mm_cvtepi32_ps(q), f))));
    for (;;) {  // while (q < 255 && decode(q) < hi) ++q, per lane
      const __m128i step =
          _mm_and_si128(_mm_cmplt_epi32(q, itop), _mm_castps_si128(_mm_cmplt_ps(decoded(q), u)));
      if (_mm_movemask_epi8(step) == 0) break;
      q = _mm_sub_epi32(q, step);
    }
    qhi[h] = q;
  }
  // Eight values of 0..255 to bytes; dead slots inverted.
  alignas(16) uint8_t bl[16], bh[16];
  _mm_store_si128(reinterpret_cast<__m128i*>(bl),
                  _mm_packus_epi16(_mm_packs_epi32(qlo[0], qlo[1]), izero));
  _mm_store_si128(reinterpret_cast<__m128i*>(bh),
                  _mm_packus_epi16(_mm_packs_epi32(qhi[0], qhi[1]), izero));
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    const bool on = ((live >> s) & 1u) != 0;
    qlo_out[s] = on ? bl[s] : uint8_t(255);
    qhi_out[s] = on ? bh[s] : uint8_t(0);
  }
#else
  quantize_planes_scalar(o, sc, inv, lo, hi, live, qlo_out, qhi_out);
#endif
}

// Quantises the boxes of the slots in `used` (bit per slot) conservatively:
// the decoded box always contains the real one. Empty boxes decode inverted.
void quantize(KWideBvhNode& n, const Aabb boxes[kWideBvhWidth], uint32_t used) {
  // The slots' planes by axis, for quantize_planes().
  alignas(16) float lo[3][kWideBvhWidth], hi[3][kWideBvhWidth];
  uint32_t live = 0;
  Aabb all;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    const Aabb& b = boxes[s];
    lo[0][s] = b.lo.x, lo[1][s] = b.lo.y, lo[2][s] = b.lo.z;
    hi[0][s] = b.hi.x, hi[1][s] = b.hi.y, hi[2][s] = b.hi.z;
    if (((used >> s) & 1u) && !b.empty()) {
      live |= 1u << s;
      all.grow(b);
    }
  }
  if (all.empty()) all = Aabb{{0, 0, 0}, {0, 0, 0}};
  n.origin = all.lo;
  for (int a = 0; a < 3; ++a) {
    const int e = choose_exponent(component(all.lo, a), component(all.hi, a));
    n.exponent[a] = uint8_t(e + 127);
    // 2^-e is a normal float for every e chosen, so x * 2^-e rounds the
    // same real number as x / 2^e: the same planes, without a division
    // per plane (a refit re-quantises every node every frame).
    quantize_planes(component(n.origin, a), exp2_int(e), exp2_int(-e), lo[a], hi[a], live, n.qlo[a],
                    n.qhi[a]);
  }
}

uint32_t leaf_count_from_meta(uint32_t meta) {
  const uint32_t unary = meta >> 5;
  return unary == 7 ? 3u : (unary == 3 ? 2u : 1u);
}

// One child of a wide node before it gets a slot.
struct Entry {
  Aabb box;
  bool interior = false;
  uint32_t build_node = kInvalidIndex;  // interior: the build node it becomes
  uint32_t first = 0, count = 0;        // leaf: range in BuildTree::prims
};

class WideCollapser {
 public:
  WideCollapser(const BuildTree& tree, std::span<const Aabb> prim_boxes, uint32_t leaf_prims,
                float ct, float ci, BvhLayouts& out)
      : tree_(tree), boxes_(prim_boxes), leaf_prims_(leaf_prims), ct_(ct), ci_(ci), out_(out) {
    if (leaf_prims_ < 1 || leaf_prims_ > kWideMaxLeafPrims) {
      throw std::invalid_argument("wide BVH: primitives per leaf slot must be 1 to 3");
    }
  }

  void run() {
    out_.wide_nodes.assign(1, KWideBvhNode{});
    out_.wide_prims.clear();
    out_.wide_prims.reserve(tree_.prims.size());
    sah_sum_ = 0.0;
    std::vector<std::pair<uint32_t, uint32_t>> work{{0u, tree_.root}};  // (wide, build)
    while (!work.empty()) {
      const auto [wide, build] = work.back();
      work.pop_back();
      process(wide, build, work);
    }
    const double root_area = tree_.nodes[tree_.root].box.half_area();
    out_.wide_sah_cost = root_area > 0.0 ? sah_sum_ / root_area : 0.0;
  }

 private:
  uint32_t slots(const BuildNode& n) const {
    return leaf_like(n) ? (n.count + leaf_prims_ - 1) / leaf_prims_ : 1u;
  }
  // Becomes one or more leaf slots of its parent (at most half the slots, so
  // two such siblings always fit).
  bool leaf_like(const BuildNode& n) const {
    return n.count <= leaf_prims_ || (n.is_leaf() && n.count <= 4 * leaf_prims_);
  }

  void add_leaf_entries(const BuildNode& n, std::vector<Entry>& entries) const {
    if (n.count > kWideBvhWidth * leaf_prims_) {
      throw std::invalid_argument("wide BVH: a leaf of the build tree has too many primitives");
    }
    for (uint32_t first = n.first; first < n.first + n.count; first += leaf_prims_) {
      Entry e;
      e.first = first;
      e.count = std::min(leaf_prims_, n.first + n.count - first);
      if (e.count == n.count) {
        e.box = n.box;
      } else {
        for (uint32_t i = e.first; i < e.first + e.count; ++i)
          e.box.grow(tree_.ref_boxes.empty() ? boxes_[tree_.prims[i]] : tree_.ref_boxes[i]);
      }
      entries.push_back(e);
    }
  }

  // The children of a wide node: open the largest interior candidate while
  // its children still fit in the free slots.
  std::vector<Entry> gather(uint32_t build) const {
    std::vector<Entry> entries;
    const BuildNode& b = tree_.nodes[build];
    if (b.is_leaf()) {
      add_leaf_entries(b, entries);
      return entries;
    }
    uint32_t cands[kWideBvhWidth] = {b.child[0], b.child[1]};
    uint32_t n = 2;
    for (;;) {
      uint32_t used = 0;
      for (uint32_t i = 0; i < n; ++i)
        used += slots(tree_.nodes[cands[i]]);
      int best = -1;
      float best_area = -1.0f;
      for (uint32_t i = 0; i < n; ++i) {
        const BuildNode& c = tree_.nodes[cands[i]];
        if (c.is_leaf() || leaf_like(c)) continue;
        const uint32_t grown =
            used - 1 + slots(tree_.nodes[c.child[0]]) + slots(tree_.nodes[c.child[1]]);
        if (grown > kWideBvhWidth || n + 1 > kWideBvhWidth) continue;
        const float area = c.box.half_area();
        if (area > best_area) {
          best_area = area;
          best = int(i);
        }
      }
      if (best < 0) break;
      const BuildNode& c = tree_.nodes[cands[best]];
      cands[best] = c.child[0];
      cands[n++] = c.child[1];
    }
    for (uint32_t i = 0; i < n; ++i) {
      const BuildNode& c = tree_.nodes[cands[i]];
      if (leaf_like(c)) {
        add_leaf_entries(c, entries);
      } else {
        Entry e;
        e.box = c.box;
        e.interior = true;
        e.build_node = cands[i];
        entries.push_back(e);
      }
    }
    return entries;
  }

  // Slot s gets the entry met first by rays of octant s (smallest projection
  // on that octant's diagonal), greedily by cost.
  static void assign_slots(const std::vector<Entry>& entries, int slot_of[kWideBvhWidth]) {
    Aabb all;
    for (const Entry& e : entries)
      all.grow(e.box);
    const Vec3 pc = all.center();
    float cost[kWideBvhWidth][kWideBvhWidth];
    for (size_t e = 0; e < entries.size(); ++e) {
      const Vec3 d = entries[e].box.center() - pc;
      for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
        cost[e][s] = ((s & 1u) ? -d.x : d.x) + ((s & 2u) ? -d.y : d.y) + ((s & 4u) ? -d.z : d.z);
      }
    }
    bool slot_taken[kWideBvhWidth] = {};
    for (size_t e = 0; e < entries.size(); ++e)
      slot_of[e] = -1;
    for (size_t round = 0; round < entries.size(); ++round) {
      int be = -1, bs = -1;
      for (size_t e = 0; e < entries.size(); ++e) {
        if (slot_of[e] >= 0) continue;
        for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
          if (slot_taken[s]) continue;
          if (be < 0 || cost[e][s] < cost[be][bs]) {
            be = int(e);
            bs = int(s);
          }
        }
      }
      slot_of[be] = bs;
      slot_taken[bs] = true;
    }
  }

  void process(uint32_t wide, uint32_t build, std::vector<std::pair<uint32_t, uint32_t>>& work) {
    const std::vector<Entry> entries = gather(build);
    int slot_of[kWideBvhWidth];
    assign_slots(entries, slot_of);
    const Entry* by_slot[kWideBvhWidth] = {};
    for (size_t e = 0; e < entries.size(); ++e)
      by_slot[slot_of[e]] = &entries[e];

    KWideBvhNode node{};
    node.child_base = uint32_t(out_.wide_nodes.size());
    node.prim_base = uint32_t(out_.wide_prims.size());
    Aabb boxes[kWideBvhWidth];
    uint32_t used = 0, rank = 0;
    std::vector<std::pair<uint32_t, uint32_t>> children;
    Aabb all;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const Entry* e = by_slot[s];
      if (!e) continue;
      used |= 1u << s;
      boxes[s] = e->box;
      all.grow(e->box);
      if (e->interior) {
        node.imask |= uint8_t(1u << s);
        node.meta[s] = uint8_t(kWideMetaInterior | (24u + s));
        children.push_back({node.child_base + rank++, e->build_node});
      } else {
        const uint32_t offset = uint32_t(out_.wide_prims.size()) - node.prim_base;
        node.meta[s] = uint8_t((((1u << e->count) - 1u) << 5) | offset);
        for (uint32_t i = e->first; i < e->first + e->count; ++i) {
          out_.wide_prims.push_back(tree_.prims[i]);
        }
        sah_sum_ += double(e->box.half_area()) * e->count * ci_;
      }
    }
    sah_sum_ += double(all.half_area()) * ct_;
    quantize(node, boxes, used);
    out_.wide_nodes[wide] = node;
    out_.wide_nodes.resize(out_.wide_nodes.size() + rank);
    // Reverse so the first child is processed next: depth-first order.
    for (size_t i = children.size(); i-- > 0;)
      work.push_back(children[i]);
  }

  const BuildTree& tree_;
  std::span<const Aabb> boxes_;
  uint32_t leaf_prims_;
  float ct_, ci_;
  BvhLayouts& out_;
  double sah_sum_ = 0.0;
};

Aabb refit_node(BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes,
                uint32_t parallel_depth) {
  KWideBvhNode& n = l.wide_nodes[index];
  Aabb boxes[kWideBvhWidth];
  uint32_t child_of[kWideBvhWidth];
  uint32_t used = 0, rank = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    if (n.meta[s] != 0) used |= 1u << s;
    child_of[s] = ((n.imask >> s) & 1u) ? n.child_base + rank++ : kInvalidIndex;
  }
  auto slot = [&](uint32_t s) {
    if (!((used >> s) & 1u)) return;
    if (child_of[s] != kInvalidIndex) {
      boxes[s] = refit_node(l, child_of[s], prim_boxes, parallel_depth ? parallel_depth - 1 : 0);
      return;
    }
    const uint32_t first = n.prim_base + (n.meta[s] & 31u);
    const uint32_t count = leaf_count_from_meta(n.meta[s]);
    for (uint32_t i = first; i < first + count; ++i) {
      const Aabb& pb = prim_boxes[l.wide_prims[i]];
      if (aabb_valid(pb)) boxes[s].grow(pb);
    }
  };
  if (parallel_depth > 0 && rank > 1) {
    tbb::parallel_for(0u, kWideBvhWidth, [&](uint32_t s) { slot(s); });
  } else {
    for (uint32_t s = 0; s < kWideBvhWidth; ++s)
      slot(s);
  }
  quantize(n, boxes, used);
  Aabb all;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    if ((used >> s) & 1u) all.grow(boxes[s]);
  }
  return all;
}

}  // namespace

namespace {

// The exact boxes of a node's used slots (interior ones from node_boxes).
uint32_t slot_boxes(const BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes,
                    std::span<const Aabb> node_boxes, Aabb boxes[kWideBvhWidth]) {
  const KWideBvhNode& n = l.wide_nodes[index];
  uint32_t used = 0, rank = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    if (n.meta[s] == 0) continue;
    used |= 1u << s;
    if ((n.imask >> s) & 1u) {
      boxes[s] = node_boxes[n.child_base + rank++];
      continue;
    }
    const uint32_t first = n.prim_base + (n.meta[s] & 31u);
    const uint32_t count = leaf_count_from_meta(n.meta[s]);
    for (uint32_t i = first; i < first + count; ++i) {
      const Aabb& pb = prim_boxes[l.wide_prims[i]];
      if (aabb_valid(pb)) boxes[s].grow(pb);
    }
  }
  return used;
}

Aabb union_of(const Aabb boxes[kWideBvhWidth], uint32_t used) {
  Aabb all;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    if ((used >> s) & 1u) all.grow(boxes[s]);
  }
  return all;
}

}  // namespace

Aabb refit_wide_node(BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes,
                     std::span<const Aabb> node_boxes) {
  Aabb boxes[kWideBvhWidth];
  const uint32_t used = slot_boxes(l, index, prim_boxes, node_boxes, boxes);
  quantize(l.wide_nodes[index], boxes, used);
  return union_of(boxes, used);
}

Aabb wide_node_box(const BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes,
                   std::span<const Aabb> node_boxes) {
  Aabb boxes[kWideBvhWidth];
  const uint32_t used = slot_boxes(l, index, prim_boxes, node_boxes, boxes);
  return union_of(boxes, used);
}

void collapse_wide(const BuildTree& tree, std::span<const Aabb> prim_boxes,
                   uint32_t max_wide_leaf_prims, float traversal_cost, float intersection_cost,
                   BvhLayouts& out) {
  out.wide_nodes.clear();
  out.wide_prims.clear();
  if (tree.empty()) return;
  WideCollapser(tree, prim_boxes, max_wide_leaf_prims, traversal_cost, intersection_cost, out)
      .run();
}

Aabb refit_wide(BvhLayouts& l, std::span<const Aabb> prim_boxes, uint32_t parallel_depth) {
  if (l.wide_nodes.empty()) return Aabb{};
  // The wide tree is about a third as deep as the binary one.
  return refit_node(l, 0, prim_boxes, (parallel_depth + 2) / 3);
}

void quantize_wide_node(KWideBvhNode& node, const Aabb boxes[kWideBvhWidth], uint32_t used) {
  quantize(node, boxes, used);
}

Aabb wide_slot_box(const KWideBvhNode& n, uint32_t slot) {
  Aabb b;
  for (int a = 0; a < 3; ++a) {
    const float sc = wide_node_scale(n, a);
    const float o = component(n.origin, a);
    const float lo = decode(o, n.qlo[a][slot], sc), hi = decode(o, n.qhi[a][slot], sc);
    (a == 0 ? b.lo.x : a == 1 ? b.lo.y : b.lo.z) = lo;
    (a == 0 ? b.hi.x : a == 1 ? b.hi.y : b.hi.z) = hi;
  }
  return b;
}

}  // namespace tandem
