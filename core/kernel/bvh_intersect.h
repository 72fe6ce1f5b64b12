// Ray-box and ray-triangle tests used by Tandem's BVH traversal
// (bvh_traverse.h). Host/device code.
//
// Both tests are written so that rounding can never make a ray miss geometry
// it really hits:
//   - the slab test uses the conservative factor of Ize 2013 ("Robust BVH Ray
//     Traversal") on the far distance, and picks the near/far plane by the
//     sign of the direction so that 0 * inf NaNs (a zero direction component
//     with the origin on a slab plane) are simply ignored;
//   - the triangle test is the watertight test of Woop, Benthin & Wald 2013
//     ("Watertight Ray/Triangle Intersection"), with its double-precision
//     fallback for edge functions that round to zero.
#pragma once

#include "core/kernel/gpu_intrinsics.h"
#include "core/kernel/math.h"
#include "core/kernel/types.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Products that nvcc must not contract into FMAs: the edge functions of two
// triangles sharing an edge are exact negations of each other only when both
// products are rounded separately, which is what makes the test watertight.
TANDEM_HD float mul_rn(float a, float b) {
#if TANDEM_GPU_CODE
  return gpu_mul_rn(a, b);
#else
  return a * b;
#endif
}

TANDEM_HD uint32_t count_trailing_zeros(uint32_t x) {
#if TANDEM_GPU_CODE
  return gpu_find_first_set(x) - 1u;
#else
  return uint32_t(__builtin_ctz(x));
#endif
}

TANDEM_HD uint32_t popcount(uint32_t x) {
#if TANDEM_GPU_CODE
  return gpu_popcount(x);
#else
  return uint32_t(__builtin_popcount(x));
#endif
}

// 1 + 2 * gamma(3) from Ize 2013 (gamma(n) = n * eps / (1 - n * eps), eps =
// 2^-24), rounded up: scaling the far slab distance by it covers the three
// roundings in (plane - origin) * (1 / dir).
constexpr float kBoxFarScale = 1.0f + 4.0f / 8388608.0f;

// Per-ray data for box tests: origin, reciprocal direction (+-inf for zero
// components) and the direction's sign per axis (bit a set: dir[a] < 0,
// -0 included so it matches the sign of 1 / -0 = -inf).
struct BoxRay {
  Vec3 origin;
  Vec3 inv_dir;
  uint32_t octant;
};

TANDEM_HD BoxRay make_box_ray(Vec3 origin, Vec3 dir) {
  BoxRay r;
  r.origin = origin;
  r.inv_dir = {1.0f / dir.x, 1.0f / dir.y, 1.0f / dir.z};
  r.octant = (float_as_uint(dir.x) >> 31) | ((float_as_uint(dir.y) >> 31) << 1) |
             ((float_as_uint(dir.z) >> 31) << 2);
  return r;
}

// Intersects the box [lo, hi] with the ray segment [tmin, tmax]. On a hit,
// *t_entry is where the ray enters the (clipped) box.
TANDEM_HD bool intersect_box(const BoxRay& r, Vec3 lo, Vec3 hi, float tmin, float tmax,
                             float* t_entry) {
  const bool nx = (r.octant & 1u) != 0, ny = (r.octant & 2u) != 0, nz = (r.octant & 4u) != 0;
  const float near_x = ((nx ? hi.x : lo.x) - r.origin.x) * r.inv_dir.x;
  const float near_y = ((ny ? hi.y : lo.y) - r.origin.y) * r.inv_dir.y;
  const float near_z = ((nz ? hi.z : lo.z) - r.origin.z) * r.inv_dir.z;
  const float far_x = ((nx ? lo.x : hi.x) - r.origin.x) * r.inv_dir.x * kBoxFarScale;
  const float far_y = ((ny ? lo.y : hi.y) - r.origin.y) * r.inv_dir.y * kBoxFarScale;
  const float far_z = ((nz ? lo.z : hi.z) - r.origin.z) * r.inv_dir.z * kBoxFarScale;
  // Written as "candidate beats current ? candidate : current" so that a NaN
  // candidate (origin exactly on the plane of a zero direction component,
  // where the ray lies inside that slab) leaves the interval unchanged.
  float tn = tmin, tf = tmax;
  tn = near_x > tn ? near_x : tn;
  tn = near_y > tn ? near_y : tn;
  tn = near_z > tn ? near_z : tn;
  tf = far_x < tf ? far_x : tf;
  tf = far_y < tf ? far_y : tf;
  tf = far_z < tf ? far_z : tf;
  *t_entry = tn;
  return tn <= tf;
}

