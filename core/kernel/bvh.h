// Tandem's own bounding volume hierarchies, as the kernels see them.
//
// Every mesh has a BLAS over its triangles (object space) and the scene has
// one TLAS over its instances (world space). Both exist in two layouts built
// from the same binary SAH tree on the host (accstruc/):
//   - binary: Aila & Laine 2009 style, both child boxes stored inline in the
//     parent so one 64-byte load decides which children to visit;
//   - wide: 8-wide compressed nodes after Ylitie, Karras & Laine 2017
//     ("Efficient incoherent ray traversal on GPUs through compressed wide
//     BVHs"): child boxes quantised to 8 bits per plane relative to a
//     per-node origin and power-of-two scale, 80 bytes for 8 children.
// Each layout is one concatenated array holding all BLAS followed by the
// TLAS; indices stored in nodes are absolute within their array.
#pragma once

#include "core/kernel/math.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

enum KBvhLayout : uint32_t { kBvhLayoutBinary = 0, kBvhLayoutWide = 1 };

// KBlasRoot::flags.
enum KBlasFlags : uint32_t {
  // The BLAS's leaf records (bvh_leaf_triangles) are not kept: its triangles
  // are tested through their indices (leaf entry -> triangle -> vertices).
  // Set by the BVH updater for a mesh whose deformer rewrites every vertex
  // each frame, so that the refit neither writes nor uploads 48 bytes a
  // triangle a frame; its records in the array are left stale.
  kBlasNoLeafRecords = 1u << 0,
  // The BLAS's wide-order records (bvh_wide_leaf_triangles) are not current:
  // the wide layout reads its triangles through the binary layout's records
  // (the leaf record index its wide entry holds). Set by the BVH updater for
  // a mesh refit since its arrays were laid out, so that a refit rewrites
  // one set of records, not two.
  kBlasNoWideRecords = 1u << 1,
  // Only the binary layout of the BLAS is current: a mesh that deforms,
  // whose wide nodes the per-frame refit leaves alone because the arrays are
  // traced by the host's loops only (AccelSettings::deforming_binary_only).
  // The host's wide loop traverses its binary nodes; the portable loops
  // never meet the flag.
  kBlasBinaryOnly = 1u << 2,
};

// A mesh's BLAS roots (blas_roots, one per mesh; kInvalidIndex: the mesh has
// no triangles to hit) and how its leaves are tested. Kept apart from KMesh
// because the BVH updater, not the scene compiler, writes them.
struct KBlasRoot {
  uint32_t bvh_root;   // in bvh_nodes
  uint32_t wide_root;  // in bvh_wide_nodes
  uint32_t flags;      // KBlasFlags
  uint32_t pad;
};
static_assert(sizeof(KBlasRoot) == 16, "GPU layout");

// The BVH's scalars (KernelData::bvh), written by the BVH updater: the TLAS
// roots (kInvalidIndex: empty scene) and which layout BvhTracer traverses.
struct KBvhConstants {
  uint32_t tlas_root;       // in bvh_nodes
  uint32_t tlas_wide_root;  // in bvh_wide_nodes
  uint32_t layout;          // KBvhLayout
  uint32_t pad;
};
static_assert(sizeof(KBvhConstants) == 16, "GPU layout");

// Binary layout: a child reference with this bit set is a leaf; the low 31
// bits are then the first entry of its primitive range in bvh_prim_indices.
constexpr uint32_t kBvhLeafFlag = 0x80000000u;
// Traversal stack entries (per level of the hierarchy). The builder keeps
// every tree shallow enough that this can never overflow: SAH splits down to
// kSahMaxDepth levels, then median splits (accstruc/bvh_builder.h).
constexpr uint32_t kBvhStackSize = 64;

