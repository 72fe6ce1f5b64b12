// Host-only traversal of the wide layout in distance order (included by
// bvh_traverse_host.h, outside nvcc), in two instruction sets: SSE2, which
// every x86-64 has, and AVX2 where the CPU has it (the eight child boxes of
// a node in one pass instead of two), chosen once at start-up
// (host_wide_isa).
#pragma once

#include <cstddef>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "core/kernel/host_isa.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// ---------------------------------------------------------------------------
// Wide layout: a loop per level in distance order. The portable loop
// (trace_two_level_wide) visits a node's children in octant order (slot ^
// octant, roughly front to back) from a stack of node groups, because a GPU
// thread has no registers for sorting. The host decodes and tests the eight
// child boxes together (AVX2, or two halves in SSE2), keeps each hit child's
// entry distance, and visits the children nearest first:
//   - a hit leaf's triangles are tested before any child is descended into,
//     leaves in order of entry distance, so the closest hit found shrinks the
//     interval of every box test after it; a leaf's triangles are tested
//     together in SSE (bvh_leaf_host.h);
//   - the interior children hit go on the stack farthest first with their
//     entry distances, and one waiting behind the closest hit found since is
//     dropped (its box test would fail);
//   - the interior children hit are prefetched as soon as the boxes are
//     tested, and a hit leaf's records (bvh_wide_leaf_triangles, next to
//     each other in the wide layout's entry order) right after;
//   - an any-hit query, whose interval does not shrink before it stops,
//     takes children in the portable loop's octant order and leaves and
//     instances in slot order: sorting buys it nothing;
//   - a BLAS flagged kBlasBinaryOnly (a deforming mesh whose wide nodes are
//     not kept current) is traversed in its binary layout.
// The box tests are the portable test's float operations lane for lane
// (origin + q * scale, then (plane - o) * inv, the far distance scaled, x then
// y then z), so a child is hit exactly when the portable loop hits it. The
// closest hit's t is the same bits as the portable loop's; of two hits at
// exactly the same t either may be reported, since the order differs.

// Entries of the wide host stacks: up to seven children wait per level, and
// a wide tree is no deeper than its binary tree (kBvhStackSize levels).
constexpr uint32_t kHostWideStackSize = (kWideBvhWidth - 1) * kBvhStackSize;

// Bits set in each 8-bit value. x86-64's baseline has no popcnt
// instruction, and __builtin_popcount became a call into libgcc (6% of the
// wide loop's instructions on builtin:procedural); a node visit needs it
// for a child's index (its rank among the interior slots) and a leaf's
// primitive count.
struct HostPopcount8 {
  uint8_t bits[256];
  constexpr HostPopcount8() : bits() {
    for (uint32_t i = 0; i < 256; ++i)
      bits[i] = uint8_t((i & 1u) + ((i >> 1) & 1u) + ((i >> 2) & 1u) + ((i >> 3) & 1u) +
                        ((i >> 4) & 1u) + ((i >> 5) & 1u) + ((i >> 6) & 1u) + (i >> 7));
  }
};
inline constexpr HostPopcount8 kHostPopcount8{};
inline uint32_t host_popcount8(uint32_t x) {
  return kHostPopcount8.bits[x & 0xffu];
}

#if defined(__SSE2__)

// Per-space constants of the wide box test: the ray's origin and inverse
// direction broadcast per axis, and where in a node the near and the far
// plane bytes of each axis are (qlo or qhi by the direction's sign), so a
// node visit picks nothing per axis.
struct HostWideRay {
  __m128 origin[3];
  __m128 inv[3];
  uint32_t near_plane[3], far_plane[3];  // byte offsets into KWideBvhNode
};