// Per-ray data of the watertight triangle test: the axis permutation that
// makes z the dominant direction axis, and the shear that maps the ray to
// the +z axis.
struct ShearRay {
  Vec3 origin;
  uint32_t kx, ky, kz;
  float sx, sy, sz;
};

TANDEM_HD ShearRay make_shear_ray(Vec3 origin, Vec3 dir) {
  ShearRay s;
  s.origin = origin;
  const float ax = fabsf(dir.x), ay = fabsf(dir.y), az = fabsf(dir.z);
  s.kz = (ax > ay) ? (ax > az ? 0u : 2u) : (ay > az ? 1u : 2u);
  s.kx = s.kz == 2u ? 0u : s.kz + 1u;
  s.ky = s.kx == 2u ? 0u : s.kx + 1u;
  // Keep the winding (and with it the sign convention of U, V, W) fixed.
  if (component(dir, int(s.kz)) < 0.0f) {
    const uint32_t t = s.kx;
    s.kx = s.ky;
    s.ky = t;
  }
  const float dz = component(dir, int(s.kz));
  s.sx = component(dir, int(s.kx)) / dz;
  s.sy = component(dir, int(s.ky)) / dz;
  s.sz = 1.0f / dz;
  return s;
}

struct TriangleHit {
  float t, u, v;
};

// Watertight ray/triangle test. Accepts hits with tmin < t < tmax. (u, v)
// are the barycentrics of p1 and p2 (Embree's convention). Two-sided.
TANDEM_HD bool intersect_triangle_watertight(const ShearRay& r, Vec3 p0, Vec3 p1, Vec3 p2,
                                             float tmin, float tmax, TriangleHit* hit) {
  const Vec3 a = p0 - r.origin, b = p1 - r.origin, c = p2 - r.origin;
  const float a_kz = component(a, int(r.kz)), b_kz = component(b, int(r.kz)),
              c_kz = component(c, int(r.kz));
  const float ax = component(a, int(r.kx)) - r.sx * a_kz;
  const float ay = component(a, int(r.ky)) - r.sy * a_kz;
  const float bx = component(b, int(r.kx)) - r.sx * b_kz;
  const float by = component(b, int(r.ky)) - r.sy * b_kz;
  const float cx = component(c, int(r.kx)) - r.sx * c_kz;
  const float cy = component(c, int(r.ky)) - r.sy * c_kz;

  // Scaled barycentrics: the 2D edge functions of the sheared triangle.
  float u = mul_rn(cx, by) - mul_rn(cy, bx);
  float v = mul_rn(ax, cy) - mul_rn(ay, cx);
  float w = mul_rn(bx, ay) - mul_rn(by, ax);
  if (u == 0.0f || v == 0.0f || w == 0.0f) {
    // The ray passes (nearly) through an edge or vertex: decide exactly.
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;
  const float det = u + v + w;
  if (det == 0.0f) return false;

  const float az = r.sz * a_kz, bz = r.sz * b_kz, cz = r.sz * c_kz;
  const float t_scaled = u * az + v * bz + w * cz;
  // Compare t = t_scaled / det against the interval without dividing.
  const float abs_det = fabsf(det);
  const float t_abs = det < 0.0f ? -t_scaled : t_scaled;
  if (!(t_abs > tmin * abs_det) || !(t_abs < tmax * abs_det)) return false;
  const float inv_det = 1.0f / det;
  const float t = t_scaled * inv_det;
  // Guard the rounding of the division so the reported t obeys the interval.
  if (!(t > tmin) || !(t < tmax)) return false;
  // Vertex p0 weighs u, p1 weighs v and p2 weighs w: Embree's (u, v) are the
  // weights of p1 and p2.
  hit->t = t;
  hit->u = v * inv_det;
  hit->v = w * inv_det;
  return true;
}

TANDEM_KERNEL_END
}  // namespace tandem
