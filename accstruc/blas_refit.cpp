#include "accstruc/blas_refit.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "accstruc/blas_refit_entries.h"
#include "accstruc/wide_bvh.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tandem {

using namespace blas_refit_entries;

namespace {

// The boxes of a node (c0_xy, c1_xy, c01_z): the only bytes a refit changes.
constexpr size_t kBinaryBoxBytes = 3 * sizeof(Vec4);
// Nodes the sweep prefetches ahead (a node's work is a few dozen ns).
constexpr uint32_t kNodesAhead = 12;

// The box triangle_boxes() gives the triangle, and whether aabb_valid()
// holds for it: every coordinate finite and within kMaxCoordinate.
inline bool triangle_box(const Vec3& a, const Vec3& c, const Vec3& d, Aabb& b) {
  b = Aabb{};
  b.grow(a);
  b.grow(c);
  b.grow(d);
  const float m = kMaxCoordinate;
  const auto ok = [m](const Vec3& q) {
    return (int(std::fabs(q.x) <= m) & int(std::fabs(q.y) <= m) & int(std::fabs(q.z) <= m)) != 0;
  };
  return (int(ok(a)) & int(ok(c)) & int(ok(d))) != 0;
}
inline bool triangle_box(const Vec3* p, const uint32_t* v, Aabb& b) {
  return triangle_box(p[v[0]], p[v[1]], p[v[2]], b);
}

// The record's vertices (xyz of p0, p1, p2) set to the triangle's current
// ones, the rest (the triangle index in p0.w, the zeros) kept as the
// records' writer put them: true when that changed the record (bit for bit).
#if defined(__SSE2__)
// In registers: built field by field in memory and compared with memcmp,
// the new record was read back right after its scalar stores (a store
// forwarding stall per 16 bytes), a fifth of a deforming mesh's refit.
// update_leaf_record4 takes the vertices as 16-byte loads (w: whatever
// follows the vertex; the record keeps its own w).
inline bool update_leaf_record4(KLeafTriangle& r, __m128 a, __m128 b, __m128 c) {
  float* f = &r.p0.x;
  const __m128 xyz = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
  const __m128 o0 = _mm_load_ps(f), o1 = _mm_load_ps(f + 4), o2 = _mm_load_ps(f + 8);
  const __m128 n0 = _mm_or_ps(_mm_and_ps(xyz, a), _mm_andnot_ps(xyz, o0));
  const __m128 n1 = _mm_or_ps(_mm_and_ps(xyz, b), _mm_andnot_ps(xyz, o1));
  const __m128 n2 = _mm_or_ps(_mm_and_ps(xyz, c), _mm_andnot_ps(xyz, o2));
  const __m128i same =
      _mm_and_si128(_mm_and_si128(_mm_cmpeq_epi32(_mm_castps_si128(n0), _mm_castps_si128(o0)),
                                  _mm_cmpeq_epi32(_mm_castps_si128(n1), _mm_castps_si128(o1))),
                    _mm_cmpeq_epi32(_mm_castps_si128(n2), _mm_castps_si128(o2)));
  if (_mm_movemask_epi8(same) == 0xffff) return false;
  _mm_store_ps(f, n0);
  _mm_store_ps(f + 4, n1);
  _mm_store_ps(f + 8, n2);
  return true;
}
inline bool update_leaf_record(KLeafTriangle& r, const Vec3& a, const Vec3& b, const Vec3& c) {
  return update_leaf_record4(r, _mm_setr_ps(a.x, a.y, a.z, 0.0f), _mm_setr_ps(b.x, b.y, b.z, 0.0f),
                             _mm_setr_ps(c.x, c.y, c.z, 0.0f));
}
// A triangle's box as two registers (xyz, w unused), the same unions as
// Aabb::grow() lane by lane (min_f / max_f are minps / maxps with the same
// operand order): bit for bit triangle_box()'s.
struct alignas(16) Box4 {
  __m128 lo, hi;
};
inline __m128 empty_lo() {
  return _mm_set1_ps(kFloatMax);
}
inline __m128 empty_hi() {
  return _mm_set1_ps(-kFloatMax);
}
// Per lane: |p| <= kMaxCoordinate (false for NaN and infinity), the test
// aabb_valid() makes of a box's corners.
inline __m128 within_limits(__m128 p) {
  const __m128 abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  return _mm_cmple_ps(_mm_and_ps(p, abs), _mm_set1_ps(kMaxCoordinate));
}
// The triangle's box from three 16-byte vertex loads (xyz + the next
// float); false where a coordinate is not finite or beyond kMaxCoordinate.
inline bool triangle_box4(__m128 a, __m128 b, __m128 c, Box4& out) {
  out.lo = _mm_min_ps(_mm_min_ps(_mm_min_ps(empty_lo(), a), b), c);
  out.hi = _mm_max_ps(_mm_max_ps(_mm_max_ps(empty_hi(), a), b), c);
  const __m128 ok = _mm_and_ps(_mm_and_ps(within_limits(a), within_limits(b)), within_limits(c));
  return (_mm_movemask_ps(ok) & 7) == 7;
}
inline Aabb to_aabb(const Box4& b) {
  alignas(16) float lo[4], hi[4];
  _mm_store_ps(lo, b.lo);
  _mm_store_ps(hi, b.hi);
  return Aabb{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
}
inline Box4 to_box4(const Aabb& b) {
  return {_mm_setr_ps(b.lo.x, b.lo.y, b.lo.z, 0.0f), _mm_setr_ps(b.hi.x, b.hi.y, b.hi.z, 0.0f)};
}
// A child's box in a binary node's form: xy = (lo.x, hi.x, lo.y, hi.y), z =
// (lo.z, hi.z) in lanes 0 and 1.
struct NodeBox {
  __m128 xy, z;
};
inline NodeBox node_box(const Box4& b) {
  return {_mm_unpacklo_ps(b.lo, b.hi), _mm_unpackhi_ps(b.lo, b.hi)};
}
// The union of both child boxes of `n` (binary_child_box(n, 0) grown by
// binary_child_box(n, 1)): lo lanes min, hi lanes max.
inline NodeBox node_union(const KBvhNode& n) {
  const __m128 c0 = _mm_load_ps(&n.c0_xy.x), c1 = _mm_load_ps(&n.c1_xy.x);
  const __m128 z = _mm_load_ps(&n.c01_z.x);
  const __m128 zs = _mm_shuffle_ps(z, z, _MM_SHUFFLE(1, 0, 3, 2));
  const __m128 lo_lanes = _mm_castsi128_ps(_mm_setr_epi32(-1, 0, -1, 0));
  const __m128 xy = _mm_or_ps(_mm_and_ps(lo_lanes, _mm_min_ps(c0, c1)),
                              _mm_andnot_ps(lo_lanes, _mm_max_ps(c0, c1)));
  const __m128 zz = _mm_or_ps(_mm_and_ps(lo_lanes, _mm_min_ps(z, zs)),
                              _mm_andnot_ps(lo_lanes, _mm_max_ps(z, zs)));
  return {xy, zz};
}
// double(a.half_area()) + double(b.half_area()) of a node's two child
// boxes, both at once: lane k the same float operations as Aabb::half_area()
// on child k (extent, then (x * y + y * z) + z * x, 0 for an empty box), then
// the two widened and added. The scalar pair, each box stored to memory
// first and with empty()'s branches, and the sum after it held about half
// of the node sweep's samples.
inline double node_boxes_half_area(const NodeBox& b0, const NodeBox& b1) {
  const __m128 lo_xy = _mm_shuffle_ps(b0.xy, b1.xy, _MM_SHUFFLE(2, 0, 2, 0));  // lx0 ly0 lx1 ly1
  const __m128 hi_xy = _mm_shuffle_ps(b0.xy, b1.xy, _MM_SHUFFLE(3, 1, 3, 1));  // hx0 hy0 hx1 hy1
  const __m128 z = _mm_movelh_ps(b0.z, b1.z);                                  // lz0 hz0 lz1 hz1
  const __m128 lo_z = _mm_shuffle_ps(z, z, _MM_SHUFFLE(2, 0, 2, 0));           // lz0 lz1 ..
  const __m128 hi_z = _mm_shuffle_ps(z, z, _MM_SHUFFLE(3, 1, 3, 1));           // hz0 hz1 ..
  const __m128 e_xy = _mm_sub_ps(hi_xy, lo_xy);                                // ex0 ey0 ex1 ey1
  const __m128 ex = _mm_shuffle_ps(e_xy, e_xy, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 ey = _mm_shuffle_ps(e_xy, e_xy, _MM_SHUFFLE(3, 1, 3, 1));
  const __m128 ez = _mm_sub_ps(hi_z, lo_z);
  const __m128 area =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(ex, ey), _mm_mul_ps(ey, ez)), _mm_mul_ps(ez, ex));
  // Not empty: lo <= hi on every axis (false for a NaN, as in empty()).
  const __m128 ok_xy = _mm_cmple_ps(lo_xy, hi_xy);
  const __m128 ok = _mm_and_ps(_mm_and_ps(_mm_shuffle_ps(ok_xy, ok_xy, _MM_SHUFFLE(2, 0, 2, 0)),
                                          _mm_shuffle_ps(ok_xy, ok_xy, _MM_SHUFFLE(3, 1, 3, 1))),
                               _mm_cmple_ps(lo_z, hi_z));
  const __m128d d = _mm_cvtps_pd(_mm_and_ps(ok, area));
  return _mm_cvtsd_f64(_mm_add_sd(d, _mm_unpackhi_pd(d, d)));
}
using TaskBox = Box4;
inline Aabb as_aabb(const Box4& b) {
  return to_aabb(b);
}
#else
using TaskBox = Aabb;
inline const Aabb& as_aabb(const Aabb& b) {
  return b;
}
inline bool update_leaf_record(KLeafTriangle& r, const Vec3& a, const Vec3& b, const Vec3& c) {
  KLeafTriangle n = r;
  n.p0.x = a.x;
  n.p0.y = a.y;
  n.p0.z = a.z;
  n.p1.x = b.x;
  n.p1.y = b.y;
  n.p1.z = b.z;
  n.p2.x = c.x;
  n.p2.y = c.y;
  n.p2.z = c.z;
  if (std::memcmp(&n, &r, sizeof n) == 0) return false;
  r = n;
  return true;
}
#endif

}  // namespace

