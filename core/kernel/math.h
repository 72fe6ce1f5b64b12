// Small vector/matrix types shared by host and device code.
//
// These are our own PODs rather than CUDA's float3 or GLM so the exact same
// arithmetic (and therefore the same rounding) runs on both compilers.
#pragma once

#include "core/kernel/defines.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

struct Vec2 {
  float x, y;
};
// The large kernel functions that g++ keeps out of line (bsdf_eval_base,
// bsdf_sample_lobes, sample_light, setup_shading, sample_texture, ...) take
// their vectors by const reference. By value, the x86-64 calling
// convention packs a Vec3's x and y into one register, and g++ builds it
// with two 4-byte stores and an 8-byte load of the same bytes, which the
// CPU cannot forward from the stores: a stall of a dozen cycles or more per
// call (3-8 % of the Cornell box's path tracing; same bits either way).
// Small inlined helpers keep taking values.
struct Vec3 {
  float x, y, z;
};
struct alignas(16) Vec4 {
  float x, y, z, w;
};

static_assert(sizeof(Vec2) == 8 && sizeof(Vec3) == 12 && sizeof(Vec4) == 16, "GPU layout");

TANDEM_HD_INLINE Vec2 make_vec2(float x, float y) {
  return {x, y};
}
TANDEM_HD_INLINE Vec3 make_vec3(float x, float y, float z) {
  return {x, y, z};
}
TANDEM_HD_INLINE Vec3 make_vec3(float s) {
  return {s, s, s};
}
TANDEM_HD_INLINE Vec4 make_vec4(float x, float y, float z, float w) {
  return {x, y, z, w};
}
TANDEM_HD_INLINE Vec4 make_vec4(Vec3 v, float w) {
  return {v.x, v.y, v.z, w};
}
TANDEM_HD_INLINE Vec3 xyz(Vec4 v) {
  return {v.x, v.y, v.z};
}

// Scalar helpers. fminf/fmaxf/sqrtf exist on both sides; wrapping them keeps
// call sites short and lets us change precision policy in one place.
TANDEM_HD_INLINE float min_f(float a, float b) {
  return a < b ? a : b;
}
TANDEM_HD_INLINE float max_f(float a, float b) {
  return a > b ? a : b;
}
TANDEM_HD_INLINE float clamp_f(float x, float lo, float hi) {
  return min_f(max_f(x, lo), hi);
}
TANDEM_HD_INLINE float saturate(float x) {
  return clamp_f(x, 0.0f, 1.0f);
}
TANDEM_HD_INLINE float lerp_f(float a, float b, float t) {
  return a + (b - a) * t;
}
TANDEM_HD_INLINE float sqr(float x) {
  return x * x;
}
TANDEM_HD_INLINE float safe_sqrt(float x) {
  return sqrtf(max_f(x, 0.0f));
}
TANDEM_HD_INLINE uint32_t min_u(uint32_t a, uint32_t b) {
  return a < b ? a : b;
}
TANDEM_HD_INLINE uint32_t max_u(uint32_t a, uint32_t b) {
  return a > b ? a : b;
}

// Vec2
TANDEM_HD_INLINE Vec2 operator+(Vec2 a, Vec2 b) {
  return {a.x + b.x, a.y + b.y};
}
TANDEM_HD_INLINE Vec2 operator-(Vec2 a, Vec2 b) {
  return {a.x - b.x, a.y - b.y};
}
TANDEM_HD_INLINE Vec2 operator*(Vec2 a, float s) {
  return {a.x * s, a.y * s};
}
TANDEM_HD_INLINE Vec2 operator*(float s, Vec2 a) {
  return {a.x * s, a.y * s};
}

