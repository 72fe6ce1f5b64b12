#include "accstruc/partial_refit.h"

#include <algorithm>

namespace tandem {

namespace {

constexpr uint32_t kNone = 0xffffffffu;

double child_areas(const KBvhNode& n) {
  return double(binary_child_box(n, 0).half_area()) + double(binary_child_box(n, 1).half_area());
}

uint32_t wide_leaf_count(uint32_t meta) {
  const uint32_t unary = meta >> 5;
  return unary == 1 ? 1 : (unary == 3 ? 2 : 3);
}

}  // namespace

void PartialRefit::index(const BvhLayouts& l, std::span<const Aabb> prim_boxes,
                         uint32_t prim_count) {
  const uint32_t n = uint32_t(l.nodes.size()), wn = uint32_t(l.wide_nodes.size());
  parent_.assign(n, kNone);
  prim_node_.assign(prim_count, kNone);
  area_sum_ = 0.0;
  for (uint32_t i = 0; i < n; ++i) {
    const KBvhNode& node = l.nodes[i];
    area_sum_ += child_areas(node);
    for (uint32_t c = 0; c < 2; ++c) {
      if (node.child[c] & kBvhLeafFlag) {
        const uint32_t first = node.child[c] & ~kBvhLeafFlag;
        for (uint32_t e = first; e < first + node.count[c]; ++e)
          prim_node_[l.prims[e]] = i;
      } else {
        parent_[node.child[c]] = i;
      }
    }
  }
  wide_parent_.assign(wn, kNone);
  prim_wide_node_.assign(prim_count, kNone);
  for (uint32_t i = 0; i < wn; ++i) {
    const KWideBvhNode& node = l.wide_nodes[i];
    uint32_t rank = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      if (node.meta[s] == 0) continue;
      if ((node.imask >> s) & 1u) {
        wide_parent_[node.child_base + rank++] = i;
        continue;
      }
      const uint32_t first = node.prim_base + (node.meta[s] & 31u);
      for (uint32_t e = first; e < first + wide_leaf_count(node.meta[s]); ++e)
        prim_wide_node_[l.wide_prims[e]] = i;
    }
  }
  // Children come after their parents: bottom-up is a backward pass.
  wide_boxes_.assign(wn, Aabb{});
  for (uint32_t i = wn; i-- > 0;)
    wide_boxes_[i] = wide_node_box(l, i, prim_boxes, wide_boxes_);
  mark_.assign(n, 0);
  wide_mark_.assign(wn, 0);
}

void PartialRefit::collect(uint32_t from, const std::vector<uint32_t>& parent,
                           std::vector<uint8_t>& mark, std::vector<uint32_t>& out) {
  for (uint32_t i = from; i != kNone && !mark[i]; i = parent[i]) {
    mark[i] = 1;
    out.push_back(i);
  }
}

void PartialRefit::refit(BvhLayouts& l, std::span<const Aabb> prim_boxes,
                         std::span<const uint32_t> prims) {
  changed_.clear();
  changed_wide_.clear();
  for (uint32_t p : prims) {
    if (p >= prim_node_.size()) continue;
    if (prim_node_[p] != kNone) collect(prim_node_[p], parent_, mark_, changed_);
    if (prim_wide_node_[p] != kNone)
      collect(prim_wide_node_[p], wide_parent_, wide_mark_, changed_wide_);
  }
  std::sort(changed_.begin(), changed_.end());
  std::sort(changed_wide_.begin(), changed_wide_.end());
  // Descending: every child before its parent.
  for (auto it = changed_.rbegin(); it != changed_.rend(); ++it) {
    area_sum_ -= child_areas(l.nodes[*it]);
    const Aabb box = refit_binary_node(l, *it, prim_boxes);
    area_sum_ += child_areas(l.nodes[*it]);
    if (*it == 0) l.bounds = box;
    mark_[*it] = 0;
  }
  for (auto it = changed_wide_.rbegin(); it != changed_wide_.rend(); ++it) {
    wide_boxes_[*it] = refit_wide_node(l, *it, prim_boxes, wide_boxes_);
    wide_mark_[*it] = 0;
  }
}

}  // namespace tandem