// Binary node. Child c's box is (lo.x, hi.x, lo.y, hi.y) in cC_xy and
// (lo.z, hi.z) in c01_z.{x,y} (c = 0) or c01_z.{z,w} (c = 1). An empty child
// (only in a root whose tree is a single leaf) has an inverted box and a
// zero count so it is never entered.
//
// Aligned to a cache line: with 16-byte alignment a large array (which the
// allocator places 16 bytes into a page) put every node across two lines, so
// each node visit, the dependent load the host traversal waits on, missed
// twice. The device arrays are 256-byte aligned anyway; the layout is the
// same bytes.
struct alignas(64) KBvhNode {
  Vec4 c0_xy;
  Vec4 c1_xy;
  Vec4 c01_z;
  uint32_t child[2];  // interior: node index; leaf: kBvhLeafFlag | first primitive entry
  uint32_t count[2];  // leaf: number of primitives; interior: 0
};
static_assert(sizeof(KBvhNode) == 64 && alignof(KBvhNode) == 64, "GPU layout");

// A BLAS leaf entry's triangle with its vertices, in the binary layout's leaf
// order (bvh_leaf_triangles, parallel to bvh_prim_indices; the TLAS's entries
// are unused). A triangle test then reads one 48-byte record, which the
// traversal can fetch as soon as it knows the leaf, instead of a chain of
// three dependent loads (leaf entry, triangle, vertices): on the large scenes
// that chain of cache misses was half of the traversal's time. The vertices
// are the mesh's own floats, so hits are bit for bit those of the indexed
// test; the refit rewrites them when a mesh deforms. The wide layout has the
// same records in its own entry order (bvh_wide_leaf_triangles, parallel to
// bvh_wide_prim_indices), so that a wide leaf's records are next to each
// other and follow from the node alone, as Embree's leaf blocks do.
struct alignas(16) KLeafTriangle {
  Vec4 p0;  // xyz: vertex 0 (object space); w: the triangle's index in its mesh, as bits
  Vec4 p1;  // xyz: vertex 1; w: 0
  Vec4 p2;  // xyz: vertex 2; w: 0
};
static_assert(sizeof(KLeafTriangle) == 48 && alignof(KLeafTriangle) == 16, "GPU layout");

constexpr uint32_t kWideBvhWidth = 8;
// Primitives per leaf slot in a wide node (the meta byte encodes the count
// in unary in its top three bits). The TLAS uses one instance per slot.
constexpr uint32_t kWideMaxLeafPrims = 3;
// meta byte of an interior child: unary count 1, bit index 24 + slot.
constexpr uint32_t kWideMetaInterior = 1u << 5;

// Wide node: up to 8 children. Interior children are stored contiguously from
// child_base in slot order (child node = child_base + number of interior
// slots before it, from imask). Leaf children reference primitives
// prim_base + (meta & 31) onwards in bvh_wide_prim_indices, (meta >> 5) in
// unary (1, 3 or 7 for 1, 2 or 3 primitives). meta == 0: empty slot.
// Child box planes: origin + q * 2^(exponent - 127) per axis; the builder
// rounds so that the decoded box, evaluated in float exactly as the
// traversal does, always contains the child.
// Slot s holds the child nearest for rays whose direction octant is s, so
// visiting slots in the order (slot ^ octant) is roughly front to back.
struct alignas(16) KWideBvhNode {
  Vec3 origin;
  uint8_t exponent[3];  // biased like a float exponent: scale = uint_as_float(e << 23)
  uint8_t imask;        // bit s: slot s is an interior node
  uint32_t child_base;
  uint32_t prim_base;
  uint8_t meta[8];
  uint8_t qlo[3][8];  // [axis][slot]
  uint8_t qhi[3][8];
};
static_assert(sizeof(KWideBvhNode) == 80 && alignof(KWideBvhNode) == 16, "GPU layout");

TANDEM_HD float wide_node_scale(const KWideBvhNode& n, int axis) {
  return uint_as_float(uint32_t(n.exponent[axis]) << 23);
}

TANDEM_KERNEL_END
}  // namespace tandem