// Vec3
TANDEM_HD_INLINE Vec3 operator+(Vec3 a, Vec3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
TANDEM_HD_INLINE Vec3 operator-(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
TANDEM_HD_INLINE Vec3 operator-(Vec3 a) {
  return {-a.x, -a.y, -a.z};
}
TANDEM_HD_INLINE Vec3 operator*(Vec3 a, Vec3 b) {
  return {a.x * b.x, a.y * b.y, a.z * b.z};
}
TANDEM_HD_INLINE Vec3 operator*(Vec3 a, float s) {
  return {a.x * s, a.y * s, a.z * s};
}
TANDEM_HD_INLINE Vec3 operator*(float s, Vec3 a) {
  return {a.x * s, a.y * s, a.z * s};
}
TANDEM_HD_INLINE Vec3 operator/(Vec3 a, float s) {
  return a * (1.0f / s);
}
TANDEM_HD_INLINE Vec3 operator/(Vec3 a, Vec3 b) {
  return {a.x / b.x, a.y / b.y, a.z / b.z};
}
TANDEM_HD_INLINE Vec3& operator+=(Vec3& a, Vec3 b) {
  a = a + b;
  return a;
}
TANDEM_HD_INLINE Vec3& operator*=(Vec3& a, Vec3 b) {
  a = a * b;
  return a;
}
TANDEM_HD_INLINE Vec3& operator*=(Vec3& a, float s) {
  a = a * s;
  return a;
}

TANDEM_HD_INLINE float dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
TANDEM_HD_INLINE Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
TANDEM_HD_INLINE float length_sq(Vec3 a) {
  return dot(a, a);
}
TANDEM_HD_INLINE float length(Vec3 a) {
  return sqrtf(dot(a, a));
}
TANDEM_HD_INLINE Vec3 normalize(Vec3 a) {
  const float len2 = dot(a, a);
  return len2 > 0.0f ? a * (1.0f / sqrtf(len2)) : a;
}
TANDEM_HD_INLINE Vec3 min_v(Vec3 a, Vec3 b) {
  return {min_f(a.x, b.x), min_f(a.y, b.y), min_f(a.z, b.z)};
}
TANDEM_HD_INLINE Vec3 max_v(Vec3 a, Vec3 b) {
  return {max_f(a.x, b.x), max_f(a.y, b.y), max_f(a.z, b.z)};
}
TANDEM_HD_INLINE Vec3 lerp_v(Vec3 a, Vec3 b, float t) {
  return a + (b - a) * t;
}
TANDEM_HD_INLINE float max_component(Vec3 a) {
  return max_f(a.x, max_f(a.y, a.z));
}
TANDEM_HD_INLINE float min_component(Vec3 a) {
  return min_f(a.x, min_f(a.y, a.z));
}
TANDEM_HD_INLINE float average(Vec3 a) {
  return (a.x + a.y + a.z) * (1.0f / 3.0f);
}
// Rec. 709 luminance of linear RGB.
TANDEM_HD_INLINE float luminance(Vec3 c) {
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}
TANDEM_HD_INLINE bool is_black(Vec3 c) {
  return c.x == 0.0f && c.y == 0.0f && c.z == 0.0f;
}
TANDEM_HD_INLINE bool is_finite(Vec3 c) {
  return is_finite(c.x) && is_finite(c.y) && is_finite(c.z);
}
TANDEM_HD_INLINE float component(Vec3 v, int axis) {
  return axis == 0 ? v.x : (axis == 1 ? v.y : v.z);
}
TANDEM_HD_INLINE Vec3 reflect(Vec3 wo, Vec3 n) {
  return 2.0f * dot(wo, n) * n - wo;
}

// Orthonormal basis around a unit normal (Duff et al. 2017, branchless).
struct Frame {
  Vec3 t, b, n;
};
TANDEM_HD_INLINE Frame make_frame(Vec3 n) {
  const float sign = n.z >= 0.0f ? 1.0f : -1.0f;
  const float a = -1.0f / (sign + n.z);
  const float b = n.x * n.y * a;
  Frame f;
  f.t = {1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x};
  f.b = {b, sign + n.y * n.y * a, -n.y};
  f.n = n;
  return f;
}
// Frame from a normal and a (not necessarily orthogonal) tangent hint.
TANDEM_HD_INLINE Frame make_frame(Vec3 n, Vec3 tangent_hint) {
  Vec3 t = tangent_hint - n * dot(n, tangent_hint);
  const float len2 = dot(t, t);
  if (!(len2 > 1e-12f)) return make_frame(n);
  t = t * (1.0f / sqrtf(len2));
  return {t, cross(n, t), n};
}
TANDEM_HD_INLINE Vec3 to_local(const Frame& f, Vec3 v) {
  return {dot(v, f.t), dot(v, f.b), dot(v, f.n)};
}
TANDEM_HD_INLINE Vec3 to_world(const Frame& f, Vec3 v) {
  return f.t * v.x + f.b * v.y + f.n * v.z;
}

// Affine 3x4 transform, row-major: rows[i] = (m[i][0..2], translation[i]).
struct Mat34 {
  Vec4 rows[3];
};
static_assert(sizeof(Mat34) == 48, "GPU layout");

TANDEM_HD_INLINE Mat34 mat34_identity() {
  return {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
}
TANDEM_HD_INLINE Vec3 transform_point(const Mat34& m, Vec3 p) {
  return {m.rows[0].x * p.x + m.rows[0].y * p.y + m.rows[0].z * p.z + m.rows[0].w,
          m.rows[1].x * p.x + m.rows[1].y * p.y + m.rows[1].z * p.z + m.rows[1].w,
          m.rows[2].x * p.x + m.rows[2].y * p.y + m.rows[2].z * p.z + m.rows[2].w};
}
TANDEM_HD_INLINE Vec3 transform_vector(const Mat34& m, Vec3 v) {
  return {m.rows[0].x * v.x + m.rows[0].y * v.y + m.rows[0].z * v.z,
          m.rows[1].x * v.x + m.rows[1].y * v.y + m.rows[1].z * v.z,
          m.rows[2].x * v.x + m.rows[2].y * v.y + m.rows[2].z * v.z};
}
// Normals transform by the inverse transpose; given the inverse matrix we
// multiply by its transpose.
TANDEM_HD_INLINE Vec3 transform_normal(const Mat34& inverse, Vec3 n) {
  return {inverse.rows[0].x * n.x + inverse.rows[1].x * n.y + inverse.rows[2].x * n.z,
          inverse.rows[0].y * n.x + inverse.rows[1].y * n.y + inverse.rows[2].y * n.z,
          inverse.rows[0].z * n.x + inverse.rows[1].z * n.y + inverse.rows[2].z * n.z};
}

TANDEM_KERNEL_END
}  // namespace tandem
