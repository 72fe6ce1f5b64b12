// Binned SAH BVH builder (Wald 2007, "On fast Construction of SAH-based
// Bounding Volume Hierarchies"), parallel with TBB: large nodes bin and
// partition their primitives in parallel, subtrees are built as tasks.
//
// The builder only sees primitive boxes, so the same code builds a mesh's
// BLAS (triangle boxes) and the scene's TLAS (world boxes of instances). Its
// result, a BuildTree, is converted into the kernel layouts by
// bvh_layouts.h.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/kernel/math.h"
#include "core/kernel/types.h"

namespace tandem {

// Axis-aligned box. An empty box is inverted (lo = +max, hi = -max) so that
// growing it by anything gives that thing.
struct Aabb {
  Vec3 lo{kFloatMax, kFloatMax, kFloatMax};
  Vec3 hi{-kFloatMax, -kFloatMax, -kFloatMax};

  void grow(Vec3 p) {
    lo = min_v(lo, p);
    hi = max_v(hi, p);
  }
  void grow(const Aabb& b) {
    lo = min_v(lo, b.lo);
    hi = max_v(hi, b.hi);
  }
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  Vec3 extent() const { return hi - lo; }
  Vec3 center() const { return (lo + hi) * 0.5f; }
  // Half the surface area; SAH only needs ratios of areas.
  float half_area() const {
    if (empty()) return 0.0f;
    const Vec3 e = extent();
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }
};

// Largest coordinate magnitude a primitive may have; Embree uses the same
// limit for valid vertices. It also keeps the wide layout's power-of-two
// scales far from overflow.
constexpr float kMaxCoordinate = 1.844e18f;

// Non-inverted box within +-kMaxCoordinate (so NaN-free): primitives failing
// this (NaN/inf/huge vertices, out-of-range indices) are left out of the
// hierarchy, as Embree does.
// Inline: the refit tests every triangle's box with it each frame.
inline bool aabb_valid(const Aabb& b) {
  const float m = kMaxCoordinate;
  return b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z && b.lo.x >= -m && b.lo.y >= -m &&
         b.lo.z >= -m && b.hi.x <= m && b.hi.y <= m && b.hi.z <= m;
}

enum class SplitMethod : uint8_t {
  kBinnedSah,  // SAH over bins of centroids
  kMedian,     // object median on the widest centroid axis (reference only)
};

// The builder's constants and limits. They are part of the BVH cache key.
struct BuildSettings {
  SplitMethod method = SplitMethod::kBinnedSah;
  uint32_t bins = 16;              // SAH bins per axis (2..64)
  bool all_axes = true;            // bin all three axes, or only the widest centroid axis
  uint32_t max_leaf_size = 4;      // a larger node is always split
  float traversal_cost = 1.0f;     // C_trav of the SAH
  float intersection_cost = 1.0f;  // C_isect of the SAH
  // build_bvh_spatial() only: extra references that spatial splits may add,
  // as a fraction of the triangles (0: none), and the overlap of an object
  // split's children, relative to the root's area, above which a node tries
  // spatial splits (Stich et al.'s alpha; their 1e-5 gave builtin:procedural
  // the same trees at a third of the build speed).
  float spatial_split_budget = 0.0f;
  float spatial_split_alpha = 1e-3f;
};

// Node of the builder's binary tree. [first, first + count) is the node's
// range in BuildTree::prims, for interior nodes too (a subtree's primitives
// are contiguous).
struct BuildNode {
  Aabb box;
  uint32_t child[2] = {kInvalidIndex, kInvalidIndex};
  uint32_t first = 0, count = 0;
  bool is_leaf() const { return child[0] == kInvalidIndex; }
};

struct BuildTree {
  std::vector<BuildNode> nodes;  // nodes[root] is the root; empty when no valid primitive
  uint32_t root = kInvalidIndex;
  std::vector<uint32_t> prims;  // primitive indices in leaf order
  // build_bvh_spatial() only: the (clipped) box of each entry of prims; a
  // split triangle has one entry per piece. Empty: the entries' boxes are
  // their primitives' boxes.
  std::vector<Aabb> ref_boxes;
  uint32_t depth = 0;  // levels, the root counting as 1
  bool empty() const { return root == kInvalidIndex; }
};

// Deepest tree the builder makes. Below kSahMaxDepth levels it switches to
// median splits, whose depth is logarithmic, so kernel traversal stacks of
// kBvhStackSize entries can never overflow.
constexpr uint32_t kSahMaxDepth = 28;

// Builds a hierarchy over `boxes` (one per primitive; invalid boxes are
// skipped). Thread-safe; uses the calling TBB arena.
BuildTree build_bvh(std::span<const Aabb> boxes, const BuildSettings& settings);

// Triangle BVH with spatial splits (accstruc/spatial_bvh.cpp) within
// settings.spatial_split_budget; boxes[i] must be triangle i's box. The tree
// may list a triangle in several leaves (with ref_boxes set): it cannot be
// refit (BlasRefit, refit_layouts), so meshes that deform use build_bvh().
BuildTree build_bvh_spatial(std::span<const Aabb> boxes, std::span<const Vec3> positions,
                            std::span<const KTriangle> triangles, const BuildSettings& settings);

// SAH cost of a tree: (sum over interior nodes of A(n) * C_trav + sum over
// leaves of A(n) * count * C_isect) / A(root).
double sah_cost(const BuildTree& tree, float traversal_cost, float intersection_cost);

}  // namespace tandem