BlasRefit::Result BlasRefit::refit(BvhLayouts& l, const MeshGeometry& g, const LayoutBases& bases,
                                   KBvhNode* nodes, KWideBvhNode* wide_nodes,
                                   KLeafTriangle* leaf_triangles, bool overwrite_records) const {
  Result result;
  if (!indexed_ || g.vertex_count != vertex_count_ || g.triangle_count != triangle_count_) {
    result.members_changed = true;
    return result;
  }
  struct Out {
    uint32_t lo = kNone, hi = 0, wide_lo = kNone, wide_hi = 0, leaf_lo = kNone, leaf_hi = 0;
    double area = 0.0;
    bool invalid = false;
  };
  const Vec3* positions = g.positions;
  const uint32_t* tris = leaf_tris_.data();
  // Records [lo, hi) were rewritten: the range the caller uploads grows.
  const auto records_changed = [](Out& o, uint32_t lo, uint32_t hi) {
    o.leaf_lo = std::min(o.leaf_lo, lo);
    o.leaf_hi = std::max(o.leaf_hi, hi);
  };

  // The triangle boxes of the leaf entries [lo, hi) of the task being
  // swept, from its leaf pass; boxes == null outside a task. per_leaf: only
  // the union of each binary leaf, at the index of its first entry.
  struct TaskBoxes {
    const TaskBox* boxes = nullptr;
    uint32_t lo = 0, hi = 0;
    bool per_leaf = false;
  };
  // Without wide nodes to re-quantise (whose slots may hold part of a binary
  // leaf), the leaf pass keeps one box per binary leaf, not per triangle:
  // the sweep then reads one 32-byte box a leaf, not two on average.
#if defined(__SSE2__)
  const bool per_leaf = wide_nodes == nullptr;
  const bool by_vertex = per_leaf && leaf_triangles == nullptr && vertex_lists_;
#else
  const bool per_leaf = false;
#endif
  const auto leaf_box = [&](uint32_t first, uint32_t count, const TaskBoxes& tb, Out& o) {
    Aabb box;
    if (tb.boxes != nullptr && !tb.per_leaf && first >= tb.lo && first + count <= tb.hi) {
      // Invalid triangles were flagged (and left empty) by the leaf pass.
      for (uint32_t e = first; e < first + count; ++e)
        box.grow(as_aabb(tb.boxes[e - tb.lo]));
      return box;
    }
    for (uint32_t e = first; e < first + count; ++e) {
      Aabb t;
      if (triangle_box(positions, tris + kEntryWords * size_t(e), t)) {
        box.grow(t);
      } else {
        o.invalid = true;
      }
    }
    return box;
  };
  // leaf_box() of a binary leaf above the tasks, rewriting its records from
  // the vertices it reads anyway.
  const auto leaf_box_and_records = [&](uint32_t first, uint32_t count, Out& o) {
    Aabb box;
    for (uint32_t e = first; e < first + count; ++e) {
      const uint32_t* v = tris + kEntryWords * size_t(e);
      const Vec3 a = positions[v[0]], b = positions[v[1]], c = positions[v[2]];
      Aabb t;
      if (triangle_box(a, b, c, t)) {
        box.grow(t);
      } else {
        o.invalid = true;
      }
      if (update_leaf_record(leaf_triangles[e], a, b, c)) {
        records_changed(o, e, e + 1);
      }
    }
    return box;
  };
  // A task's leaf pass: every leaf entry of its subtree front to back (the
  // order the leaf indices and records lie in memory), its triangle box
  // into `out` (or, per_leaf, each binary leaf's union) and its record
  // rewritten. The node sweep that follows walks the nodes backwards and
  // would meet the leaves in reverse, out of the reach of the hardware
  // prefetcher, with every vertex load a cache miss waited for; here the
  // vertices a few triangles ahead are prefetched.
  const auto leaf_pass = [&](const Task& task, TaskBox* out, Out& o) {
    constexpr uint32_t kAhead = 32;  // triangles: a few hundred ns of work
#if defined(__SSE2__)
    // The vertex indices themselves (a stream the vertex prefetches below
    // wait on): a few cache lines further ahead.
    constexpr uint32_t kIndicesAhead = 4 * kAhead;
    // In registers: the vertices' 16-byte loads (positions have a readable
    // element past the last vertex) give the box and the record's xyz.
    const __m128 xyz = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
    // The triangle's index without kLastOfLeaf.
    const __m128 index_bits = _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, int(~kLastOfLeaf)));
    bool changed = false;
    // per_leaf: the union of the current binary leaf's triangles so far (in
    // entry order, as the sweep's union of per-triangle boxes was), and its
    // first entry.
    Box4 leaf{empty_lo(), empty_hi()};
    // Locals, not the captures: every SSE store may alias anything (__m128
    // is may_alias), so each use of a captured reference was a reload
    // through the closure, a dozen loads a triangle.
    const uint32_t* const entries = tris;
    const Vec3* const verts = positions;
    KLeafTriangle* const records = leaf_triangles;
    const bool overwrite = overwrite_records, leaves_only = per_leaf;
    const uint32_t lo = task.leaf_lo, hi = task.leaf_hi;
    bool invalid = false;
    uint32_t leaf_first = lo;
    for (uint32_t e = lo; e < hi; ++e) {
      if (e + kAhead < hi) {
        const uint32_t* f = entries + kEntryWords * size_t(e + kAhead);
        __builtin_prefetch(verts + f[0]);
        __builtin_prefetch(verts + f[1]);
        __builtin_prefetch(verts + f[2]);
        if ((e & 3u) == 0 && e + kIndicesAhead < hi)
          __builtin_prefetch(entries + kEntryWords * size_t(e + kIndicesAhead));
      }
      const __m128i v =
          _mm_load_si128(reinterpret_cast<const __m128i*>(entries + kEntryWords * size_t(e)));
      const uint32_t i0 = uint32_t(_mm_cvtsi128_si32(v));
      const uint32_t i1 = uint32_t(_mm_cvtsi128_si32(_mm_shuffle_epi32(v, 0x55)));
      const uint32_t i2 = uint32_t(_mm_cvtsi128_si32(_mm_shuffle_epi32(v, 0xaa)));
      const float* pf = &verts[0].x;
      const __m128 a = _mm_loadu_ps(pf + 3 * size_t(i0)), b = _mm_loadu_ps(pf + 3 * size_t(i1)),
                   c = _mm_loadu_ps(pf + 3 * size_t(i2));
      Box4 t;
      if (!triangle_box4(a, b, c, t)) {
        invalid = true;
        t = {empty_lo(), empty_hi()};  // leaves the union as it is, like a skipped triangle
      }
      if (!leaves_only) {
        out[e - lo] = t;
      } else {
        leaf.lo = _mm_min_ps(leaf.lo, t.lo);
        leaf.hi = _mm_max_ps(leaf.hi, t.hi);
        if (_mm_movemask_ps(_mm_castsi128_ps(v)) & 8) {  // kLastOfLeaf
          out[leaf_first - lo] = leaf;
          leaf = {empty_lo(), empty_hi()};
          leaf_first = e + 1;
        }
      }
      if (records == nullptr) continue;
      float* r = &records[e].p0.x;
      if (overwrite) {
        // Every vertex of the mesh moved: the record is written without
        // reading the old one, past the caches (no read for ownership), 96
        // of the 192 MB a frame of a million-vertex mesh's records moved.
        const __m128 w0 = _mm_and_ps(index_bits, _mm_castsi128_ps(v));  // the triangle's index
        _mm_stream_ps(r, _mm_or_ps(_mm_and_ps(xyz, a), w0));
        _mm_stream_ps(r + 4, _mm_and_ps(xyz, b));
        _mm_stream_ps(r + 8, _mm_and_ps(xyz, c));
        changed = true;
      } else if (update_leaf_record4(records[e], a, b, c)) {
        records_changed(o, e, e + 1);
      }
    }
    if (invalid) o.invalid = true;
    if (changed) {
      _mm_sfence();
      records_changed(o, task.leaf_lo, task.leaf_hi);
    }
