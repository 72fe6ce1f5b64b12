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
// The kernel arrays are the refit's only copy: it reads the old boxes (and
// the topology) from them and writes the new ones there, and leaves the
// host copy in BvhLayouts (nodes, wide_nodes) as it was; copy_boxes_to_host()
// brings that up to date when someone reads it. Reading and writing both
// copies every frame doubled the bytes the refit moves, and the frame loop
// only consumes the kernel arrays. The same leaf-order pass that takes the
// leaf boxes also rewrites the binary leaves' vertex records
// (bvh_leaf_triangles), which a second pass used to read the same vertices
// again for.
//
// Without wide nodes and records to write (a mesh that deforms whole, traced
// in binary alone), the leaf pass needs only each binary leaf's box: it is
// taken from the leaf's distinct vertices (listed by index(), each loaded
// once) rather than from its triangles' three each, with the same bits.
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
    // Leaf records rewritten (relative to bases.prim), ascending, one span
    // per task at most; empty when no records were given.
    std::vector<NodeSpan> leaf_spans;
  };
  // Refits the hierarchy indexed to the mesh's current positions in the
  // kernel arrays: nodes / wide_nodes / leaf_triangles point at this BLAS's
  // first node / wide node / leaf record (bases.node etc. of the arrays),
  // and hold it as emit_layouts() and the leaf records' writer put it there
  // (child references include `bases`). leaf_triangles may be null: then
  // no records are written; wide_nodes may be null: then the wide layout is
  // left as it was (its boxes are re-quantised from the binary ones, so a
  // later refit with it, even of an unchanged mesh, brings it up to date). Updates l.bounds, and
  // only that of `l`: the host copy of the nodes goes stale (copy_boxes_to_host()). mesh.positions
  // must have one readable element past the last vertex (KernelScene's positions do).
  // overwrite_records: the caller knows every vertex moved (its delta holds
  // the mesh's whole vertex range), so the records are written without
  // reading the old ones (streaming stores) and each task's whole leaf range
  // is reported; otherwise only the records that changed, bit for bit.
  Result refit(BvhLayouts& l, const MeshGeometry& mesh, const LayoutBases& bases, KBvhNode* nodes,
               KWideBvhNode* wide_nodes, KLeafTriangle* leaf_triangles,
               bool overwrite_records = false) const;

  // Copies the boxes (binary: c0_xy, c1_xy, c01_z; wide: origin, exponents,
  // quantised planes) of the kernel arrays' copy of `l` (pointers as for
  // refit()) into l, whose topology they share: l is then what an eager
  // refit of the host copy would have made, byte for byte.
  static void copy_boxes_to_host(BvhLayouts& l, const KBvhNode* nodes,
                                 const KWideBvhNode* wide_nodes);

 private:
  struct Task {
    uint32_t lo = 0, hi = 0;            // binary nodes [lo, hi): one subtree
    uint32_t wide_lo = 0, wide_hi = 0;  // its wide nodes in anchored_
    uint32_t leaf_lo = 0, leaf_hi = 0;  // its leaf entries, contiguous (preorder)
    // Its binary leaves in leaf_sizes_ and their first word in leaf_verts_.
    uint32_t leaves_lo = 0, leaves_hi = 0, verts_lo = 0;
  };
  // A wide node re-quantised once binary node `anchor` is refit.
  struct Anchored {
    uint32_t anchor, wide;
  };
  // Fills leaf_verts_ and leaf_sizes_ and the tasks' ranges in them.
  void index_leaf_vertices(const BvhLayouts& l);
  bool indexed_ = false;
  uint32_t vertex_count_ = 0, triangle_count_ = 0;
  std::vector<uint32_t> leaf_tris_;  // 3 vertex indices per binary leaf entry
  // Per binary leaf holding triangles, in leaf-entry order: its distinct
  // vertices in the order of their last use by its triangles, the last one
  // repeated up to a multiple of four (leaf_verts_), and its triangle count
  // and groups of four (leaf_sizes_). Empty when a leaf holds more than 255
  // triangles.
  struct LeafSize {
    uint8_t triangles, groups;
  };
  std::vector<uint32_t> leaf_verts_;
  std::vector<LeafSize> leaf_sizes_;
  bool vertex_lists_ = false;          // leaf_verts_ and leaf_sizes_ cover every task
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
