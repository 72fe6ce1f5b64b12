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

namespace tandem {

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

// A BLAS from `root`, the ray already in its object space (tr.box), the
// instance record filled by enter_instance. True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_blas(TwoLevelTrace<kCount>& tr, const KBvhNode* nodes, uint32_t root,
                            const uint32_t* record) {
  const HostBoxRay hb = make_host_box_ray(tr.box);
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
        const uint32_t first = n.child[c] & ~kBvhLeafFlag;
        for (uint32_t i = 0; i < n.count[c]; ++i) {
          if (tr.leaf_triangle(first + i, record)) return true;
        }
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

// ---------------------------------------------------------------------------
// Wide layout: a loop per level in distance order. The portable loop
// (trace_two_level_wide) visits a node's children in octant order (slot ^
// octant, roughly front to back) from a stack of node groups, because a GPU
// thread has no registers for sorting. The host decodes and tests the eight
// child boxes four at a time in SSE, keeps each hit child's entry distance,
// and visits the children nearest first:
//   - a hit leaf's triangles are tested before any child is descended into,
//     leaves in order of entry distance, so the closest hit found shrinks the
//     interval of every box test after it;
//   - the interior children hit go on the stack farthest first with their
//     entry distances, and one waiting behind the closest hit found since is
//     dropped (its box test would fail);
//   - a BLAS node's leaf entries (bvh_wide_prim_indices) are prefetched as
//     the node is visited, and the leaf records they name
//     (bvh_leaf_triangles, the binary layout's) as soon as a leaf is hit.
// The box tests are the portable test's float operations lane for lane
// (origin + q * scale, then (plane - o) * inv, the far distance scaled, x then
// y then z), so a child is hit exactly when the portable loop hits it. The
// closest hit's t is the same bits as the portable loop's; of two hits at
// exactly the same t either may be reported, since the order differs.

// Entries of the wide host stacks: up to seven children wait per level, and
// a wide tree is no deeper than its binary tree (kBvhStackSize levels).
constexpr uint32_t kHostWideStackSize = (kWideBvhWidth - 1) * kBvhStackSize;

#if defined(__SSE2__)

// Slots 0..3 and 4..7 of an axis's eight plane bytes, as floats.
inline void host_wide_planes(const uint8_t* q, __m128* slots_lo, __m128* slots_hi) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i bytes = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(q));
  const __m128i words = _mm_unpacklo_epi8(bytes, zero);
  *slots_lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero));
  *slots_hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero));
}

// Bit s: slot s of n holds a child (meta != 0), in one byte compare. With a
// loop over the slots here, the sanitizer build (GCC, -O1) warned of an
// uninitialised slot index and counted every slot live.
inline uint32_t host_wide_live_slots(const KWideBvhNode& n) {
  const __m128i meta = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(n.meta));
  const uint32_t empty = uint32_t(_mm_movemask_epi8(_mm_cmpeq_epi8(meta, _mm_setzero_si128())));
  return ~empty & 0xffu;
}

// Bit s: slot s of n holds a child (empty slots are not tested, as in the
// portable loop) and the ray hits its box within [tmin, tmax], entering it
// at t_entry[s].
inline uint32_t host_wide_slot_hits(const KWideBvhNode& n, const BoxRay& r, float tmin, float tmax,
                                    uint32_t live, float t_entry[kWideBvhWidth]) {
  __m128 tn[2] = {_mm_set1_ps(tmin), _mm_set1_ps(tmin)};
  __m128 tf[2] = {_mm_set1_ps(tmax), _mm_set1_ps(tmax)};
  const __m128 far_scale = _mm_set1_ps(kBoxFarScale);
  for (int a = 0; a < 3; ++a) {
    const bool negative = ((r.octant >> a) & 1u) != 0;
    __m128 qn[2], qf[2];
    host_wide_planes(negative ? n.qhi[a] : n.qlo[a], &qn[0], &qn[1]);
    host_wide_planes(negative ? n.qlo[a] : n.qhi[a], &qf[0], &qf[1]);
    const __m128 origin = _mm_set1_ps(component(n.origin, a));
    const __m128 scale = _mm_set1_ps(wide_node_scale(n, a));
    const __m128 ray_origin = _mm_set1_ps(component(r.origin, a));
    const __m128 inv = _mm_set1_ps(component(r.inv_dir, a));
    for (int h = 0; h < 2; ++h) {
      const __m128 near_plane = _mm_add_ps(origin, _mm_mul_ps(qn[h], scale));
      const __m128 far_plane = _mm_add_ps(origin, _mm_mul_ps(qf[h], scale));
      const __m128 t_near = _mm_mul_ps(_mm_sub_ps(near_plane, ray_origin), inv);
      const __m128 t_far =
          _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(far_plane, ray_origin), inv), far_scale);
      tn[h] = _mm_max_ps(t_near, tn[h]);
      tf[h] = _mm_min_ps(t_far, tf[h]);
    }
  }
  _mm_storeu_ps(t_entry, tn[0]);
  _mm_storeu_ps(t_entry + 4, tn[1]);
  const uint32_t hits = uint32_t(_mm_movemask_ps(_mm_cmple_ps(tn[0], tf[0]))) |
                        (uint32_t(_mm_movemask_ps(_mm_cmple_ps(tn[1], tf[1]))) << 4);
  return hits & live;
}