#else
    (void)overwrite_records;
    const auto prefetch_vertices = [&](uint32_t e) {
      const uint32_t* f = tris + kEntryWords * size_t(e);
      __builtin_prefetch(positions + f[0]);
      __builtin_prefetch(positions + f[1]);
      __builtin_prefetch(positions + f[2]);
    };
    for (uint32_t e = task.leaf_lo; e < task.leaf_hi; ++e) {
      if (e + kAhead < task.leaf_hi) prefetch_vertices(e + kAhead);
      const uint32_t* v = tris + kEntryWords * size_t(e);
      const Vec3 a = positions[v[0]], b = positions[v[1]], c = positions[v[2]];
      Aabb t;
      if (!triangle_box(a, b, c, t)) {
        o.invalid = true;
        t = Aabb{};  // leaves the union as it is, like a skipped triangle
      }
      out[e - task.leaf_lo] = t;
      if (leaf_triangles != nullptr && update_leaf_record(leaf_triangles[e], a, b, c)) {
        records_changed(o, e, e + 1);
      }
    }
#endif
  };

#if defined(__SSE2__)
  // The leaf pass when only each binary leaf's box is wanted (per_leaf) and
  // no records are written (a mesh that deforms whole): the box of a leaf's
  // distinct vertices, each loaded once, four at a time, instead of its
  // triangles' boxes (a grid's leaf of eight triangles: 9 vertex loads, not
  // 24, through 4-byte indices, not 16-byte entries). The same bits: minps /
  // maxps return the second operand of equal inputs (+0 and -0), so a
  // union's zero is the last one met; the list keeps the vertices in the
  // order of their last use by the leaf's triangles, which meets the same
  // one last. The prefetch distance made no measurable difference. A vertex
  // that is not finite or beyond kMaxCoordinate asks for a rebuild, as its
  // triangle's box does in leaf_pass (then the boxes do not matter).
  const auto leaf_pass_by_vertex = [&](const Task& task, TaskBox* out, Out& o) {
    constexpr uint32_t kAhead = 192;  // vertices
    const uint32_t* const list = leaf_verts_.data();
    const LeafSize* const sizes = leaf_sizes_.data();
    const float* const pf = &positions[0].x;
    const uint32_t listed = uint32_t(leaf_verts_.size());
    __m128 ok = _mm_castsi128_ps(_mm_set1_epi32(-1));
    uint32_t j = task.verts_lo, e = task.leaf_lo;
    for (uint32_t k = task.leaves_lo; k < task.leaves_hi; ++k) {
      __m128 lo = empty_lo(), hi = empty_hi();
      for (uint32_t g = sizes[k].groups; g > 0; --g, j += 4) {
        if (j + kAhead < listed) {
          for (uint32_t q = 0; q < 4; ++q)
            __builtin_prefetch(pf + 3 * size_t(list[j + kAhead + q]));
        }
        const __m128 p0 = _mm_loadu_ps(pf + 3 * size_t(list[j]));
        const __m128 p1 = _mm_loadu_ps(pf + 3 * size_t(list[j + 1]));
        const __m128 p2 = _mm_loadu_ps(pf + 3 * size_t(list[j + 2]));
        const __m128 p3 = _mm_loadu_ps(pf + 3 * size_t(list[j + 3]));
        // A tree of minps / maxps in list order: of equal inputs each keeps
        // its second, the later one, as a chain in list order would.
        lo = _mm_min_ps(lo, _mm_min_ps(_mm_min_ps(p0, p1), _mm_min_ps(p2, p3)));
        hi = _mm_max_ps(hi, _mm_max_ps(_mm_max_ps(p0, p1), _mm_max_ps(p2, p3)));
        ok = _mm_and_ps(ok, _mm_and_ps(_mm_and_ps(within_limits(p0), within_limits(p1)),
                                       _mm_and_ps(within_limits(p2), within_limits(p3))));
      }
      out[e - task.leaf_lo] = {lo, hi};
      e += sizes[k].triangles;
    }
    if ((_mm_movemask_ps(ok) & 7) != 7) o.invalid = true;
  };
