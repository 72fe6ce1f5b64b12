// Spatiotemporal variance-guided filtering (after Schied et al. 2017,
// "Spatiotemporal Variance-Guided Filtering"), as per-pixel stages over POD
// buffers so that the CPU (TBB, core/render/svgf_cpu.h) and the CUDA device
// (backends/cuda/svgf_kernels.cu) run the same code:
//
//   svgf_temporal_pixel   demodulate this frame's radiance by albedo, find
//                         the pixel's history through its motion vector
//                         (rejected where depth, normal or id disagree),
//                         blend colour and luminance moments by an
//                         exponential moving average capped by a history
//                         length
//   svgf_variance_pixel   per-pixel luminance variance: from the temporal
//                         moments, or from a spatial estimate where the
//                         history is still short (just disoccluded)
//   svgf_atrous_pixel     one a-trous iteration (5x5 B3-spline taps, step
//                         2^i), weights stopped at depth, normal and
//                         luminance edges, luminance scaled by the
//                         variance; variance filtered alongside
//   svgf_modulate_pixel   multiply the albedo back in
//
// Filtering illumination (radiance / albedo) instead of radiance keeps
// texture detail sharp: the filter only has to smooth the lighting.
#pragma once

#include "core/kernel/features.h"

namespace tandem {

struct SvgfParams {
  uint32_t width, height;
  uint32_t max_history;          // colour EMA weight is 1 / min(length, max_history)
  uint32_t max_moments_history;  // the same for the luminance moments
  uint32_t iterations;           // a-trous iterations
  float sigma_depth;             // depth edge stop, in units of the local depth slope
  float sigma_normal;            // exponent of the normal edge stop
  float sigma_luminance;         // luminance edge stop, in standard deviations
  float reproject_normal_cos;    // history normal must agree to this cosine
  float reproject_depth_rel;     // ... and depth to this fraction (plus the slope)
  float variance_scale;          // variance of the input's mean per unit estimate (1 / its spp)
};

TANDEM_HD SvgfParams svgf_default_params(uint32_t width, uint32_t height) {
  SvgfParams p;
  p.width = width;
  p.height = height;
  p.max_history = 12;
  p.max_moments_history = 5;
  p.iterations = 5;
  p.sigma_depth = 1.0f;
  p.sigma_normal = 128.0f;
  p.sigma_luminance = 4.0f;
  p.reproject_normal_cos = 0.9f;
  p.reproject_depth_rel = 0.02f;
  p.variance_scale = 1.0f;
  return p;
}

// Radiance / albedo, guarded so that black albedo (emitters, pure black
// paint) neither divides by zero nor loses the radiance: modulation
// multiplies by the same guarded value.
TANDEM_HD Vec3 svgf_guard_albedo(Vec3 albedo) {
  const float kMin = 1e-3f;
  return make_vec3(max_f(albedo.x, kMin), max_f(albedo.y, kMin), max_f(albedo.z, kMin));
}

// exp(x) for x <= 0 to about 2e-6 relative, with plain arithmetic: the
// edge-stopping weights are most of the filter's cost, and libm's expf is
// several times slower (and not bit-equal between the CPU and the GPU).
TANDEM_HD float svgf_exp_neg(float x) {
  const float y = x * 1.44269504f;  // log2(e)
  if (!(y > -126.0f)) return 0.0f;
  // floor(y) by truncation (y <= 0 here): floorf is a library call on
  // baseline x86-64.
  int n = int(y);
  n -= float(n) > y ? 1 : 0;
  const float g = y - float(n) - 0.5f;
  // 2^g for g in [-0.5, 0.5): degree-5 Taylor polynomial, times 2^0.5.
  const float p =
      1.41421356f *
      (1.0f +
       g * (0.693147182f +
            g * (0.240226507f + g * (0.0555041087f + g * (0.00961812911f + g * 0.00133335581f)))));
  return p * uint_as_float(uint32_t(n + 127) << 23);
}

// x^n for a whole n by repeated squaring (the normal edge stop's exponent).
TANDEM_HD float svgf_pow_whole(float x, uint32_t n) {
  float r = 1.0f;
  while (n) {
    if (n & 1u) r *= x;
    x *= x;
    n >>= 1u;
  }
  return r;
}

// Depth slope of the current frame at (x, y): per axis the smaller one-sided
// difference to a neighbour on the same surface kind (so an edge does not
// count as slope), as a bound on how much depth may change per pixel.
TANDEM_HD Vec2 svgf_depth_slope(const PixelFeatures* features, uint32_t width, uint32_t height,
                                uint32_t x, uint32_t y) {
  const PixelFeatures& c = features[size_t(y) * width + x];
  float g[2] = {0.0f, 0.0f};
  for (int axis = 0; axis < 2; ++axis) {
    float best = kFloatMax;
    for (int s = -1; s <= 1; s += 2) {
      const int nx = int(x) + (axis == 0 ? s : 0), ny = int(y) + (axis == 1 ? s : 0);
      if (nx < 0 || ny < 0 || nx >= int(width) || ny >= int(height)) continue;
      const PixelFeatures& n = features[size_t(ny) * width + uint32_t(nx)];
      if (features_hit(n) != features_hit(c)) continue;
      best = min_f(best, fabsf(n.depth - c.depth));
    }
    g[axis] = best == kFloatMax ? 0.0f : best;
  }
  return make_vec2(g[0], g[1]);
}

// --- temporal accumulation ---------------------------------------------------

struct SvgfTemporalBuffers {
  const PixelFeatures* features;       // this frame
  const Vec3* radiance;                // this frame's noisy radiance
  const PixelFeatures* prev_features;  // last frame (null: no history)
  const Vec4* prev_color;              // last frame's history: illumination rgb
  const Vec4* prev_moments;            // last frame's (m1, m2, length, 0)
  Vec4* color;                         // out: illumination rgb, variance (temporal)
  Vec4* moments;                       // out: (m1, m2, length, 0)
  Vec2* depth_slope;                   // out: svgf_depth_slope per pixel, for the later stages
};

// Whether last frame's pixel `prev` shows the surface this frame's `cur` sees.
TANDEM_HD bool svgf_history_consistent(const SvgfParams& p, const PixelFeatures& cur,
                                       const PixelFeatures& prev, float depth_tolerance) {
  // Also: miss against hit. The material too: a light and the ceiling
  // around it are often one instance, with illumination orders of magnitude
  // apart, and bilinear taps at a fractional motion straddle their edge.
  if (cur.instance != prev.instance || cur.material != prev.material) return false;
  if (!features_hit(cur)) return true;  // environment on both
  if (fabsf(prev.depth - cur.prev_depth) > depth_tolerance) return false;
  return dot(prev.normal, cur.normal) >= p.reproject_normal_cos;
}

TANDEM_HD void svgf_temporal_pixel(const SvgfParams& p, const SvgfTemporalBuffers& b, uint32_t x,
                                   uint32_t y) {
  const size_t i = size_t(y) * p.width + x;
  const PixelFeatures& f = b.features[i];
  const Vec3 illum = b.radiance[i] / svgf_guard_albedo(f.albedo);
  const float lum = luminance(illum);

  Vec3 hist_color = make_vec3(0.0f);
  float hist_m1 = 0.0f, hist_m2 = 0.0f, hist_len = 0.0f, weight_sum = 0.0f;
  const Vec2 slope = svgf_depth_slope(b.features, p.width, p.height, x, y);
  b.depth_slope[i] = slope;
  if (b.prev_features) {
    const float tol = p.reproject_depth_rel * f.prev_depth + 2.0f * (slope.x + slope.y);
    // Previous position in pixel-index coordinates (centres at integers).
    const float qx = float(x) + f.motion.x, qy = float(y) + f.motion.y;
    if (qx > -1.0f && qy > -1.0f && qx < float(p.width) && qy < float(p.height)) {
      const int x0 = int(floorf(qx)), y0 = int(floorf(qy));
      const float fx = qx - float(x0), fy = qy - float(y0);
      // Bilinear taps; the inconsistent ones are left out and the rest
      // renormalised. No wider search: a pixel none of whose taps shows its
      // surface was just uncovered, and borrowing a neighbour's history
      // there is what leaves trails behind moving objects.
      for (int k = 0; k < 4; ++k) {
        const int tx = x0 + (k & 1), ty = y0 + (k >> 1);
        if (tx < 0 || ty < 0 || tx >= int(p.width) || ty >= int(p.height)) continue;
        const size_t j = size_t(ty) * p.width + uint32_t(tx);
        const float w = ((k & 1) ? fx : 1.0f - fx) * ((k >> 1) ? fy : 1.0f - fy);
        if (w <= 0.0f || !svgf_history_consistent(p, f, b.prev_features[j], tol)) continue;
        hist_color += xyz(b.prev_color[j]) * w;
        hist_m1 += b.prev_moments[j].x * w;
        hist_m2 += b.prev_moments[j].y * w;
        hist_len += b.prev_moments[j].z * w;
        weight_sum += w;
      }
    }
  }
  Vec3 color = illum;
  float m1 = lum, m2 = lum * lum, len = 1.0f;
  if (weight_sum > 1e-4f) {
    const float inv = 1.0f / weight_sum;
    hist_color *= inv;
    hist_m1 *= inv;
    hist_m2 *= inv;
    len = floorf(hist_len * inv + 0.5f) + 1.0f;
    const float a = 1.0f / min_f(len, float(p.max_history));
    const float am = 1.0f / min_f(len, float(p.max_moments_history));
    color = lerp_v(hist_color, illum, a);
    m1 = lerp_f(hist_m1, lum, am);
    m2 = lerp_f(hist_m2, lum * lum, am);
    len = min_f(len, 65535.0f);
  }
  b.color[i] = make_vec4(color, max_f(0.0f, m2 - m1 * m1) * p.variance_scale);
  b.moments[i] = make_vec4(m1, m2, len, 0.0f);
}

// --- edge-stopping weights -------------------------------------------------

// Weight of neighbour q for centre c at pixel offset (dx, dy), times
// exp(-extra) (the luminance term): 0 across a material or hit/miss
// boundary, falling off with depth beyond the local slope and with the
// angle between normals.
TANDEM_HD float svgf_edge_weight(const SvgfParams& p, const PixelFeatures& c,
                                 const PixelFeatures& q, Vec2 slope, int dx, int dy, float extra) {
  // Material boundaries are edges too: an emitter next to a wall (often one
  // mesh) differs in demodulated illumination by orders of magnitude.
  if (c.material != q.material) return 0.0f;  // also: hit against miss
  if (!features_hit(c)) return svgf_exp_neg(-extra);
  const float expected =
      p.sigma_depth * (slope.x * fabsf(float(dx)) + slope.y * fabsf(float(dy))) + 1e-3f * c.depth;
  const float wz = fabsf(c.depth - q.depth) / max_f(expected, 1e-8f);
  const float wn = svgf_pow_whole(max_f(0.0f, dot(c.normal, q.normal)), uint32_t(p.sigma_normal));
  return wn * svgf_exp_neg(-(wz + extra));
}

// --- variance --------------------------------------------------------------

struct SvgfVarianceBuffers {
  const PixelFeatures* features;
  const Vec2* depth_slope;  // from the temporal stage
  const Vec4* color;        // temporal output: illumination, temporal variance
  const Vec4* moments;      // temporal output: (m1, m2, length, 0)
  Vec4* out;                // illumination, variance
};

// Below this many frames of history the moments are too young to trust.
constexpr float kSvgfMinHistoryForVariance = 4.0f;

TANDEM_HD void svgf_variance_pixel(const SvgfParams& p, const SvgfVarianceBuffers& b, uint32_t x,
                                   uint32_t y) {
  const size_t i = size_t(y) * p.width + x;
  const Vec4 m = b.moments[i];
  if (m.z >= kSvgfMinHistoryForVariance) {
    b.out[i] = b.color[i];
    return;
  }
  // A spatial estimate over 7x7 pixels of the same surface, boosted while
  // the history is short so that the filter smooths harder there.
  const PixelFeatures& c = b.features[i];
  const Vec2 slope = b.depth_slope[i];
  float wsum = 0.0f, m1 = 0.0f, m2 = 0.0f;
  Vec3 col = make_vec3(0.0f);
  for (int dy = -3; dy <= 3; ++dy) {
    for (int dx = -3; dx <= 3; ++dx) {
      const int qx = int(x) + dx, qy = int(y) + dy;
      if (qx < 0 || qy < 0 || qx >= int(p.width) || qy >= int(p.height)) continue;
      const size_t j = size_t(qy) * p.width + uint32_t(qx);
      const float w =
          (dx == 0 && dy == 0) ? 1.0f : svgf_edge_weight(p, c, b.features[j], slope, dx, dy, 0.0f);
      if (w <= 0.0f) continue;
      m1 += b.moments[j].x * w;
      m2 += b.moments[j].y * w;
      col += xyz(b.color[j]) * w;
      wsum += w;
    }
  }
  const float inv = 1.0f / wsum;  // the centre's own weight is 1
  m1 *= inv;
  m2 *= inv;
  const float variance =
      max_f(0.0f, m2 - m1 * m1) * (kSvgfMinHistoryForVariance / m.z) * p.variance_scale;
  b.out[i] = make_vec4(col * inv, variance);
}

// --- a-trous ------------------------------------------------------------------

struct SvgfAtrousBuffers {
  const PixelFeatures* features;
  const Vec2* depth_slope;  // from the temporal stage
  const Vec4* in;           // illumination, variance
  Vec4* out;
};

TANDEM_HD float svgf_kernel_tap(int d) {
  // B3 spline (1/16, 1/4, 3/8, 1/4, 1/16).
  return d == 0 ? 0.375f : (d == 1 || d == -1 ? 0.25f : 0.0625f);
}

TANDEM_HD void svgf_atrous_pixel(const SvgfParams& p, const SvgfAtrousBuffers& b, uint32_t step,
                                 uint32_t x, uint32_t y) {
  const size_t i = size_t(y) * p.width + x;
  // Local copies: the compiler cannot know that b.out does not alias them.
  const PixelFeatures c = b.features[i];
  const Vec4 center = b.in[i];
  const float lum_c = luminance(xyz(center));
  // The luminance edge stop uses the variance blurred over 3x3 pixels: the
  // raw per-pixel estimate is itself noisy.
  float var_blur = 0.0f, var_w = 0.0f;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int qx = int(x) + dx, qy = int(y) + dy;
      if (qx < 0 || qy < 0 || qx >= int(p.width) || qy >= int(p.height)) continue;
      const float k = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
      var_blur += b.in[size_t(qy) * p.width + uint32_t(qx)].w * k;
      var_w += k;
    }
  }
  const float lum_scale = 1.0f / (p.sigma_luminance * safe_sqrt(var_blur / var_w) + 1e-10f);
  const Vec2 slope = b.depth_slope[i];

  Vec3 sum = xyz(center) * 0.140625f;  // centre tap: 3/8 * 3/8, weight 1
  float var_sum = center.w * 0.140625f * 0.140625f, wsum = 0.140625f;
  const int s = int(step);
  for (int ky = -2; ky <= 2; ++ky) {
    for (int kx = -2; kx <= 2; ++kx) {
      if (kx == 0 && ky == 0) continue;
      const int qx = int(x) + kx * s, qy = int(y) + ky * s;
      if (qx < 0 || qy < 0 || qx >= int(p.width) || qy >= int(p.height)) continue;
      const size_t j = size_t(qy) * p.width + uint32_t(qx);
      const PixelFeatures& fq = b.features[j];
      if (fq.material != c.material) continue;
      const Vec4 q = b.in[j];
      const float w = svgf_edge_weight(p, c, fq, slope, kx * s, ky * s,
                                       fabsf(luminance(xyz(q)) - lum_c) * lum_scale);
      if (w <= 0.0f) continue;
      const float h = svgf_kernel_tap(kx) * svgf_kernel_tap(ky) * w;
      sum += xyz(q) * h;
      var_sum += q.w * h * h;
      wsum += h;
    }
  }
  const float inv = 1.0f / wsum;
  b.out[i] = make_vec4(sum * inv, var_sum * inv * inv);
}

// Filtered illumination times albedo: the final radiance.
TANDEM_HD Vec3 svgf_modulate_pixel(const PixelFeatures& f, const Vec4& illumination) {
  return xyz(illumination) * svgf_guard_albedo(f.albedo);
}

}  // namespace tandem
