// Host-only traversal of the binary layout (and of the wide layout in
// distance order, at the end of this file): the same tree, the same visiting
// order and the same hits as trace_two_level_binary (bit for bit, which of
// two equal-t hits wins included), written for a CPU instead of for GPU
// registers. Included by bvh_traverse.h in translation units that nvcc does
// not compile (the CPU backends, the host backend's kernels, the bench).
//
// What differs from the portable loop, and why it changes nothing found:
//   - Both child boxes of a node are tested in one set of SSE operations.
//     Every lane does the portable test's float operations in the same
//     order, and _mm_max_ps / _mm_min_ps return their second operand on a
//     NaN just as the portable "candidate beats current ? candidate :
//     current" does, so entry distances and hit flags are the same bits.
//   - A node waiting on the stack keeps the distance at which the ray enters
//     its box, and is dropped when a hit found since is nearer than that
//     (the portable loop visits it and then misses both of its children).
//     Its box test with the shrunken interval would fail, and the boxes
//     below it lie inside it, so no triangle under it could be hit closer:
//     only a node visit (a dependent cache miss on the large scenes) is
//     saved.
//   - A loop per level: the host has no register budget to protect, and the
//     BLAS loop keeps its own small stack.
#pragma once

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/kernel/bvh_leaf_host.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// A node waiting on the host stack and the distance its box is entered at.
struct HostBvhStackEntry {
  uint32_t node;
  float t_entry;
};

#if defined(__SSE2__)

// Per-ray constants of the two-box test, lane for lane as host_box_test2
// arranges the planes.
struct HostBoxRay {
  __m128 origin_xy, inv_xy;  // (o.x, o.x, o.y, o.y), (1/d.x, 1/d.x, 1/d.y, 1/d.y)
  __m128 origin_z, inv_z;    // broadcast
  __m128 neg_xy;             // all ones in lanes (x, y, x, y) whose direction is negative
  __m128 neg_z;              // all ones when d.z is negative
};

inline __m128 host_lane_mask(bool on) {
  return _mm_castsi128_ps(_mm_set1_epi32(on ? -1 : 0));
}

inline HostBoxRay make_host_box_ray(const BoxRay& r) {
  HostBoxRay h;
  h.origin_xy = _mm_setr_ps(r.origin.x, r.origin.x, r.origin.y, r.origin.y);
  h.inv_xy = _mm_setr_ps(r.inv_dir.x, r.inv_dir.x, r.inv_dir.y, r.inv_dir.y);
  h.origin_z = _mm_set1_ps(r.origin.z);
  h.inv_z = _mm_set1_ps(r.inv_dir.z);
  const bool nx = (r.octant & 1u) != 0, ny = (r.octant & 2u) != 0;
  h.neg_xy = _mm_castsi128_ps(_mm_setr_epi32(nx ? -1 : 0, ny ? -1 : 0, nx ? -1 : 0, ny ? -1 : 0));
  h.neg_z = host_lane_mask((r.octant & 4u) != 0);
  return h;
}

inline __m128 host_select(__m128 mask, __m128 if_set, __m128 if_clear) {
  return _mm_or_ps(_mm_and_ps(mask, if_set), _mm_andnot_ps(mask, if_clear));
}