#endif

  // Child references in the kernel arrays include the bases.
#if defined(__SSE2__)
  // A child's box in node form, inside a task: a leaf's from the leaf
  // pass's boxes (the same unions as leaf_box()).
  const auto leaf_node_box = [&](uint32_t first, uint32_t count, const TaskBoxes& tb, Out& o) {
    if (first < tb.lo || first + count > tb.hi)
      return node_box(to_box4(leaf_box(first, count, tb, o)));
    const Box4* b = tb.boxes + (first - tb.lo);
    if (tb.per_leaf) return node_box(count > 0 ? *b : Box4{empty_lo(), empty_hi()});
    Box4 u{empty_lo(), empty_hi()};
    for (const Box4* end = b + count; b < end; ++b) {
      u.lo = _mm_min_ps(u.lo, b->lo);
      u.hi = _mm_max_ps(u.hi, b->hi);
    }
    return node_box(u);
  };
  // refit_node() inside a task, in registers: the same unions (lane by lane
  // minps / maxps in Aabb::grow()'s operand order), area and compare. The
  // area it adds is returned, not summed into `o`: `o` lives in memory (the
  // out-of-line leaf_box() takes it), and the running sum through it was a
  // store-to-load chain a node.
  const auto refit_node_sse = [&](uint32_t i, const TaskBoxes& tb, Out& o) {
    KBvhNode& node = nodes[i];
    NodeBox box[2];
    for (uint32_t c = 0; c < 2; ++c) {
      const uint32_t ref = node.child[c];
      if (ref & kBvhLeafFlag) {
        box[c] = leaf_node_box((ref & ~kBvhLeafFlag) - bases.prim, node.count[c], tb, o);
      } else {
        // Refit before its parent (larger index), so exact already.
        box[c] = node_union(nodes[ref - bases.node]);
      }
    }
    const double area = node_boxes_half_area(box[0], box[1]);
    float* f = &node.c0_xy.x;
    const __m128 z = _mm_movelh_ps(box[0].z, box[1].z);
    const __m128i same = _mm_and_si128(
        _mm_and_si128(_mm_cmpeq_epi32(_mm_castps_si128(box[0].xy),
                                      _mm_load_si128(reinterpret_cast<const __m128i*>(f))),
                      _mm_cmpeq_epi32(_mm_castps_si128(box[1].xy),
                                      _mm_load_si128(reinterpret_cast<const __m128i*>(f + 4)))),
        _mm_cmpeq_epi32(_mm_castps_si128(z),
                        _mm_load_si128(reinterpret_cast<const __m128i*>(f + 8))));
    if (_mm_movemask_epi8(same) == 0xffff) return area;
    _mm_store_ps(f, box[0].xy);
    _mm_store_ps(f + 4, box[1].xy);
    _mm_store_ps(f + 8, z);
    o.lo = std::min(o.lo, i);
    o.hi = std::max(o.hi, i + 1);
    return area;
  };
