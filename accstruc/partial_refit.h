// Refitting a hierarchy of which only a few primitives moved: the TLAS of
// a frame that moves k of n instances. Only the nodes on the k paths to the
// root are recomputed, O(k log n), and they come out bit for bit as a full
// refit_layouts() would make them: a box is an exact union, so nodes whose
// subtree did not change keep the values a full refit would recompute.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "accstruc/bvh_layouts.h"

namespace tandem {

class PartialRefit {
 public:
  // Indexes `l`, which must be up to date with `prim_boxes` (just built or
  // fully refit): parents, the nodes holding each primitive, the wide
  // nodes' exact boxes and the binary child-area sum. O(n).
  void index(const BvhLayouts& l, std::span<const Aabb> prim_boxes, uint32_t prim_count);
  // Refits the ancestors of `prims` (whose boxes changed in `prim_boxes`)
  // in both layouts and updates `l.bounds`. Afterwards changed_nodes() and
  // changed_wide_nodes() list the rewritten nodes, ascending.
  void refit(BvhLayouts& l, std::span<const Aabb> prim_boxes, std::span<const uint32_t> prims);

  const std::vector<uint32_t>& changed_nodes() const { return changed_; }
  const std::vector<uint32_t>& changed_wide_nodes() const { return changed_wide_; }
  // Sum of both child boxes' half areas over all binary nodes (the SAH's
  // node term), kept up to date by refit().
  double child_area_sum() const { return area_sum_; }

 private:
  // Marks `from` and its ancestors (until an already marked one) in `mark`.
  static void collect(uint32_t from, const std::vector<uint32_t>& parent,
                      std::vector<uint8_t>& mark, std::vector<uint32_t>& out);

  std::vector<uint32_t> parent_, prim_node_;            // binary layout
  std::vector<uint32_t> wide_parent_, prim_wide_node_;  // wide layout
  std::vector<Aabb> wide_boxes_;
  std::vector<uint8_t> mark_, wide_mark_;
  std::vector<uint32_t> changed_, changed_wide_;
  double area_sum_ = 0.0;
};

}  // namespace tandem