// The near and far plane offsets of each direction octant: qhi follows
// qlo, and a negative direction swaps near and far.
struct HostWidePlanes {
  uint32_t near_plane[3], far_plane[3];
};
struct HostWidePlaneTable {
  HostWidePlanes octant[8];
  constexpr HostWidePlaneTable() : octant() {
    constexpr uint32_t lo = uint32_t(offsetof(KWideBvhNode, qlo));
    constexpr uint32_t swap = uint32_t(offsetof(KWideBvhNode, qhi)) - lo;
    for (uint32_t o = 0; o < 8; ++o) {
      for (uint32_t a = 0; a < 3; ++a) {
        const uint32_t negative = (o >> a) & 1u;
        octant[o].near_plane[a] = lo + kWideBvhWidth * a + negative * swap;
        octant[o].far_plane[a] = lo + kWideBvhWidth * a + (negative ^ 1u) * swap;
      }
    }
  }
};
inline constexpr HostWidePlaneTable kHostWidePlanes{};

inline HostWideRay make_host_wide_ray(const BoxRay& r) {
  HostWideRay h;
  h.origin[0] = _mm_set1_ps(r.origin.x);
  h.origin[1] = _mm_set1_ps(r.origin.y);
  h.origin[2] = _mm_set1_ps(r.origin.z);
  h.inv[0] = _mm_set1_ps(r.inv_dir.x);
  h.inv[1] = _mm_set1_ps(r.inv_dir.y);
  h.inv[2] = _mm_set1_ps(r.inv_dir.z);
  const HostWidePlanes& planes = kHostWidePlanes.octant[r.octant & 7u];
  for (uint32_t a = 0; a < 3; ++a) {
    h.near_plane[a] = planes.near_plane[a];
    h.far_plane[a] = planes.far_plane[a];
  }
  return h;
}

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
inline uint32_t host_wide_slot_hits(const KWideBvhNode& n, const HostWideRay& r, float tmin,
                                    float tmax, uint32_t live, float t_entry[kWideBvhWidth]) {
  const uint8_t* bytes = reinterpret_cast<const uint8_t*>(&n);
  __m128 tn[2] = {_mm_set1_ps(tmin), _mm_set1_ps(tmin)};
  __m128 tf[2] = {_mm_set1_ps(tmax), _mm_set1_ps(tmax)};
  const __m128 far_scale = _mm_set1_ps(kBoxFarScale);
  for (int a = 0; a < 3; ++a) {
    __m128 qn[2], qf[2];
    host_wide_planes(bytes + r.near_plane[a], &qn[0], &qn[1]);
    host_wide_planes(bytes + r.far_plane[a], &qf[0], &qf[1]);
    const __m128 origin = _mm_set1_ps(component(n.origin, a));
    const __m128 scale = _mm_set1_ps(wide_node_scale(n, a));
    for (int h = 0; h < 2; ++h) {
      const __m128 near_plane = _mm_add_ps(origin, _mm_mul_ps(qn[h], scale));
      const __m128 far_plane = _mm_add_ps(origin, _mm_mul_ps(qf[h], scale));
      const __m128 t_near = _mm_mul_ps(_mm_sub_ps(near_plane, r.origin[a]), r.inv[a]);
      const __m128 t_far =
          _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(far_plane, r.origin[a]), r.inv[a]), far_scale);
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

struct HostWideRay {
  BoxRay box;
};
inline HostWideRay make_host_wide_ray(const BoxRay& r) {
  return HostWideRay{r};
}

inline uint32_t host_wide_live_slots(const KWideBvhNode& n) {
  uint32_t live = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s)
    live |= (n.meta[s] != 0 ? 1u : 0u) << s;
  return live;
}

inline uint32_t host_wide_slot_hits(const KWideBvhNode& n, const HostWideRay& r, float tmin,
                                    float tmax, uint32_t live, float t_entry[kWideBvhWidth]) {
  const Vec3 scale = {wide_node_scale(n, 0), wide_node_scale(n, 1), wide_node_scale(n, 2)};
  uint32_t hits = 0;
  for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
    t_entry[s] = tmax;
    if (!((live >> s) & 1u)) continue;
    Vec3 lo, hi;
    wide_child_box(n, scale, s, &lo, &hi);
    if (intersect_box(r.box, lo, hi, tmin, tmax, &t_entry[s])) hits |= 1u << s;
  }
  return hits;
}

#endif

