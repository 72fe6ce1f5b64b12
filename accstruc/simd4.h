// Four-float vectors for the builder's hot loops (binning, bounds). SSE on
// x86-64, where it is always available; plain loops elsewhere. Host code
// only: the kernels never see this.
#pragma once

#include <cstdint>

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
#undef TANDEM_SIMD_BINOP
inline void to_int(F4 a, int32_t out[4]) {
  for (int i = 0; i < 4; ++i)
    out[i] = int32_t(a.v[i]);
}
inline float half_area(F4 lo, F4 hi) {
  const float x = hi.v[0] - lo.v[0], y = hi.v[1] - lo.v[1], z = hi.v[2] - lo.v[2];
  return x * y + y * z + z * x;
}

#endif

}  // namespace tandem::simd