#else

inline uint32_t host_wide_live_slots(const KWideBvhNode& n) {
  uint32_t live = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s)
    live |= (n.meta[s] != 0 ? 1u : 0u) << s;
  return live;
}

inline uint32_t host_wide_slot_hits(const KWideBvhNode& n, const BoxRay& r, float tmin, float tmax,
                                    uint32_t live, float t_entry[kWideBvhWidth]) {
  const Vec3 scale = {wide_node_scale(n, 0), wide_node_scale(n, 1), wide_node_scale(n, 2)};
  uint32_t hits = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    t_entry[s] = tmax;
    if (!((live >> s) & 1u)) continue;
    const Vec3 lo = make_vec3(n.origin.x + float(n.qlo[0][s]) * scale.x,
                              n.origin.y + float(n.qlo[1][s]) * scale.y,
                              n.origin.z + float(n.qlo[2][s]) * scale.z);
    const Vec3 hi = make_vec3(n.origin.x + float(n.qhi[0][s]) * scale.x,
                              n.origin.y + float(n.qhi[1][s]) * scale.y,
                              n.origin.z + float(n.qhi[2][s]) * scale.z);
    if (intersect_box(r, lo, hi, tmin, tmax, &t_entry[s])) hits |= 1u << s;
  }
  return hits;
}

#endif

// The children of a wide node that the ray hits, nearest first.
struct HostWideHits {
  uint32_t slot[kWideBvhWidth];
  float t[kWideBvhWidth];
  uint32_t count;
  uint32_t leaves;  // bit i: hit i (in this order) is a leaf slot
};

template <bool kCount>
inline void host_wide_visit(TwoLevelTrace<kCount>& tr, const KWideBvhNode& n, bool in_blas,
                            HostWideHits& out) {
  const uint32_t live = host_wide_live_slots(n);
  if constexpr (kCount) {
    tr.counters->nodes += 1;
    tr.counters->boxes += uint64_t(popcount(live));
    if (in_blas) tr.counters->blas_nodes += 1;
  }
  float t_entry[kWideBvhWidth];
  const uint32_t hits = host_wide_slot_hits(n, tr.box, tr.tmin, tr.tmax, live, t_entry);
  // Insertion by entry distance, ties in octant order (the portable loop's).
  const uint32_t octant = tr.octant();
  uint32_t count = 0;
  for (uint32_t bits = hits; bits != 0; bits &= bits - 1u) {
    const uint32_t s = count_trailing_zeros(bits);
    const float t = t_entry[s];
    uint32_t j = count++;
    for (; j > 0; --j) {
      const float tp = out.t[j - 1];
      if (tp < t || (tp == t && (out.slot[j - 1] ^ octant) < (s ^ octant))) break;
      out.slot[j] = out.slot[j - 1];
      out.t[j] = tp;
    }
    out.slot[j] = s;
    out.t[j] = t;
  }
  out.count = count;
  uint32_t leaves = 0;
  for (uint32_t i = 0; i < count; ++i)
    leaves |= (((n.imask >> out.slot[i]) & 1u) ^ 1u) << i;
  out.leaves = leaves;
}

// First entry and number of primitives of leaf slot s.
inline uint32_t host_wide_leaf_first(const KWideBvhNode& n, uint32_t s) {
  return n.prim_base + (n.meta[s] & 31u);
}
inline uint32_t host_wide_leaf_count(const KWideBvhNode& n, uint32_t s) {
  return uint32_t(popcount(uint32_t(n.meta[s]) >> 5));
}