#if TANDEM_HOST_AVX2
// host_wide_slot_hits() with the eight slots in one AVX register: the same
// float operations per lane (vmaxps / vminps return their second operand on
// a NaN as maxps / minps do), so the same hits and entry distances.
TANDEM_TARGET_AVX2 inline uint32_t host_wide_slot_hits_avx2(const KWideBvhNode& n,
                                                            const HostWideRay& r, float tmin,
                                                            float tmax, uint32_t live,
                                                            float t_entry[kWideBvhWidth]) {
  const uint8_t* bytes = reinterpret_cast<const uint8_t*>(&n);
  __m256 tn = _mm256_set1_ps(tmin), tf = _mm256_set1_ps(tmax);
  const __m256 far_scale = _mm256_set1_ps(kBoxFarScale);
  for (int a = 0; a < 3; ++a) {
    const __m256 qn = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(
        _mm_loadl_epi64(reinterpret_cast<const __m128i*>(bytes + r.near_plane[a]))));
    const __m256 qf = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(
        _mm_loadl_epi64(reinterpret_cast<const __m128i*>(bytes + r.far_plane[a]))));
    const __m256 origin = _mm256_set1_ps(component(n.origin, a));
    const __m256 scale = _mm256_set1_ps(wide_node_scale(n, a));
    const __m256 ray_origin = _mm256_broadcastss_ps(r.origin[a]);
    const __m256 inv = _mm256_broadcastss_ps(r.inv[a]);
    const __m256 near_plane = _mm256_add_ps(origin, _mm256_mul_ps(qn, scale));
    const __m256 far_plane = _mm256_add_ps(origin, _mm256_mul_ps(qf, scale));
    const __m256 t_near = _mm256_mul_ps(_mm256_sub_ps(near_plane, ray_origin), inv);
    const __m256 t_far =
        _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(far_plane, ray_origin), inv), far_scale);
    tn = _mm256_max_ps(t_near, tn);
    tf = _mm256_min_ps(t_far, tf);
  }
  _mm256_storeu_ps(t_entry, tn);
  return uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(tn, tf, _CMP_LE_OQ))) & live;
}
#endif

// The instruction sets of the loop below: only the child-box test differs.
struct HostWideSse {
  static uint32_t slot_hits(const KWideBvhNode& n, const HostWideRay& r, float tmin, float tmax,
                            uint32_t live, float t_entry[kWideBvhWidth]) {
    return host_wide_slot_hits(n, r, tmin, tmax, live, t_entry);
  }
};
#if TANDEM_HOST_AVX2
struct HostWideAvx2 {
  TANDEM_TARGET_AVX2 static uint32_t slot_hits(const KWideBvhNode& n, const HostWideRay& r,
                                               float tmin, float tmax, uint32_t live,
                                               float t_entry[kWideBvhWidth]) {
    return host_wide_slot_hits_avx2(n, r, tmin, tmax, live, t_entry);
  }
};
#endif

// The children of a node among `bits` (a hit mask), nearest first: slots in
// slot[], entry distances in t[]; ties in octant order (the portable
// loop's). Returns how many.
inline uint32_t host_wide_sorted(uint32_t bits, const float t_entry[kWideBvhWidth], uint32_t octant,
                                 uint32_t slot[kWideBvhWidth], float t[kWideBvhWidth]) {
  uint32_t count = 0;
  for (; bits != 0; bits &= bits - 1u) {
    const uint32_t s = count_trailing_zeros(bits);
    const float ts = t_entry[s];
    uint32_t j = count++;
    for (; j > 0; --j) {
      const float tp = t[j - 1];
      if (tp < ts || (tp == ts && (slot[j - 1] ^ octant) < (s ^ octant))) break;
      slot[j] = slot[j - 1];
      t[j] = tp;
    }
    slot[j] = s;
    t[j] = ts;
  }
  return count;
}

