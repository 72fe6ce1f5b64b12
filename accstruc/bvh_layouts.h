// Conversion of a BuildTree into the two kernel layouts of core/kernel/bvh.h,
// refitting them in place, checking them, and copying them into the
// concatenated kernel arrays.
//
// A BvhLayouts holds one hierarchy (a mesh's BLAS or the TLAS) with indices
// relative to itself, so it can be cached on disk and placed anywhere in the
// kernel arrays; emit_layouts() adds the bases when copying.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "accstruc/bvh_builder.h"
#include "core/kernel/bvh.h"

namespace tandem {

struct BvhLayouts {
  std::vector<KBvhNode> nodes;           // binary layout, root at 0
  std::vector<uint32_t> prims;           // primitive ids in the binary layout's leaf order
  std::vector<KWideBvhNode> wide_nodes;  // wide layout, root at 0
  std::vector<uint32_t> wide_prims;      // primitive ids of the wide layout's leaves
  Aabb bounds;                           // box of all primitives in the hierarchy
  uint32_t depth = 0;                    // levels of the binary build tree
  double sah_cost = 0.0;                 // of the binary tree (C_trav, C_isect of the build)
  double wide_sah_cost = 0.0;            // of the wide tree, same constants
  bool empty() const { return nodes.empty(); }
};

// Where a hierarchy starts in each concatenated kernel array.
struct LayoutBases {
  uint32_t node = 0, prim = 0, wide_node = 0, wide_prim = 0;
};

// Builds both layouts from a tree. prim_boxes are the boxes the tree was
// built from (to bound the leaves that the wide layout splits);
// max_wide_leaf_prims is the number of primitives per wide leaf slot (3 for
// triangles, 1 for instances). Leaves of the tree may hold at most
// 8 * max_wide_leaf_prims primitives.
BvhLayouts make_layouts(const BuildTree& tree, std::span<const Aabb> prim_boxes,
                        uint32_t max_wide_leaf_prims, float traversal_cost,
                        float intersection_cost);

// Binary layout only (also used by make_layouts).
void flatten_binary(const BuildTree& tree, BvhLayouts& out);
// Wide layout only (also used by make_layouts). Sets wide_sah_cost.
void collapse_wide(const BuildTree& tree, std::span<const Aabb> prim_boxes,
                   uint32_t max_wide_leaf_prims, float traversal_cost, float intersection_cost,
                   BvhLayouts& out);

// Recomputes every box of both layouts bottom-up from the primitives' current
// boxes (topology unchanged), in O(n), in parallel for large hierarchies.
// Invalid primitive boxes count as empty. Updates `bounds`. Returns the
// refit tree's refit_quality() (up to summation order).
double refit_layouts(BvhLayouts& layouts, std::span<const Aabb> prim_boxes);

// When a refit tree is rebuilt (the TLAS and every BLAS alike): a refit
// keeps the topology while the primitives move, so boxes grow and overlap.
// refit_quality() is the SAH's node term of the binary layout, the sum of
// both child boxes' half areas over all nodes relative to the root's (the
// expected number of box tests of a ray through the root, up to constants);
// a refit tree whose quality exceeds kRefitQualityLimit times its quality
// right after its build traces that much slower than a rebuild would, and is
// rebuilt.
constexpr double kRefitQualityLimit = 1.3;
double refit_quality(const BvhLayouts& layouts);
bool refit_too_poor(double quality, double built_quality);

// Element ranges [begin, end) rewritten in a kernel array.
struct NodeSpan {
  uint32_t begin = 0, end = 0;
};
struct NodeSpans {
  NodeSpan nodes, wide_nodes;  // relative to the hierarchy's bases
};
// emit_layouts() of a refit hierarchy's nodes (a refit keeps the primitive
// arrays): writes only the nodes that differ from what the kernel arrays
// hold and returns the span of them, so an upload skips the subtrees a
// deformation left alone.
NodeSpans emit_refit_nodes(const BvhLayouts& layouts, const LayoutBases& bases, KBvhNode* nodes,
                           KWideBvhNode* wide_nodes);

// One node's boxes from its children, for refits of a few paths
// (partial_refit.h). Binary: interior children's boxes are read from the
// child nodes, which must be up to date. Wide: interior children's exact
// boxes come from node_boxes (indexed by wide node). Both return the node's
// exact box, bit for bit what refit_layouts() computes for it.
Aabb refit_binary_node(BvhLayouts& layouts, uint32_t index, std::span<const Aabb> prim_boxes);
Aabb refit_wide_node(BvhLayouts& layouts, uint32_t index, std::span<const Aabb> prim_boxes,
                     std::span<const Aabb> node_boxes);
// refit_wide_node()'s box without touching the node.
Aabb wide_node_box(const BvhLayouts& layouts, uint32_t index, std::span<const Aabb> prim_boxes,
                   std::span<const Aabb> node_boxes);
// Child c's box of a binary node.
Aabb binary_child_box(const KBvhNode& node, uint32_t c);

// Writes child c's box into a binary node (the inverse of
// binary_child_box()); inline, as the refits call it for every child.
inline void set_binary_child_box(KBvhNode& node, uint32_t c, const Aabb& b) {
  Vec4& xy = c == 0 ? node.c0_xy : node.c1_xy;
  xy = {b.lo.x, b.hi.x, b.lo.y, b.hi.y};
  if (c == 0) {
    node.c01_z.x = b.lo.z;
    node.c01_z.y = b.hi.z;
  } else {
    node.c01_z.z = b.lo.z;
    node.c01_z.w = b.hi.z;
  }
}

// Structural check of an untrusted hierarchy (e.g. read from disk): every
// index in range, children after their parents (no cycles), depth within the
// kernel stacks, primitive ids below prim_count. Boxes are not checked.
bool validate_layouts(const BvhLayouts& layouts, uint32_t prim_count);

// Copies a hierarchy into the kernel arrays at `bases`, making its indices
// absolute. The destination ranges must hold nodes.size(), prims.size(),
// wide_nodes.size() and wide_prims.size() elements.
void emit_layouts(const BvhLayouts& layouts, const LayoutBases& bases, KBvhNode* nodes,
                  uint32_t* prims, KWideBvhNode* wide_nodes, uint32_t* wide_prims);

// A BLAS's wide leaf entries as the kernel holds them: entry j of the wide
// layout is written as the binary leaf entry (base.prim + position in
// layouts.prims) of the same triangle, so that both layouts read a
// triangle's vertices from its one leaf record (bvh_leaf_triangles) and a
// refit, which rewrites those records, serves both. Overwrites what
// emit_layouts() wrote to wide_prims for a BLAS (the TLAS keeps instance
// indices).
void emit_blas_wide_entries(const BvhLayouts& layouts, const LayoutBases& bases,
                            uint32_t* wide_prims);

// emit_layouts() for the listed nodes only (node indices relative to the
// hierarchy; the primitive arrays are left alone).
void emit_layout_nodes(const BvhLayouts& layouts, const LayoutBases& bases,
                       std::span<const uint32_t> node_list,
                       std::span<const uint32_t> wide_node_list, KBvhNode* nodes,
                       KWideBvhNode* wide_nodes);

// Decoded box of a wide node's slot (for tests and refits).
Aabb wide_slot_box(const KWideBvhNode& node, uint32_t slot);

}  // namespace tandem