// The interior children among h, nearest next (returned), the others onto
// the stack farthest first; then the nearest waiting node still in front of
// the closest hit. Returns kInvalidIndex when the loop is done.
inline uint32_t host_wide_next_node(const KWideBvhNode& n, const HostWideHits& h, float tmax,
                                    const KWideBvhNode* nodes, HostBvhStackEntry* stack,
                                    uint32_t& sp) {
  uint32_t next = kInvalidIndex;
  float t_next = 0.0f;
  for (uint32_t i = h.count; i-- > 0;) {
    if (((h.leaves >> i) & 1u) || h.t[i] > tmax) continue;
    const uint32_t s = h.slot[i];
    if (next != kInvalidIndex && sp < kHostWideStackSize) stack[sp++] = {next, t_next};
    next = n.child_base + popcount(uint32_t(n.imask) & ((1u << s) - 1u));
    t_next = h.t[i];
    // Both cache lines of the 80-byte node.
    const KWideBvhNode* child = nodes + next;
    prefetch_readonly(child);
    prefetch_readonly(reinterpret_cast<const char*>(child) + sizeof(KWideBvhNode) - 1);
  }
  if (next != kInvalidIndex) return next;
  while (sp != 0) {
    const HostBvhStackEntry e = stack[--sp];
    if (!(e.t_entry > tmax)) return e.node;
  }
  return kInvalidIndex;
}

// A BLAS of the wide layout from `root`, the ray in its object space
// (enter_instance's record). True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_wide_blas(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                 uint32_t root, const uint32_t* record) {
  const uint32_t* entries = tr.kd->bvh_wide_prim_indices;  // leaf record indices (bvh.h)
  HostBvhStackEntry stack[kHostWideStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KWideBvhNode& n = nodes[node_index];
    prefetch_readonly(entries + n.prim_base);
    HostWideHits h;
    host_wide_visit(tr, n, true, h);
    if (h.leaves != 0u) {
      for (uint32_t bits = h.leaves; bits != 0; bits &= bits - 1u) {
        const uint32_t s = h.slot[count_trailing_zeros(bits)];
        const uint32_t first = host_wide_leaf_first(n, s), count = host_wide_leaf_count(n, s);
        for (uint32_t k = 0; k < count; ++k)
          tr.prefetch_leaf_triangles(entries[first + k], 1, record);
      }
      for (uint32_t bits = h.leaves; bits != 0; bits &= bits - 1u) {
        const uint32_t i = count_trailing_zeros(bits);
        if (h.t[i] > tr.tmax) continue;  // behind a hit of a nearer leaf
        const uint32_t s = h.slot[i];
        const uint32_t first = host_wide_leaf_first(n, s), count = host_wide_leaf_count(n, s);
        for (uint32_t k = 0; k < count; ++k) {
          if (tr.leaf_triangle(entries[first + k], record)) return true;
        }
      }
    }
    node_index = host_wide_next_node(n, h, tr.tmax, nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

// The TLAS of the wide layout from `root`, in world space: a node's hit
// instances, nearest first, each BLAS to its end, then its interior
// children. True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_two_level_wide(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                      uint32_t root) {
  const uint32_t* prim_indices = tr.kd->bvh_wide_prim_indices;
  HostBvhStackEntry stack[kHostWideStackSize];
  uint32_t record[kBvhInstanceRecordWords];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KWideBvhNode& n = nodes[node_index];
    HostWideHits h;
    host_wide_visit(tr, n, false, h);
    for (uint32_t bits = h.leaves; bits != 0; bits &= bits - 1u) {
      const uint32_t i = count_trailing_zeros(bits);
      if (h.t[i] > tr.tmax) continue;
      const uint32_t s = h.slot[i];
      const uint32_t first = host_wide_leaf_first(n, s), count = host_wide_leaf_count(n, s);
      for (uint32_t k = 0; k < count; ++k) {
        const uint32_t blas = tr.enter_instance(prim_indices[first + k], true, record);
        if (blas == kInvalidIndex) continue;
        const bool stop = host_trace_wide_blas(tr, nodes, blas, record);
        tr.leave_instance(record);
        if (stop) return true;
      }
    }
    node_index = host_wide_next_node(n, h, tr.tmax, nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

}  // namespace tandem