// The slot among `bits` (not empty) whose box the ray enters first, and that
// distance in *t; of equal distances the lowest slot. The order of a node's
// hit leaves: taken one at a time, so that once a leaf's hit is nearer than
// the rest nothing more is sorted.
inline uint32_t host_wide_nearest(uint32_t bits, const float t_entry[kWideBvhWidth], float* t) {
#if defined(__SSE2__)
  const __m128i lane_bits = _mm_setr_epi32(1, 2, 4, 8);
  const __m128 in_lo = _mm_castsi128_ps(
      _mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(int(bits & 15u)), lane_bits), lane_bits));
  const __m128 in_hi = _mm_castsi128_ps(
      _mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(int(bits >> 4)), lane_bits), lane_bits));
  const __m128 inf = _mm_castsi128_ps(_mm_set1_epi32(0x7f800000));
  const __m128 lo = _mm_or_ps(_mm_and_ps(in_lo, _mm_loadu_ps(t_entry)), _mm_andnot_ps(in_lo, inf));
  const __m128 hi =
      _mm_or_ps(_mm_and_ps(in_hi, _mm_loadu_ps(t_entry + 4)), _mm_andnot_ps(in_hi, inf));
  __m128 m = _mm_min_ps(lo, hi);
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(2, 3, 0, 1)));
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(1, 0, 3, 2)));
  const uint32_t equal = uint32_t(_mm_movemask_ps(_mm_cmpeq_ps(lo, m))) |
                         (uint32_t(_mm_movemask_ps(_mm_cmpeq_ps(hi, m))) << 4);
  // A slot entered at +inf (tmax infinite) equals the padding: keep to bits.
  const uint32_t s =
      (equal & bits) != 0u ? count_trailing_zeros(equal & bits) : count_trailing_zeros(bits);
#else
  uint32_t s = count_trailing_zeros(bits);
  for (uint32_t rest = bits & (bits - 1u); rest != 0; rest &= rest - 1u) {
    const uint32_t r = count_trailing_zeros(rest);
    if (t_entry[r] < t_entry[s]) s = r;
  }
#endif
  *t = t_entry[s];
  return s;
}

// Visits node n: counts it, tests its child boxes. Returns the hit mask.
template <bool kCount, class Isa>
inline uint32_t host_wide_visit(TwoLevelTrace<kCount>& tr, const HostWideRay& wr,
                                const KWideBvhNode& n, bool in_blas, float t_entry[kWideBvhWidth]) {
  const uint32_t live = host_wide_live_slots(n);
  if constexpr (kCount) {
    tr.counters->nodes += 1;
    tr.counters->boxes += uint64_t(host_popcount8(live));
    if (in_blas) tr.counters->blas_nodes += 1;
  }
  return Isa::slot_hits(n, wr, tr.tmin, tr.tmax, live, t_entry);
}

// First entry and number of primitives of leaf slot s.
inline uint32_t host_wide_leaf_first(const KWideBvhNode& n, uint32_t s) {
  return n.prim_base + (n.meta[s] & 31u);
}
inline uint32_t host_wide_leaf_count(const KWideBvhNode& n, uint32_t s) {
  return host_popcount8(uint32_t(n.meta[s]) >> 5);
}