// intersect_box() on both children of a binary node. Returns bit c set for
// each child hit and its entry distance in t_entry[c].
inline uint32_t host_box_test2(const HostBoxRay& r, const KBvhNode& n, float tmin, float tmax,
                               float t_entry[2]) {
  const __m128 c0 = _mm_load_ps(&n.c0_xy.x);  // lo0.x hi0.x lo0.y hi0.y
  const __m128 c1 = _mm_load_ps(&n.c1_xy.x);
  const __m128 cz = _mm_load_ps(&n.c01_z.x);  // lo0.z hi0.z lo1.z hi1.z
  const __m128 t0 = _mm_mul_ps(_mm_sub_ps(c0, r.origin_xy), r.inv_xy);
  const __m128 t1 = _mm_mul_ps(_mm_sub_ps(c1, r.origin_xy), r.inv_xy);
  const __m128 tz = _mm_mul_ps(_mm_sub_ps(cz, r.origin_z), r.inv_z);
  // Lanes (child 0 x, child 0 y, child 1 x, child 1 y) and (child 0 z,
  // child 1 z, -, -).
  const __m128 lo_xy = _mm_shuffle_ps(t0, t1, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 hi_xy = _mm_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 1, 3, 1));
  const __m128 lo_z = _mm_shuffle_ps(tz, tz, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 hi_z = _mm_shuffle_ps(tz, tz, _MM_SHUFFLE(3, 1, 3, 1));
  const __m128 scale = _mm_set1_ps(kBoxFarScale);
  const __m128 near_xy = host_select(r.neg_xy, hi_xy, lo_xy);
  const __m128 far_xy = _mm_mul_ps(host_select(r.neg_xy, lo_xy, hi_xy), scale);
  const __m128 near_z = host_select(r.neg_z, hi_z, lo_z);
  const __m128 far_z = _mm_mul_ps(host_select(r.neg_z, lo_z, hi_z), scale);
  // Per child in lanes 0 and 1, in the portable test's order x, y, z.
  const __m128 near_x = _mm_shuffle_ps(near_xy, near_xy, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 near_y = _mm_shuffle_ps(near_xy, near_xy, _MM_SHUFFLE(3, 1, 3, 1));
  const __m128 far_x = _mm_shuffle_ps(far_xy, far_xy, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 far_y = _mm_shuffle_ps(far_xy, far_xy, _MM_SHUFFLE(3, 1, 3, 1));
  __m128 tn = _mm_set1_ps(tmin), tf = _mm_set1_ps(tmax);
  tn = _mm_max_ps(near_x, tn);
  tn = _mm_max_ps(near_y, tn);
  tn = _mm_max_ps(near_z, tn);
  tf = _mm_min_ps(far_x, tf);
  tf = _mm_min_ps(far_y, tf);
  tf = _mm_min_ps(far_z, tf);
  alignas(16) float tn_out[4];
  _mm_store_ps(tn_out, tn);
  t_entry[0] = tn_out[0];
  t_entry[1] = tn_out[1];
  return uint32_t(_mm_movemask_ps(_mm_cmple_ps(tn, tf))) & 3u;
}

#else

struct HostBoxRay {
  BoxRay box;
};
inline HostBoxRay make_host_box_ray(const BoxRay& r) {
  return HostBoxRay{r};
}
inline uint32_t host_box_test2(const HostBoxRay& r, const KBvhNode& n, float tmin, float tmax,
                               float t_entry[2]) {
  const bool h0 =
      intersect_box(r.box, make_vec3(n.c0_xy.x, n.c0_xy.z, n.c01_z.x),
                    make_vec3(n.c0_xy.y, n.c0_xy.w, n.c01_z.y), tmin, tmax, &t_entry[0]);
  const bool h1 =
      intersect_box(r.box, make_vec3(n.c1_xy.x, n.c1_xy.z, n.c01_z.z),
                    make_vec3(n.c1_xy.y, n.c1_xy.w, n.c01_z.w), tmin, tmax, &t_entry[1]);
  return (h0 ? 1u : 0u) | (h1 ? 2u : 0u);
}

#endif

// One node of the host loops: its box tests and counters. Returns the hit
// mask (bit c: child c).
template <bool kCount>
inline uint32_t host_visit_node(TwoLevelTrace<kCount>& tr, const HostBoxRay& hb, const KBvhNode& n,
                                bool in_blas, float t_entry[2]) {
  if constexpr (kCount) {
    tr.counters->nodes += 1;
    tr.counters->boxes += 2;
    if (in_blas) tr.counters->blas_nodes += 1;
  }
  return host_box_test2(hb, n, tr.tmin, tr.tmax, t_entry);
}

// The interior children among `inner` (hit mask): the nearer next, the
// other onto the stack; then the nearest waiting node still in front of the
// closest hit. Returns kInvalidIndex when the loop is done.
inline uint32_t host_next_node(const KBvhNode& n, uint32_t inner, const float t_entry[2],
                               float tmax, const KBvhNode* nodes, HostBvhStackEntry* stack,
                               uint32_t& sp) {
  uint32_t next = kInvalidIndex;
  float t_next = 0.0f;
  if (inner == 3u) {
    const bool swap = t_entry[1] < t_entry[0];
    const uint32_t near_c = swap ? 1u : 0u;
    next = n.child[near_c];
    t_next = t_entry[near_c];
    prefetch_readonly(nodes + n.child[near_c ^ 1u]);
    if (sp < kBvhStackSize) stack[sp++] = {n.child[near_c ^ 1u], t_entry[near_c ^ 1u]};
  } else if (inner != 0u) {
    const uint32_t c = inner == 1u ? 0u : 1u;
    next = n.child[c];
    t_next = t_entry[c];
  }
  if (next != kInvalidIndex && !(t_next > tmax)) return next;
  while (sp != 0) {
    const HostBvhStackEntry e = stack[--sp];
    if (!(e.t_entry > tmax)) return e.node;
  }
  return kInvalidIndex;
}

// The `count` triangles of a binary leaf from entry `first` of the current
// BLAS, in entry order, four at a time in SSE from their leaf records (the
// indexed path, for BLAS without records, one at a time). True: an any-hit
// query stopped.
template <bool kCount>
inline bool host_binary_leaf(TwoLevelTrace<kCount>& tr, uint32_t first, uint32_t count,
                             bool indexed, const uint32_t* record
#if defined(__SSE2__)
                             ,
                             const HostShear4& shear
#endif
) {
  uint32_t i = 0;
#if defined(__SSE2__)
  if (!indexed) {
    const KLeafTriangle* records = tr.kd->bvh_leaf_triangles + first;
    for (; i < count; i += 4) {
      const KLeafTriangle* rec[4];
      const uint32_t chunk = count - i < 4 ? count - i : 4;
      for (uint32_t k = 0; k < chunk; ++k)
        rec[k] = records + i + k;
      const int found = host_test_records4(tr, shear, rec, chunk, record);
      if (found > 0) return true;
      if (found < 0) break;  // this chunk and the rest one at a time
    }
  }
#else
  (void)indexed;
#endif
  for (; i < count; ++i) {
    if (tr.leaf_triangle(first + i, record)) return true;
  }
  return false;
}

// A BLAS from `root`, the ray already in its object space (tr.box), the
// instance record filled by enter_instance. True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_blas(TwoLevelTrace<kCount>& tr, const KBvhNode* nodes, uint32_t root,
                            const uint32_t* record) {
  const HostBoxRay hb = make_host_box_ray(tr.box);
  const bool indexed = (record[kRecordBlasFlags] & kBlasNoLeafRecords) != 0u;
#if defined(__SSE2__)
  const HostShear4 shear = make_host_shear4(tr.box, record);
#endif
  HostBvhStackEntry stack[kBvhStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KBvhNode& n = nodes[node_index];
    float t_entry[2];
    const uint32_t hits = host_visit_node(tr, hb, n, true, t_entry);
    const uint32_t leaf_bits = (n.child[0] >> 31) | ((n.child[1] >> 31) << 1);
    const uint32_t leaves = hits & leaf_bits;
    if (leaves != 0u) {
      if (leaves & 1u) tr.prefetch_leaf_triangles(n.child[0] & ~kBvhLeafFlag, n.count[0], record);
      if (leaves & 2u) tr.prefetch_leaf_triangles(n.child[1] & ~kBvhLeafFlag, n.count[1], record);
      for (uint32_t c = 0; c < 2; ++c) {
        if (!((leaves >> c) & 1u)) continue;
#if defined(__SSE2__)
        if (host_binary_leaf(tr, n.child[c] & ~kBvhLeafFlag, n.count[c], indexed, record, shear))
          return true;
#else
        if (host_binary_leaf(tr, n.child[c] & ~kBvhLeafFlag, n.count[c], indexed, record))
          return true;
#endif
      }
    }
    node_index = host_next_node(n, hits & ~leaf_bits, t_entry, tr.tmax, nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

// The TLAS from `root` in world space; the instances of a hit leaf are
// visited (each BLAS to its end) before the node's interior children, in
// entry order, as in trace_two_level_binary. True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_two_level_binary(TwoLevelTrace<kCount>& tr, const KBvhNode* nodes,
                                        uint32_t root) {
  const uint32_t* prim_indices = tr.kd->bvh_prim_indices;
  const HostBoxRay world = make_host_box_ray(tr.box);
  HostBvhStackEntry stack[kBvhStackSize];
  uint32_t record[kBvhInstanceRecordWords];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KBvhNode& n = nodes[node_index];
    float t_entry[2];
    const uint32_t hits = host_visit_node(tr, world, n, false, t_entry);
    const uint32_t leaf_bits = (n.child[0] >> 31) | ((n.child[1] >> 31) << 1);
    const uint32_t leaves = hits & leaf_bits;
    for (uint32_t c = 0; c < 2; ++c) {
      if (!((leaves >> c) & 1u)) continue;
      const uint32_t first = n.child[c] & ~kBvhLeafFlag;
      for (uint32_t i = 0; i < n.count[c]; ++i) {
        const uint32_t blas = tr.enter_instance(prim_indices[first + i], false, record);
        if (blas == kInvalidIndex) continue;
        const bool stop = host_trace_blas(tr, nodes, blas, record);
        tr.leave_instance(record);
        if (stop) return true;
      }
    }
    node_index = host_next_node(n, hits & ~leaf_bits, t_entry, tr.tmax, nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

TANDEM_KERNEL_END
}  // namespace tandem

// The wide layout's host loop.
#include "core/kernel/bvh_wide_host.h"
