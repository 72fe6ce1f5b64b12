// Host only: the watertight ray/triangle test (bvh_intersect.h) on up to
// four leaf records at once, one triangle per SSE lane. Included by
// bvh_traverse_host.h, outside nvcc.
//
// Why: on the large scenes a ray tests 30-90 triangles, and the scalar test
// (about 130 instructions, with the shear's axis picked per vertex by a
// branchy component()) was a quarter of the host traversal's instructions;
// the traversal is bound by instructions more than by memory there.
//
// Same hits, bit for bit, as testing the records one after another with
// TwoLevelTrace::test_triangle:
//   - every lane does the scalar test's float operations in its order
//     (no FMA on x86-64's SSE, IEEE division), with the shear's axes picked
//     from the transposed records instead of per component;
//   - the tests against tmax are redone, in record order, for the lanes that
//     passed them with the tmax at the call, against the tmax left by the
//     hits before: the scalar loop tests each record against the interval
//     the records before it shrank, and a lane that fails the wider test
//     fails the narrower one too (the products are monotonic in tmax);
//   - a lane whose edge function rounds to exactly zero needs the scalar
//     test's double-precision fallback: then the whole leaf takes the scalar
//     loop (rare: the ray grazes an edge or a vertex);
//   - the alpha test and the hit record are TwoLevelTrace::record_hit's.
#pragma once

#include "core/kernel/defines.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

#if defined(__SSE2__)

// The watertight test's per-ray constants, broadcast for four lanes: the
// shear's axes, the origin's components on them and the shear itself.
struct HostShear4 {
  uint32_t kx, ky, kz;
  __m128 ox, oy, oz;  // origin[kx], origin[ky], origin[kz]
  __m128 sx, sy, sz;
};

// `box` is the BLAS's ray (the shear's axes in bits 8..13 of its octant) and
// `record` its instance record (the shear's factors), as enter_instance left
// them.
inline HostShear4 make_host_shear4(const BoxRay& box, const uint32_t* record) {
  HostShear4 s;
  s.kx = (box.octant >> 8) & 3u;
  s.ky = (box.octant >> 10) & 3u;
  s.kz = box.octant >> 12;
  const float origin[3] = {box.origin.x, box.origin.y, box.origin.z};
  s.ox = _mm_set1_ps(origin[s.kx]);
  s.oy = _mm_set1_ps(origin[s.ky]);
  s.oz = _mm_set1_ps(origin[s.kz]);
  s.sx = _mm_set1_ps(uint_as_float(record[kRecordShear]));
  s.sy = _mm_set1_ps(uint_as_float(record[kRecordShear + 1]));
  s.sz = _mm_set1_ps(uint_as_float(record[kRecordShear + 2]));
  return s;
}

// What the lanes of one four-triangle test found.
struct HostTriangles4 {
  alignas(16) float t[4];
  alignas(16) float t_abs[4];    // |t * det|, the division-free interval test's
  alignas(16) float abs_det[4];  // |det|
  alignas(16) float u[4];        // Embree's (u, v): the weights of p1 and p2
  alignas(16) float v[4];
  uint32_t hits;        // bit i: lane i hits within (tmin, tmax) at the call
  uint32_t zero_edges;  // bit i: lane i needs the double-precision fallback
};

inline const Vec4& leaf_vertex(const KLeafTriangle& t, int k) {
  return k == 0 ? t.p0 : (k == 1 ? t.p1 : t.p2);
}

// Vertex k (0, 1, 2) of four records, transposed: (x, y, z) of the lanes.
inline void host_transpose_vertex(const KLeafTriangle* const rec[4], int k, __m128 out[3]) {
  __m128 r0 = _mm_load_ps(&leaf_vertex(*rec[0], k).x);
  __m128 r1 = _mm_load_ps(&leaf_vertex(*rec[1], k).x);
  __m128 r2 = _mm_load_ps(&leaf_vertex(*rec[2], k).x);
  __m128 r3 = _mm_load_ps(&leaf_vertex(*rec[3], k).x);
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  out[0] = r0;
  out[1] = r1;
  out[2] = r2;
}