// The interior children among `inner` (hit mask), the nearest next
// (returned), the others onto the stack farthest first, each dropped when
// the closest hit found is nearer than its box; then the nearest waiting
// node still in front of the closest hit. Returns kInvalidIndex when the
// loop is done.
inline uint32_t host_wide_next_node(const KWideBvhNode& n, uint32_t inner,
                                    const float t_entry[kWideBvhWidth], uint32_t octant, float tmax,
                                    bool by_distance, const KWideBvhNode* nodes,
                                    HostBvhStackEntry* stack, uint32_t& sp) {
  const uint32_t imask = n.imask;
  uint32_t next = kInvalidIndex;
  if (inner != 0u) {
    const uint32_t rest = inner & (inner - 1u);
    if (rest == 0u) {
      // One child (the common case below the top levels).
      const uint32_t s = count_trailing_zeros(inner);
      if (!(t_entry[s] > tmax)) next = n.child_base + host_popcount8(imask & ((1u << s) - 1u));
    } else if ((rest & (rest - 1u)) == 0u) {
      // Two: the nearer next, the other waits (ties in octant order).
      uint32_t a = count_trailing_zeros(inner), b = count_trailing_zeros(rest);
      if (t_entry[b] < t_entry[a] || (t_entry[b] == t_entry[a] && (b ^ octant) < (a ^ octant))) {
        const uint32_t swap = a;
        a = b;
        b = swap;
      }
      if (!(t_entry[a] > tmax)) {
        next = n.child_base + host_popcount8(imask & ((1u << a) - 1u));
        if (!(t_entry[b] > tmax) && sp < kHostWideStackSize)
          stack[sp++] = {n.child_base + host_popcount8(imask & ((1u << b) - 1u)), t_entry[b]};
      }
    } else if (!by_distance) {
      // Octant order (the portable loop's), farthest pushed first.
      uint32_t ordered = 0;  // bit (s ^ octant) for slot s
      for (uint32_t bits = inner; bits != 0; bits &= bits - 1u)
        ordered |= 1u << (count_trailing_zeros(bits) ^ octant);
      while (ordered != 0) {
        const uint32_t pos = 31u - uint32_t(__builtin_clz(ordered));
        ordered &= ~(1u << pos);
        const uint32_t s = pos ^ octant;
        if (next != kInvalidIndex && sp < kHostWideStackSize) stack[sp++] = {next, tmax};
        next = n.child_base + host_popcount8(imask & ((1u << s) - 1u));
      }
    } else {
      uint32_t slot[kWideBvhWidth];
      float t[kWideBvhWidth];
      float t_next = 0.0f;
      for (uint32_t i = host_wide_sorted(inner, t_entry, octant, slot, t); i-- > 0;) {
        if (t[i] > tmax) continue;
        if (next != kInvalidIndex && sp < kHostWideStackSize) stack[sp++] = {next, t_next};
        next = n.child_base + host_popcount8(imask & ((1u << slot[i]) - 1u));
        t_next = t[i];
      }
    }
  }
  if (next != kInvalidIndex) return next;
  while (sp != 0) {
    const HostBvhStackEntry e = stack[--sp];
    if (!(e.t_entry > tmax)) return e.node;
  }
  return kInvalidIndex;
}

// Starts fetching the interior children among `inner` (hit mask), both
// cache lines of each 80-byte node: called as soon as the boxes are tested,
// so the fetches overlap the leaves' triangle tests (`leaves`, the hit
// leaves) and each other. A lone child with no leaf to test is loaded next
// anyway: then nothing.
inline void host_wide_prefetch_children(const KWideBvhNode& n, uint32_t inner, uint32_t leaves,
                                        const KWideBvhNode* nodes) {
  if (leaves == 0u && (inner & (inner - 1u)) == 0u) return;
  const uint32_t imask = n.imask;
  for (; inner != 0; inner &= inner - 1u) {
    const uint32_t s = count_trailing_zeros(inner);
    const KWideBvhNode* child = nodes + n.child_base + host_popcount8(imask & ((1u << s) - 1u));
    prefetch_readonly(child);
    prefetch_readonly(reinterpret_cast<const char*>(child) + sizeof(KWideBvhNode) - 1);
  }
}

// Where a BLAS's wide leaves find their triangles (KBlasFlags): in their own
// wide-order records, through the binary layout's records, or through the
// mesh's indices.
enum class HostWideRecords : uint8_t { kWide, kBinary, kIndexed };

inline HostWideRecords host_wide_records(const uint32_t* record) {
  const uint32_t flags = record[kRecordBlasFlags];
  if ((flags & kBlasNoLeafRecords) != 0u) return HostWideRecords::kIndexed;
  return (flags & kBlasNoWideRecords) != 0u ? HostWideRecords::kBinary : HostWideRecords::kWide;
}

// Starts fetching what the test of leaf slot s reads first.
template <bool kCount>
inline void host_wide_prefetch_leaf(const TwoLevelTrace<kCount>& tr, const KWideBvhNode& n,
                                    uint32_t s, HostWideRecords records, const uint32_t* record) {
  const uint32_t first = host_wide_leaf_first(n, s), count = host_wide_leaf_count(n, s);
  if (records == HostWideRecords::kWide) {
    const KLeafTriangle* r = tr.kd->bvh_wide_leaf_triangles + first;
    prefetch_readonly(r);
    prefetch_readonly(reinterpret_cast<const char*>(r + count) - 1);
    return;
  }
  const uint32_t* entries = tr.kd->bvh_wide_prim_indices;
  for (uint32_t k = 0; k < count; ++k)
    tr.prefetch_leaf_triangles(entries[first + k], 1, record);
}

