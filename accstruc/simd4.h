// Four-float vectors for the builder's hot loops (binning, bounds). SSE on
// x86-64, where it is always available; plain loops elsewhere. Host code
// only: the kernels never see this.
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tandem::simd {

#if defined(__SSE2__)

struct F4 {
  __m128 v;
};
inline F4 load(const float* p) {
  return {_mm_load_ps(p)};
}  // 16-byte aligned
inline void store(float* p, F4 a) {
  _mm_store_ps(p, a.v);
}
inline F4 set1(float s) {
  return {_mm_set1_ps(s)};
}
inline F4 set(float x, float y, float z, float w) {
  return {_mm_setr_ps(x, y, z, w)};
}
inline F4 operator+(F4 a, F4 b) {
  return {_mm_add_ps(a.v, b.v)};
}
inline F4 operator-(F4 a, F4 b) {
  return {_mm_sub_ps(a.v, b.v)};
}
inline F4 operator*(F4 a, F4 b) {
  return {_mm_mul_ps(a.v, b.v)};
}
inline F4 min(F4 a, F4 b) {
  return {_mm_min_ps(a.v, b.v)};
}
inline F4 max(F4 a, F4 b) {
  return {_mm_max_ps(a.v, b.v)};
}
// Truncating conversion of the lanes to int32.
inline void to_int(F4 a, int32_t out[4]) {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_cvttps_epi32(a.v));
}
// e.x * e.y + e.y * e.z + e.z * e.x of the first three lanes of e = hi - lo:
// half the surface area of a box, without leaving the registers.
inline float half_area(F4 lo, F4 hi) {
  const __m128 e = _mm_sub_ps(hi.v, lo.v);
  const __m128 p = _mm_mul_ps(e, _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)));  // xy yz zx ww
  const __m128 s = _mm_add_ss(p, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1)));
  return _mm_cvtss_f32(_mm_add_ss(s, _mm_shuffle_ps(p, p, _MM_SHUFFLE(2, 2, 2, 2))));
}

// The vector with its fourth lane zeroed: records that keep an id (or
// anything that is not a coordinate) there must not feed it to arithmetic.
inline F4 xyz(F4 a) {
  return {_mm_and_ps(a.v, _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0)))};
}
// lo <= hi in each of the first three lanes: a non-empty box, as
// Aabb::empty() tests it.
inline bool le3(F4 lo, F4 hi) {
  return (_mm_movemask_ps(_mm_cmple_ps(lo.v, hi.v)) & 7) == 7;
}
// Lane-wise operations for structure-of-arrays loops (the spatial
// builder's piece binning): unaligned memory, division, and masks (all bits
// set in a lane where the comparison holds).
inline F4 loadu(const float* p) {
  return {_mm_loadu_ps(p)};
}
inline void storeu(float* p, F4 a) {
  _mm_storeu_ps(p, a.v);
}
inline F4 operator/(F4 a, F4 b) {
  return {_mm_div_ps(a.v, b.v)};
}
inline F4 lt(F4 a, F4 b) {
  return {_mm_cmplt_ps(a.v, b.v)};
}
inline F4 le(F4 a, F4 b) {
  return {_mm_cmple_ps(a.v, b.v)};
}
inline F4 mask_and(F4 a, F4 b) {
  return {_mm_and_ps(a.v, b.v)};
}
// mask ? a : b, lane by lane.
inline F4 select(F4 mask, F4 a, F4 b) {
  return {_mm_or_ps(_mm_and_ps(mask.v, a.v), _mm_andnot_ps(mask.v, b.v))};
}
// One bit per lane where the mask is set.
inline int mask_bits(F4 mask) {
  return _mm_movemask_ps(mask.v);
}

#else