#endif
  const auto refit_node = [&](uint32_t i, const TaskBoxes& tb, Out& o) {
    KBvhNode& node = nodes[i];
    Aabb box[2];
    for (uint32_t c = 0; c < 2; ++c) {
      const uint32_t ref = node.child[c];
      if (ref & kBvhLeafFlag) {
        const uint32_t first = (ref & ~kBvhLeafFlag) - bases.prim;
        box[c] = leaf_triangles && tb.boxes == nullptr
                     ? leaf_box_and_records(first, node.count[c], o)
                     : leaf_box(first, node.count[c], tb, o);
      } else {
        // Refit before its parent (larger index), so exact already.
        const KBvhNode& child = nodes[ref - bases.node];
        box[c] = binary_child_box(child, 0);
        box[c].grow(binary_child_box(child, 1));
      }
    }
    o.area += double(box[0].half_area()) + double(box[1].half_area());
    KBvhNode updated = node;
    set_binary_child_box(updated, 0, box[0]);
    set_binary_child_box(updated, 1, box[1]);
    if (std::memcmp(&updated, &node, kBinaryBoxBytes) == 0) return;
    // Only the boxes: the line is in the cache (just read), and the parent
    // reads these boxes back soon.
    std::memcpy(&node, &updated, kBinaryBoxBytes);
    o.lo = std::min(o.lo, i);
    o.hi = std::max(o.hi, i + 1);
  };

  const auto requantize = [&](uint32_t w, const TaskBoxes& tb, Out& o) {
    KWideBvhNode& node = wide_nodes[w];
    Aabb boxes[kWideBvhWidth];
    uint32_t used = 0;
    const uint32_t* src = wide_src_.data() + size_t(kWideBvhWidth) * w;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t kind = src[s] & kSlotKind, at = src[s] & kSlotIndex;
      if (kind == kSlotEmpty) continue;
      used |= 1u << s;
      if (kind == kSlotNode) {
        boxes[s] = binary_child_box(nodes[at >> 1], at & 1u);
      } else {
        boxes[s] = leaf_box(at, wide_leaf_count(node.meta[s]), tb, o);
      }
    }
    // quantize_wide_node() sets only the boxes (origin, exponents, planes).
    KWideBvhNode updated = node;
    quantize_wide_node(updated, boxes, used);
    if (std::memcmp(&updated, &node, sizeof(KWideBvhNode)) == 0) return;
    node = updated;
    o.wide_lo = std::min(o.wide_lo, w);
    o.wide_hi = std::max(o.wide_hi, w + 1);
  };

  std::vector<Out> outs(tasks_.size() + 1);
  tbb::parallel_for(size_t(0), tasks_.size(), [&](size_t t) {
    const Task& task = tasks_[t];
    // A local, not outs[t]: the node writes could alias a reference, which
    // kept the running area sum in memory, one dependent load and store a node.
    Out o;
    // Per worker thread, reused: a task's boxes stay in its core's L2
    // between the two passes (a few hundred KB at most).
    static thread_local std::vector<TaskBox> task_boxes;
    if (task_boxes.size() < task.leaf_hi - task.leaf_lo)
      task_boxes.resize(task.leaf_hi - task.leaf_lo);
#if defined(__SSE2__)
    if (by_vertex) {
      leaf_pass_by_vertex(task, task_boxes.data(), o);
    } else {
      leaf_pass(task, task_boxes.data(), o);
    }
#else
    leaf_pass(task, task_boxes.data(), o);
#endif
    const TaskBoxes tb{task_boxes.data(), task.leaf_lo, task.leaf_hi, per_leaf};
#if defined(__SSE2__)
    double area = 0.0;  // in a register: o.area is in memory (refit_node_sse)
#endif
    uint32_t next = task.wide_lo;
    for (uint32_t i = task.hi; i-- > task.lo;) {
      // The sweep walks the nodes backwards, which the hardware prefetcher
      // follows poorly: a quarter of the refit's samples waited on the
      // node's first load.
      if (i >= task.lo + kNodesAhead) __builtin_prefetch(nodes + (i - kNodesAhead), 1);
#if defined(__SSE2__)
      area += refit_node_sse(i, tb, o);
#else
      refit_node(i, tb, o);
#endif
      if (!wide_nodes) continue;
      for (; next < task.wide_hi && anchored_[next].anchor >= i; ++next)
        requantize(anchored_[next].wide, tb, o);
    }
#if defined(__SSE2__)
    o.area += area;
#endif
    outs[t] = o;
  });
  Out& top = outs.back();
  const TaskBoxes none;
  for (uint32_t i : top_)
    refit_node(i, none, top);
  if (wide_nodes) {
    for (uint32_t w : wide_deferred_)
      requantize(w, none, top);
  }

  // In task order, then the top: the same sum whatever ran where.
  double area = 0.0;
  Out all;
  for (const Out& o : outs) {
    area += o.area;
    all.lo = std::min(all.lo, o.lo);
    all.hi = std::max(all.hi, o.hi);
    all.wide_lo = std::min(all.wide_lo, o.wide_lo);
    all.wide_hi = std::max(all.wide_hi, o.wide_hi);
    all.invalid = all.invalid || o.invalid;
  }
  // Tasks hold disjoint leaf ranges; the top's span (leaves of the nodes
  // above the tasks) may cover some of them, which a mark merges.
  std::vector<NodeSpan>& leaves = result.leaf_spans;
  for (const Out& o : outs) {
    if (o.leaf_hi > 0) leaves.push_back({o.leaf_lo, o.leaf_hi});
  }
  std::sort(leaves.begin(), leaves.end(),
            [](const NodeSpan& a, const NodeSpan& b) { return a.begin < b.begin; });
  for (uint32_t t : non_members_) {
    const KTriangle& tri = g.triangles[t];
    const uint32_t v[3] = {tri.v0, tri.v1, tri.v2};
    Aabb box;
    if (v[0] < g.vertex_count && v[1] < g.vertex_count && v[2] < g.vertex_count &&
        triangle_box(positions, v, box)) {
      all.invalid = true;
      break;
    }
  }
  l.bounds = binary_child_box(nodes[0], 0);
  l.bounds.grow(binary_child_box(nodes[0], 1));
  const double root = l.bounds.half_area();
  result.members_changed = all.invalid;
  result.quality = root > 0.0 ? area / root : 0.0;
  if (all.hi > 0) result.spans.nodes = {all.lo, all.hi};
  if (all.wide_hi > 0) result.spans.wide_nodes = {all.wide_lo, all.wide_hi};
  return result;
}

void BlasRefit::copy_boxes_to_host(BvhLayouts& l, const KBvhNode* nodes,
                                   const KWideBvhNode* wide_nodes) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, l.nodes.size(), 16384), [&](auto r) {
    for (size_t i = r.begin(); i < r.end(); ++i)
      std::memcpy(&l.nodes[i], &nodes[i], kBinaryBoxBytes);
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, l.wide_nodes.size(), 16384), [&](auto r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      KWideBvhNode& h = l.wide_nodes[i];
      const KWideBvhNode& k = wide_nodes[i];
      h.origin = k.origin;
      std::memcpy(h.exponent, k.exponent, sizeof h.exponent);
      std::memcpy(h.qlo, k.qlo, sizeof h.qlo);
      std::memcpy(h.qhi, k.qhi, sizeof h.qhi);
    }
  });
}

}  // namespace tandem
