// Warps from the unit square to common domains, with their densities.
// Each warp has a chi-square test in tests/kernel_sampling_test.cpp.
#pragma once

#include "core/kernel/math.h"
#include "core/kernel/trig.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Shirley-Chiu concentric mapping of the unit square to the unit disk.
TANDEM_HD_INLINE Vec2 sample_disk_concentric(float u1, float u2) {
  const float a = 2.0f * u1 - 1.0f;
  const float b = 2.0f * u2 - 1.0f;
  if (a == 0.0f && b == 0.0f) return {0.0f, 0.0f};
  // phi in units of pi: the same angles as pi/4 * (b/a) and pi/2 - pi/4 * (a/b).
  float r, phi_over_pi;
  if (a * a > b * b) {
    r = a;
    phi_over_pi = 0.25f * (b / a);
  } else {
    r = b;
    phi_over_pi = 0.5f - 0.25f * (a / b);
  }
  const SinCos sc = sincos_pi(phi_over_pi);
  return {r * sc.cos, r * sc.sin};
}

// Cosine-weighted hemisphere around +z; pdf = cos(theta) / pi.
TANDEM_HD_INLINE Vec3 sample_cosine_hemisphere(float u1, float u2) {
  const Vec2 d = sample_disk_concentric(u1, u2);
  const float z = safe_sqrt(1.0f - d.x * d.x - d.y * d.y);
  return {d.x, d.y, z};
}
TANDEM_HD_INLINE float pdf_cosine_hemisphere(float cos_theta) {
  return cos_theta > 0.0f ? cos_theta * kInvPi : 0.0f;
}

// Uniform direction on the unit sphere; pdf = 1 / (4 pi).
TANDEM_HD_INLINE Vec3 sample_uniform_sphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = safe_sqrt(1.0f - z * z);
  const SinCos sc = sincos_pi(2.0f * u2);  // phi = 2 pi u2
  return {r * sc.cos, r * sc.sin, z};
}

// Uniform point on a triangle, returned as barycentrics (b1, b2) with
// b0 = 1 - b1 - b2. Uses the low-distortion square-to-triangle map of Heitz
// (2019) so stratification of (u1, u2) carries over to the triangle.
TANDEM_HD_INLINE Vec2 sample_triangle_barycentrics(float u1, float u2) {
  float b0, b1;
  if (u2 > u1) {
    b0 = u1 * 0.5f;
    b1 = u2 - b0;
  } else {
    b1 = u2 * 0.5f;
    b0 = u1 - b1;
  }
  return {b1, 1.0f - b0 - b1};
}

// Power heuristic (beta = 2) for multiple importance sampling; written so
// very large pdfs (near-specular lobes) do not overflow.
TANDEM_HD_INLINE float mis_power_heuristic(float pdf_a, float pdf_b) {
  if (!(pdf_a > 0.0f)) return 0.0f;
  if (!(pdf_b > 0.0f) || !is_finite(pdf_b)) return 1.0f;
  if (!is_finite(pdf_a)) return 1.0f;
  const float r = pdf_b / pdf_a;
  return 1.0f / (1.0f + r * r);
}

// Equirectangular (latitude-longitude) mapping with +y up. u = 0.5 looks down
// -z, matching the usual HDRI orientation used by glTF viewers.
TANDEM_HD_INLINE Vec2 direction_to_equirect(Vec3 d) {
  // atan2_pi (trig.h) rather than atan2f: the same bits on the CPU and the
  // GPU, and a quarter of glibc's instructions (every missed ray looks its
  // direction up).
  const float u = atan2_pi(d.x, -d.z) * 0.5f + 0.5f;
  // theta from atan2 rather than acos(d.y): acos is ill-conditioned near the
  // poles, where float d.y = 1 - 6e-8 steps move theta by 3e-4 rad, and the
  // sin(theta) Jacobian in env_pdf then disagrees with env_sample's (or is 0).
  const float v = atan2_pi(sqrtf(d.x * d.x + d.z * d.z), d.y);
  return {u - floorf(u), v};
}
TANDEM_HD_INLINE Vec3 equirect_to_direction(float u, float v) {
  const SinCos phi = sincos_pi(2.0f * u - 1.0f);  // phi = (u - 0.5) 2 pi
  const SinCos theta = sincos_pi(v);              // theta = v pi
  return {theta.sin * phi.sin, theta.cos, -theta.sin * phi.cos};
}

TANDEM_KERNEL_END
}  // namespace tandem