struct F4 {
  float v[4];
};
inline F4 load(const float* p) {
  return {{p[0], p[1], p[2], p[3]}};
}
inline void store(float* p, F4 a) {
  for (int i = 0; i < 4; ++i)
    p[i] = a.v[i];
}
inline F4 set1(float s) {
  return {{s, s, s, s}};
}
inline F4 set(float x, float y, float z, float w) {
  return {{x, y, z, w}};
}
#define TANDEM_SIMD_BINOP(op, expr) \
  inline F4 op(F4 a, F4 b) {        \
    F4 r;                           \
    for (int i = 0; i < 4; ++i)     \
      r.v[i] = expr;                \
    return r;                       \
  }
TANDEM_SIMD_BINOP(operator+, a.v[i] + b.v[i])
TANDEM_SIMD_BINOP(operator-, a.v[i] - b.v[i])
TANDEM_SIMD_BINOP(operator*, a.v[i] * b.v[i])
TANDEM_SIMD_BINOP(min, b.v[i] < a.v[i] ? b.v[i] : a.v[i])
TANDEM_SIMD_BINOP(max, b.v[i] > a.v[i] ? b.v[i] : a.v[i])
inline void to_int(F4 a, int32_t out[4]) {
  for (int i = 0; i < 4; ++i)
    out[i] = int32_t(a.v[i]);
}
inline float half_area(F4 lo, F4 hi) {
  const float x = hi.v[0] - lo.v[0], y = hi.v[1] - lo.v[1], z = hi.v[2] - lo.v[2];
  return x * y + y * z + z * x;
}

inline F4 xyz(F4 a) {
  a.v[3] = 0.0f;
  return a;
}
inline bool le3(F4 lo, F4 hi) {
  return lo.v[0] <= hi.v[0] && lo.v[1] <= hi.v[1] && lo.v[2] <= hi.v[2];
}
inline F4 loadu(const float* p) {
  return load(p);
}
inline void storeu(float* p, F4 a) {
  store(p, a);
}
TANDEM_SIMD_BINOP(operator/, a.v[i] / b.v[i])
// Masks: a lane is all ones (1.0f's bits do not matter, only nonzero-ness
// through the integer view).
inline F4 mask_of(bool m0, bool m1, bool m2, bool m3) {
  const bool m[4] = {m0, m1, m2, m3};
  F4 r;
  for (int i = 0; i < 4; ++i) {
    const uint32_t bits = m[i] ? 0xffffffffu : 0u;
    std::memcpy(&r.v[i], &bits, 4);
  }
  return r;
}
inline bool lane_set(F4 m, int i) {
  uint32_t bits;
  std::memcpy(&bits, &m.v[i], 4);
  return bits != 0;
}
inline F4 lt(F4 a, F4 b) {
  return mask_of(a.v[0] < b.v[0], a.v[1] < b.v[1], a.v[2] < b.v[2], a.v[3] < b.v[3]);
}
inline F4 le(F4 a, F4 b) {
  return mask_of(a.v[0] <= b.v[0], a.v[1] <= b.v[1], a.v[2] <= b.v[2], a.v[3] <= b.v[3]);
}
inline F4 mask_and(F4 a, F4 b) {
  return mask_of(lane_set(a, 0) && lane_set(b, 0), lane_set(a, 1) && lane_set(b, 1),
                 lane_set(a, 2) && lane_set(b, 2), lane_set(a, 3) && lane_set(b, 3));
}
inline F4 select(F4 mask, F4 a, F4 b) {
  F4 r;
  for (int i = 0; i < 4; ++i)
    r.v[i] = lane_set(mask, i) ? a.v[i] : b.v[i];
  return r;
}
#undef TANDEM_SIMD_BINOP
inline int mask_bits(F4 mask) {
  return (lane_set(mask, 0) ? 1 : 0) | (lane_set(mask, 1) ? 2 : 0) | (lane_set(mask, 2) ? 4 : 0) |
         (lane_set(mask, 3) ? 8 : 0);
}

#endif

}  // namespace tandem::simd