// intersect_triangle_watertight() on four records (repeat one to fill unused
// lanes: only the caller's lanes count) against (tmin, tmax).
inline void host_watertight4(const HostShear4& s, const KLeafTriangle* const rec[4], float tmin,
                             float tmax, HostTriangles4* out) {
  __m128 p[3][3];  // [vertex][axis]
  host_transpose_vertex(rec, 0, p[0]);
  host_transpose_vertex(rec, 1, p[1]);
  host_transpose_vertex(rec, 2, p[2]);
  // a = p0 - origin, then its components on the shear's axes (the same
  // subtraction whichever is taken first).
  __m128 x[3], y[3], z[3];
  for (int k = 0; k < 3; ++k) {
    const __m128 kz = _mm_sub_ps(p[k][s.kz], s.oz);
    x[k] = _mm_sub_ps(_mm_sub_ps(p[k][s.kx], s.ox), _mm_mul_ps(s.sx, kz));
    y[k] = _mm_sub_ps(_mm_sub_ps(p[k][s.ky], s.oy), _mm_mul_ps(s.sy, kz));
    z[k] = kz;
  }
  // Vertices a, b, c are 0, 1, 2.
  const __m128 u = _mm_sub_ps(_mm_mul_ps(x[2], y[1]), _mm_mul_ps(y[2], x[1]));
  const __m128 v = _mm_sub_ps(_mm_mul_ps(x[0], y[2]), _mm_mul_ps(y[0], x[2]));
  const __m128 w = _mm_sub_ps(_mm_mul_ps(x[1], y[0]), _mm_mul_ps(y[1], x[0]));
  const __m128 zero = _mm_setzero_ps();
  const __m128 zero_edge =
      _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero));
  const __m128 any_negative =
      _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
  const __m128 any_positive =
      _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
  const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
  const __m128 az = _mm_mul_ps(s.sz, z[0]), bz = _mm_mul_ps(s.sz, z[1]),
               cz = _mm_mul_ps(s.sz, z[2]);
  const __m128 t_scaled =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz));
  const __m128 sign = _mm_set1_ps(-0.0f);
  const __m128 abs_det = _mm_andnot_ps(sign, det);
  const __m128 det_negative = _mm_cmplt_ps(det, zero);
  const __m128 t_abs = _mm_or_ps(_mm_and_ps(det_negative, _mm_xor_ps(t_scaled, sign)),
                                 _mm_andnot_ps(det_negative, t_scaled));
  const __m128 in_interval =
      _mm_and_ps(_mm_cmpgt_ps(t_abs, _mm_mul_ps(_mm_set1_ps(tmin), abs_det)),
                 _mm_cmplt_ps(t_abs, _mm_mul_ps(_mm_set1_ps(tmax), abs_det)));
  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.0f), det);
  const __m128 t = _mm_mul_ps(t_scaled, inv_det);
  const __m128 t_inside =
      _mm_and_ps(_mm_cmpgt_ps(t, _mm_set1_ps(tmin)), _mm_cmplt_ps(t, _mm_set1_ps(tmax)));
  const __m128 rejected =
      _mm_or_ps(_mm_and_ps(any_negative, any_positive), _mm_cmpeq_ps(det, zero));
  const __m128 hit = _mm_andnot_ps(rejected, _mm_and_ps(in_interval, t_inside));
  _mm_store_ps(out->t, t);
  _mm_store_ps(out->t_abs, t_abs);
  _mm_store_ps(out->abs_det, abs_det);
  _mm_store_ps(out->u, _mm_mul_ps(v, inv_det));
  _mm_store_ps(out->v, _mm_mul_ps(w, inv_det));
  out->hits = uint32_t(_mm_movemask_ps(hit));
  out->zero_edges = uint32_t(_mm_movemask_ps(zero_edge));
}

// Tests `count` (1..4) leaf records of the current BLAS, rec[0..count-1], in
// that order, as test_triangle on each would. Returns 1: an any-hit query
// stopped, 0: done, -1: a lane needs the exact fallback and nothing was
// recorded (the caller tests these records with test_triangle instead).
template <bool kCount>
inline int host_test_records4(TwoLevelTrace<kCount>& tr, const HostShear4& s,
                              const KLeafTriangle* rec[4], uint32_t count, const uint32_t* record) {
  if (count == 0) return 0;
  for (uint32_t i = count; i < 4; ++i)
    rec[i] = rec[0];
  HostTriangles4 h;
  host_watertight4(s, rec, tr.tmin, tr.tmax, &h);
  const uint32_t lanes = (1u << count) - 1u;
  if ((h.zero_edges & lanes) != 0u) return -1;
  for (uint32_t bits = h.hits & lanes; bits != 0; bits &= bits - 1u) {
    const uint32_t i = count_trailing_zeros(bits);
    // An earlier lane's hit may have shrunk the interval since the test.
    if (!(h.t_abs[i] < tr.tmax * h.abs_det[i]) || !(h.t[i] < tr.tmax)) continue;
    const TriangleHit th = {h.t[i], h.u[i], h.v[i]};
    if (!tr.record_hit(th, float_as_uint(rec[i]->p0.w), record)) continue;
    if (tr.any_hit) {
      // Counted as the loop of single tests counts: up to the one that stopped it.
      if constexpr (kCount) tr.counters->triangles += i + 1;
      return 1;
    }
  }
  if constexpr (kCount) tr.counters->triangles += count;
  return 0;
}

#endif  // __SSE2__

TANDEM_KERNEL_END
}  // namespace tandem