// The triangles of leaf slot s of BLAS node n. True: an any-hit query
// stopped.
template <bool kCount>
inline bool host_wide_leaf(TwoLevelTrace<kCount>& tr, const KWideBvhNode& n, uint32_t s,
                           HostWideRecords records, const uint32_t* record
#if defined(__SSE2__)
                           ,
                           const HostShear4& shear
#endif
) {
  const uint32_t first = host_wide_leaf_first(n, s), count = host_wide_leaf_count(n, s);
  const uint32_t* entries = tr.kd->bvh_wide_prim_indices;
#if defined(__SSE2__)
  if (records != HostWideRecords::kIndexed) {
    const KLeafTriangle* rec[4];
    for (uint32_t k = 0; k < count; ++k) {
      rec[k] = records == HostWideRecords::kWide ? tr.kd->bvh_wide_leaf_triangles + first + k
                                                 : tr.kd->bvh_leaf_triangles + entries[first + k];
    }
    const int found = host_test_records4(tr, shear, rec, count, record);
    if (found >= 0) return found > 0;
  }
#else
  (void)records;
#endif
  for (uint32_t k = 0; k < count; ++k) {
    if (tr.wide_leaf_triangle(first + k, record)) return true;
  }
  return false;
}

// A BLAS of the wide layout from `root`, the ray in its object space
// (enter_instance's record). True: an any-hit query stopped.
template <bool kCount, class Isa>
inline bool host_trace_wide_blas(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                 uint32_t root, const uint32_t* record) {
  const uint32_t* entries = tr.kd->bvh_wide_prim_indices;
  const HostWideRecords records = host_wide_records(record);
  const HostWideRay wr = make_host_wide_ray(tr.box);
#if defined(__SSE2__)
  const HostShear4 shear = make_host_shear4(tr.box, record);
#endif
  const uint32_t octant = tr.octant();
  HostBvhStackEntry stack[kHostWideStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KWideBvhNode& n = nodes[node_index];
    if (records != HostWideRecords::kWide) prefetch_readonly(entries + n.prim_base);
    float t_entry[kWideBvhWidth];
    const uint32_t hits = host_wide_visit<kCount, Isa>(tr, wr, n, true, t_entry);
    const uint32_t leaves = hits & ~uint32_t(n.imask);
    host_wide_prefetch_children(n, hits & n.imask, leaves, nodes);
    if (leaves != 0u) {
      for (uint32_t bits = leaves; bits != 0; bits &= bits - 1u)
        host_wide_prefetch_leaf(tr, n, count_trailing_zeros(bits), records, record);
      // Nearest first; an any-hit query stops at its first hit, so it
      // takes them in slot order.
      for (uint32_t bits = leaves; bits != 0;) {
        uint32_t s;
        if (tr.any_hit || (bits & (bits - 1u)) == 0u) {
          s = count_trailing_zeros(bits);
          bits &= bits - 1u;
          if (t_entry[s] > tr.tmax) continue;
        } else {
          float t;
          s = host_wide_nearest(bits, t_entry, &t);
          if (t > tr.tmax) break;  // every other leaf lies behind the closest hit too
          bits &= ~(1u << s);
        }
#if defined(__SSE2__)
        if (host_wide_leaf(tr, n, s, records, record, shear)) return true;
#else
        if (host_wide_leaf(tr, n, s, records, record)) return true;
#endif
      }
    }
    node_index = host_wide_next_node(n, hits & n.imask, t_entry, octant, tr.tmax, !tr.any_hit,
                                     nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

// The TLAS of the wide layout from `root`, in world space: a node's hit
// instances, nearest first, each BLAS to its end, then its interior
// children. True: an any-hit query stopped.
template <bool kCount, class Isa>
inline bool host_trace_two_level_wide_isa(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                          uint32_t root) {
  const uint32_t* prim_indices = tr.kd->bvh_wide_prim_indices;
  const BoxRay world_box = tr.box;
  const HostWideRay world = make_host_wide_ray(world_box);
  const uint32_t octant = tr.octant();
  HostBvhStackEntry stack[kHostWideStackSize];
  uint32_t record[kBvhInstanceRecordWords];
  uint32_t sp = 0;
  uint32_t node_index = root;
  do {
    const KWideBvhNode& n = nodes[node_index];
    float t_entry[kWideBvhWidth];
    const uint32_t hits = host_wide_visit<kCount, Isa>(tr, world, n, false, t_entry);
    const uint32_t leaves = hits & ~uint32_t(n.imask);
    host_wide_prefetch_children(n, hits & n.imask, leaves, nodes);
    if (leaves != 0u) {
      // Instances nearest first; an any-hit query (whose interval does not
      // shrink) in slot order.
      uint32_t slot[kWideBvhWidth];
      float t[kWideBvhWidth];
      uint32_t count = 0;
      if (tr.any_hit) {
        for (uint32_t bits = leaves; bits != 0; bits &= bits - 1u) {
          const uint32_t s = count_trailing_zeros(bits);
          slot[count] = s;
          t[count++] = t_entry[s];
        }
      } else {
        count = host_wide_sorted(leaves, t_entry, octant, slot, t);
      }
      for (uint32_t i = 0; i < count; ++i) {
        if (t[i] > tr.tmax) continue;
        const uint32_t first = host_wide_leaf_first(n, slot[i]);
        const uint32_t instances = host_wide_leaf_count(n, slot[i]);
        for (uint32_t k = 0; k < instances; ++k) {
          const uint32_t blas = tr.enter_instance(prim_indices[first + k], true, record);
          if (blas == kInvalidIndex) continue;
          // A deforming mesh whose wide nodes are not kept current: its
          // binary ones (kBlasBinaryOnly).
          const bool stop =
              (record[kRecordBlasFlags] & kBlasBinaryOnly) != 0u
                  ? host_trace_blas(
                        tr, tr.kd->bvh_nodes,
                        tr.kd->blas_roots[tr.kd->instances[record[kRecordInstance]].mesh].bvh_root,
                        record)
                  : host_trace_wide_blas<kCount, Isa>(tr, nodes, blas, record);
          // leave_instance() without its divisions: the world ray as it was.
          tr.box = world_box;
          if (stop) return true;
        }
      }
    }
    node_index = host_wide_next_node(n, hits & n.imask, t_entry, octant, tr.tmax, !tr.any_hit,
                                     nodes, stack, sp);
  } while (node_index != kInvalidIndex);
  return false;
}

// Which instruction set the host's wide loop uses: AVX2 where the CPU has it,
// unless the environment's TANDEM_HOST_ISA is "sse2"; tests switch it to run
// both. Chosen once at start-up, read per query.
struct HostWideIsaChoice {
  bool avx2 = false;
};
inline HostWideIsaChoice host_wide_isa{host_cpu_has_avx2()};

// The whole loop, each instruction set compiled into one function (flatten:
// the BLAS loop and the box and triangle tests inlined into it, so the AVX2
// copy is AVX2 throughout).
template <bool kCount>
__attribute__((flatten)) inline bool host_trace_two_level_wide_sse(TwoLevelTrace<kCount>& tr,
                                                                   const KWideBvhNode* nodes,
                                                                   uint32_t root) {
  return host_trace_two_level_wide_isa<kCount, HostWideSse>(tr, nodes, root);
}
#if TANDEM_HOST_AVX2
template <bool kCount>
TANDEM_TARGET_AVX2 __attribute__((flatten)) inline bool host_trace_two_level_wide_avx2(
    TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes, uint32_t root) {
  return host_trace_two_level_wide_isa<kCount, HostWideAvx2>(tr, nodes, root);
}
#endif

// The TLAS of the wide layout from `root`, in world space, and every BLAS
// the ray enters. True: an any-hit query stopped.
template <bool kCount>
inline bool host_trace_two_level_wide(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                      uint32_t root) {
#if TANDEM_HOST_AVX2
  if (host_wide_isa.avx2) return host_trace_two_level_wide_avx2(tr, nodes, root);
#endif
  return host_trace_two_level_wide_sse(tr, nodes, root);
}

TANDEM_KERNEL_END
}  // namespace tandem
