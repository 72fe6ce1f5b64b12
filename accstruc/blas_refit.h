// The per-frame refit of a deforming mesh's BLAS: both layouts in one pass
// over the triangles, written straight into the kernel arrays.
//
// refit_layouts() (bvh_layouts.h) is general but slow on a million moving
// triangles: it needs a box per triangle in an array of its own, read in
// the binary leaves' order and again in the wide leaves' order, and then
// emit_refit_nodes() copies both layouts into the kernel arrays. BlasRefit
// instead indexes a BLAS once after its build:
//   - the triangles' vertex indices in the binary leaves' order, so leaf
//     boxes come from one sequential pass over them;
//   - the binary tree cut into subtrees (contiguous node ranges, the layout
//     being depth-first preorder) refit as parallel tasks, each a reverse
//     sweep over its range (children come after their parents);
//   - for every wide slot, the binary node child whose box is exactly the
//     slot's (the wide tree is collapsed from the same build tree), or the
//     run of at most three triangles of a binary leaf the slot holds when
//     the collapse split a leaf, so the wide nodes are re-quantised from
//     boxes the binary sweep just computed, right after it computed them.
// A node whose boxes did not change is not written, so the reported spans
// (like emit_refit_nodes()'s) cover only what a deformation moved. The
// result is bit for bit what refit_layouts() + emit_refit_nodes() produce
// (same exact unions, same quantisation); only the child-area sum of the
// quality measure is added in another order.
//
// index() refuses (returns false) hierarchies it cannot map that way; the
// caller then keeps using refit_layouts().
#pragma once

#include <cstdint>
#include <vector>

#include "accstruc/bvh_cache.h"
#include "accstruc/bvh_layouts.h"

namespace tandem {

class BlasRefit {
 public:
  // Indexes `l`, a triangle BLAS as built for `mesh` (the kernel arrays
  // hold it as emit_layouts() wrote it). False: not indexable, nothing kept.
  bool index(const BvhLayouts& l, const MeshGeometry& mesh);
  bool indexed() const { return indexed_; }
  void clear();

  struct Result {
    // A triangle of the hierarchy got an invalid box, or one outside it a
    // valid one: only a rebuild can change the set of members.
    bool members_changed = false;
    double quality = 0.0;  // refit_quality() of the refit tree
    NodeSpans spans;       // nodes rewritten, relative to the bases
  };
  // Refits `l` (the hierarchy indexed) to the mesh's current positions, in
  // l and in the kernel arrays at `bases` (nodes / wide_nodes point at the
  // array starts), and updates l.bounds. mesh.positions must have one
  // readable element past the last vertex (KernelScene's positions do).
  Result refit(BvhLayouts& l, const MeshGeometry& mesh, const LayoutBases& bases, KBvhNode* nodes,
               KWideBvhNode* wide_nodes) const;

 private:
  struct Task {
    uint32_t lo = 0, hi = 0;            // binary nodes [lo, hi): one subtree
    uint32_t wide_lo = 0, wide_hi = 0;  // its wide nodes in anchored_
  };
  // A wide node re-quantised once binary node `anchor` is refit.
  struct Anchored {
    uint32_t anchor, wide;
  };
  bool indexed_ = false;
  uint32_t vertex_count_ = 0, triangle_count_ = 0;
  std::vector<uint32_t> leaf_tris_;    // 3 vertex indices per binary leaf entry
  std::vector<uint32_t> non_members_;  // triangles left out at the build
  std::vector<Task> tasks_;
  std::vector<uint32_t> top_;            // nodes above the tasks, descending
  std::vector<Anchored> anchored_;       // per task, by descending anchor
  std::vector<uint32_t> wide_deferred_;  // wide nodes whose sources span tasks
  // Per wide node and slot: kSlot* kind in the top bits, then a binary
  // node child (2 * node + c) or a binary leaf entry (first of <= 3).
  std::vector<uint32_t> wide_src_;
};

}  // namespace tandem
