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
//   svgf_atrous_pixel     one a-trous iteration (3x3 or 5x5 taps, step
//                         2^i), weights stopped at depth, normal and
//                         luminance edges, luminance scaled by the
//                         variance; variance filtered alongside; the last
//                         iteration multiplies the albedo back in
//                         (svgf_modulate_pixel)
//
// The temporal stage also writes a compact guide per pixel (normal, depth,
// material: 20 bytes instead of the 64 of PixelFeatures) that the later
// stages read at every tap; that and the interior/border split of the
// a-trous loop (no bounds checks away from the image border) are most of
// the filter's speed.
//
// Filtering illumination (radiance / albedo) instead of radiance keeps
// texture detail sharp: the filter only has to smooth the lighting.
#pragma once

#include "core/kernel/features.h"

// The a-trous pixel function must be inlined into the CPU driver's row loop
// for that loop to vectorise; at -O3 GCC otherwise keeps it out of line.
// Its tap loops must be unrolled completely too (before the vectoriser
// runs, which takes only innermost loops).
#if defined(__CUDACC__)
#define TANDEM_SVGF_INLINE TANDEM_HD
#define TANDEM_SVGF_UNROLL _Pragma("unroll")
#elif defined(__GNUC__) && !defined(__clang__)
#define TANDEM_SVGF_INLINE inline __attribute__((always_inline))
#define TANDEM_SVGF_UNROLL _Pragma("GCC unroll 16")
#else
#define TANDEM_SVGF_INLINE TANDEM_HD
#define TANDEM_SVGF_UNROLL
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

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
  uint32_t kernel_radius;        // a-trous taps: 1 = 3x3 (1/4, 1/2, 1/4), 2 = 5x5 B3 spline
  // Firefly clamp: once a pixel has more than max_moments_history frames of
  // history, this frame's illumination luminance is clamped to the history
  // mean plus firefly_sigma standard deviations before it enters the history
  // (0: off). A 1-spp path sample is heavy-tailed; one caustic sample would
  // otherwise stay visible for max_history frames (and the a-trous filter
  // spreads it into a square). Measured on the arena: 3 lowers the denoised
  // relMSE at frame 30 of the scripted path from 0.29 to 0.016.
  float firefly_sigma;
};

TANDEM_HD SvgfParams svgf_default_params(uint32_t width, uint32_t height) {
  SvgfParams p;
  p.width = width;
  p.height = height;
  p.max_history = 12;
  p.max_moments_history = 5;
  // 4, not Schied et al.'s 5: on the arena's scripted path the fifth
  // iteration (taps 16 pixels apart) changes the denoised relMSE by less
  // than the frame-to-frame noise (0.0117 / 0.0196 / 0.0154 with 4 against
  // 0.0119 / 0.0196 / 0.0155 with 5 at frames 15 / 30 / 59; SSIM within
  // 0.001) and costs a fifth of the a-trous stage
  // (docs/performance/log/denoiser.md).
  p.iterations = 4;
  p.sigma_depth = 1.0f;
  p.sigma_normal = 128.0f;
  p.sigma_luminance = 4.0f;
  p.reproject_normal_cos = 0.9f;
  p.reproject_depth_rel = 0.02f;
  p.variance_scale = 1.0f;
  p.kernel_radius = 1;
  p.firefly_sigma = 3.0f;
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
// Branch-free, so that the CPU's a-trous loop over a row vectorises.
TANDEM_HD float svgf_exp_neg(float x) {
  // log2(e) x, clamped to the normal range; at the clamp (and for -inf)
  // the result is 0.
  const float y = max_f(x * 1.44269504f, -126.0f);
  const float in_range = y > -126.0f ? 1.0f : 0.0f;
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
  return in_range * p * uint_as_float(uint32_t(n + 127) << 23);
}

// Per-pixel guide of the spatial stages (from svgf_temporal_pixel).
struct SvgfGuide {
  Vec3 normal;  // 0 for a miss
  float depth;  // 0 for a miss
};

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
  SvgfGuide* guide;                    // out: normal and depth, for the later stages
  uint32_t* material;                  // out: material (kInvalidIndex: miss)
};

// The temporal stage's reads of this frame, one overload per buffer form
// (the CPU driver's, over planes, are in core/render/svgf_cpu.cpp): the
// pixel functions below are the same code for both.
TANDEM_HD const PixelFeatures& svgf_cur_pixel(const SvgfTemporalBuffers& b, size_t i) {
  return b.features[i];
}
TANDEM_HD Vec3 svgf_cur_radiance(const SvgfTemporalBuffers& b, size_t i) {
  return b.radiance[i];
}
TANDEM_HD float svgf_cur_depth(const SvgfTemporalBuffers& b, ptrdiff_t j) {
  return b.features[j].depth;
}
TANDEM_HD bool svgf_cur_hit(const SvgfTemporalBuffers& b, ptrdiff_t j) {
  return b.features[j].instance != kInvalidIndex;
}

// Depth slope of the current frame at (x, y): per axis the smaller one-sided
// difference to a neighbour on the same surface kind (so an edge does not
// count as slope), as a bound on how much depth may change per pixel.
// Branch-free (neighbours outside the image are read clamped and weigh
// nothing), so that the CPU's temporal row loop vectorises.
// kCheckBorder = false is for pixels not on the image's edge (the CPU
// driver's vectorised loop: neighbour addresses then follow the row).
template <bool kCheckBorder = true, class B>
TANDEM_SVGF_INLINE Vec2 svgf_depth_slope(const B& b, uint32_t width, uint32_t height, uint32_t x,
                                         uint32_t y) {
  const ptrdiff_t i = ptrdiff_t(y) * ptrdiff_t(width) + ptrdiff_t(x);
  const float depth = svgf_cur_depth(b, i);
  const bool hit = svgf_cur_hit(b, i);
  float g[2];
  TANDEM_SVGF_UNROLL
  for (int axis = 0; axis < 2; ++axis) {
    float best = kFloatMax;
    TANDEM_SVGF_UNROLL
    for (int s = -1; s <= 1; s += 2) {
      const int c = (axis == 0 ? int(x) : int(y)) + s;
      const int limit = axis == 0 ? int(width) : int(height);
      const bool inside = !kCheckBorder || (c >= 0 && c < limit);
      const ptrdiff_t step = axis == 0 ? 1 : ptrdiff_t(width);
      const ptrdiff_t j = i + (!kCheckBorder || inside ? ptrdiff_t(s) * step : 0);
      const bool same_kind = svgf_cur_hit(b, j) == hit;
      const float d = fabsf(svgf_cur_depth(b, j) - depth);
      best = inside && same_kind ? min_f(best, d) : best;
    }
    g[axis] = best == kFloatMax ? 0.0f : best;
  }
  return make_vec2(g[0], g[1]);
}

// What the reprojection test reads of last frame's pixel: the device reads
// it from last frame's feature records, the CPU driver from a compact guide
// (6 planes instead of 64-byte records at each of the 4 bilinear taps).
struct SvgfPrevSurface {
  Vec3 normal;
  float depth;
  uint32_t instance, material;
};
TANDEM_HD SvgfPrevSurface svgf_prev_surface(const PixelFeatures& f) {
  SvgfPrevSurface s;
  s.normal = make_vec3(f.normal.x, f.normal.y, f.normal.z);
  s.depth = f.depth;
  s.instance = f.instance;
  s.material = f.material;
  return s;
}

// Whether last frame's pixel `prev` shows the surface this frame's `cur` sees.
// 1 if so, else 0.
TANDEM_HD float svgf_history_consistent(const SvgfParams& p, const PixelFeatures& cur,
                                        const SvgfPrevSurface& prev, float depth_tolerance) {
  // Also: miss against hit. The material too: a light and the ceiling
  // around it are often one instance, with illumination orders of magnitude
  // apart, and bilinear taps at a fractional motion straddle their edge.
  // The environment on both is consistent. Float arithmetic on the tests,
  // not && and || (nor & and | on bools, which GCC turns back into
  // branches): no branches, and no loads under a condition (which the
  // CPU's vectorised row loop cannot gather).
  const float same_id =
      ((cur.instance == prev.instance) & (cur.material == prev.material)) ? 1.0f : 0.0f;
  // depth difference <= tolerance and cosine >= the threshold, both at once
  // (a - b <= 0 exactly when a <= b, for finite floats).
  const float surface_excess = max_f(fabsf(prev.depth - cur.prev_depth) - depth_tolerance,
                                     p.reproject_normal_cos - dot(prev.normal, cur.normal));
  const float same_surface = surface_excess <= 0.0f ? 1.0f : 0.0f;
  const float miss = features_hit(cur) ? 0.0f : 1.0f;
  return same_id * max_f(miss, same_surface);
}

// The temporal stage's reads of last frame and writes, one overload per
// buffer form (the CPU driver's are in core/render/svgf_cpu.cpp): the
// pixel function below is the same code for both.
TANDEM_HD SvgfPrevSurface svgf_prev_surface(const SvgfTemporalBuffers& b, int j) {
  return svgf_prev_surface(b.prev_features[j]);
}
TANDEM_HD void svgf_store_temporal(const SvgfTemporalBuffers& b, size_t i, const PixelFeatures& f,
                                   Vec2 slope, Vec4 color, Vec4 moments) {
  b.depth_slope[i] = slope;
  b.guide[i] = SvgfGuide{make_vec3(f.normal.x, f.normal.y, f.normal.z), f.depth};
  b.material[i] = f.material;
  b.color[i] = color;
  b.moments[i] = moments;
}

// floor(v) for |v| < 2^31 without a library call (floorf is one on
// baseline x86-64, and a call keeps a loop from vectorising).
TANDEM_HD int svgf_floor_int(float v) {
  const int n = int(v);
  return n - (float(n) > v ? 1 : 0);
}

// kCheckBorder: see svgf_depth_slope.
template <bool kHasHistory, bool kCheckBorder = true, class B>
TANDEM_SVGF_INLINE void svgf_temporal_pixel_h(const SvgfParams& p, const B& b, uint32_t x,
                                              uint32_t y) {
  const size_t i = size_t(y) * p.width + x;
  // A reference to the record, or (planes) to a temporary put together.
  const PixelFeatures& f = svgf_cur_pixel(b, i);
  Vec3 illum = svgf_cur_radiance(b, i) / svgf_guard_albedo(f.albedo);
  float lum = luminance(illum);

  Vec3 hist_color = make_vec3(0.0f);
  float hist_m1 = 0.0f, hist_m2 = 0.0f, hist_len = 0.0f, weight_sum = 0.0f;
  const Vec2 slope = svgf_depth_slope<kCheckBorder>(b, p.width, p.height, x, y);
  if (kHasHistory) {
    const float tol = p.reproject_depth_rel * f.prev_depth + 2.0f * (slope.x + slope.y);
    // Previous position in pixel-index coordinates (centres at integers).
    const float qx = float(x) + f.motion.x, qy = float(y) + f.motion.y;
    const bool inside = qx > -1.0f && qy > -1.0f && qx < float(p.width) && qy < float(p.height);
    // Clamped first, so that the conversion to int is defined for any
    // motion; inside the image this changes nothing.
    const int x0 = svgf_floor_int(min_f(max_f(qx, -2.0f), float(p.width) + 1.0f));
    const int y0 = svgf_floor_int(min_f(max_f(qy, -2.0f), float(p.height) + 1.0f));
    const float fx = qx - float(x0), fy = qy - float(y0);
    // Bilinear taps; the inconsistent ones are left out and the rest
    // renormalised. No wider search: a pixel none of whose taps shows its
    // surface was just uncovered, and borrowing a neighbour's history
    // there is what leaves trails behind moving objects. Taps outside the
    // image are read clamped and weigh nothing (no branches).
    TANDEM_SVGF_UNROLL
    for (int k = 0; k < 4; ++k) {
      const int tx = x0 + (k & 1), ty = y0 + (k >> 1);
      const bool tap_inside =
          inside & (tx >= 0) & (ty >= 0) & (tx < int(p.width)) & (ty < int(p.height));
      // Clamped, not selected: a select of the index becomes a select of
      // 64-bit addresses, which GCC's vectorised loop cannot gather from.
      const int cx = tx < 0 ? 0 : (tx >= int(p.width) ? int(p.width) - 1 : tx);
      const int cy = ty < 0 ? 0 : (ty >= int(p.height) ? int(p.height) - 1 : ty);
      // A 32-bit index (images have fewer than 2^31 pixels): the CPU's
      // vectorised loop gathers with 32-bit offsets.
      const int j = cy * int(p.width) + cx;
      const float bw = ((k & 1) ? fx : 1.0f - fx) * ((k >> 1) ? fy : 1.0f - fy);
      // bw >= 0: a tap of bilinear weight 0 adds nothing either way.
      const float w =
          (tap_inside ? bw : 0.0f) * svgf_history_consistent(p, f, svgf_prev_surface(b, j), tol);
      const Vec4 pc = b.prev_color[j], pm = b.prev_moments[j];
      hist_color += make_vec3(pc.x, pc.y, pc.z) * w;
      hist_m1 += pm.x * w;
      hist_m2 += pm.y * w;
      hist_len += pm.z * w;
      weight_sum += w;
    }
  }
  // With history (selects, not branches: the row loop vectorises).
  const bool has = weight_sum > 1e-4f;
  const float inv = 1.0f / max_f(weight_sum, 1e-4f);
  hist_color *= inv;
  hist_m1 *= inv;
  hist_m2 *= inv;
  // Rounded to the nearest integer (the argument is >= 0).
  const float hist_frames = float(int(hist_len * inv + 0.5f)) + 1.0f;
  // The firefly clamp (SvgfParams::firefly_sigma).
  const float limit =
      hist_m1 + p.firefly_sigma * safe_sqrt(max_f(0.0f, hist_m2 - hist_m1 * hist_m1));
  const bool clamp = has & (p.firefly_sigma > 0.0f) & (hist_frames > float(p.max_moments_history)) &
                     (lum > limit) & (lum > 0.0f);
  const float scale = clamp ? limit / max_f(lum, 1e-30f) : 1.0f;
  illum *= scale;
  lum = clamp ? limit : lum;
  const float a = 1.0f / min_f(hist_frames, float(p.max_history));
  const float am = 1.0f / min_f(hist_frames, float(p.max_moments_history));
  const Vec3 color = has ? lerp_v(hist_color, illum, a) : illum;
  const float m1 = has ? lerp_f(hist_m1, lum, am) : lum;
  const float m2 = has ? lerp_f(hist_m2, lum * lum, am) : lum * lum;
  const float len = has ? min_f(hist_frames, 65535.0f) : 1.0f;
  svgf_store_temporal(b, i, f, slope,
                      make_vec4(color, max_f(0.0f, m2 - m1 * m1) * p.variance_scale),
                      make_vec4(m1, m2, len, 0.0f));
}

TANDEM_SVGF_INLINE void svgf_temporal_pixel(const SvgfParams& p, const SvgfTemporalBuffers& b,
                                            uint32_t x, uint32_t y) {
  if (b.prev_features)
    svgf_temporal_pixel_h<true>(p, b, x, y);
  else
    svgf_temporal_pixel_h<false>(p, b, x, y);
}

// --- edge-stopping weights -------------------------------------------------

// Per-centre constants of the edge stops, so that a tap costs one
// multiplication per term instead of a division.
struct SvgfEdgeCenter {
  Vec3 normal;
  float depth;
  uint32_t material;
  float hit;  // 1 for a surface, 0 for the environment
  // 1 / the depth change expected at pixel offset (|dx|, |dy|) = (a, b)
  // along the local slope: inv_expected(a, b) = 1 / (sx * a + sy * b + floor).
  float sx, sy, floor_depth;
};

TANDEM_HD SvgfEdgeCenter svgf_edge_center(const SvgfParams& p, const SvgfGuide& g,
                                          uint32_t material, Vec2 slope) {
  SvgfEdgeCenter c;
  // Field by field: an aggregate copy keeps GCC from vectorising the
  // a-trous row loop.
  c.normal = make_vec3(g.normal.x, g.normal.y, g.normal.z);
  c.depth = g.depth;
  c.material = material;
  c.hit = material != kInvalidIndex ? 1.0f : 0.0f;
  c.sx = p.sigma_depth * slope.x;
  c.sy = p.sigma_depth * slope.y;
  c.floor_depth = 1e-3f * g.depth;
  return c;
}

TANDEM_HD float svgf_inv_expected_depth(const SvgfEdgeCenter& c, int adx, int ady) {
  // Every term is >= 0: an addition keeps it off zero without a select
  // (which GCC would turn into a branch around the division).
  return 1.0f / (c.sx * float(adx) + c.sy * float(ady) + c.floor_depth + 1e-8f);
}

// Exponent of the geometric edge stops of neighbour q (same material as
// the centre: the caller checks) given 1 / its expected depth change:
// growing with depth beyond the local slope and with the angle between
// normals. The normal term is sigma_normal * (1 - cos), i.e. the weight
// exp(-sigma_n (1 - cos)), which for the large exponents used equals
// Schied et al.'s max(0, cos)^sigma_n to within 1% of the weight wherever
// that weight exceeds 1e-3 (ln cos = cos - 1 + O((1 - cos)^2)); it costs no
// pow and shares one exp with the other terms. The environment (a miss)
// has neither term.
TANDEM_HD float svgf_geometry_exponent(const SvgfParams& p, const SvgfEdgeCenter& c,
                                       const SvgfGuide& q, float inv_expected) {
  const float wz = fabsf(c.depth - q.depth) * inv_expected;
  const float wn = p.sigma_normal * (1.0f - dot(c.normal, q.normal));
  // A product, not a select: GCC will not speculate the arithmetic of a
  // conditional arm, which would keep the row loop from vectorising. Both
  // terms are finite for a miss (its depth and normal are 0).
  return (wz + wn) * c.hit;
}
TANDEM_HD float svgf_guide_weight(const SvgfParams& p, const SvgfEdgeCenter& c, const SvgfGuide& q,
                                  float inv_expected, float extra) {
  return svgf_exp_neg(-(svgf_geometry_exponent(p, c, q, inv_expected) + extra));
}

// --- variance --------------------------------------------------------------

struct SvgfVarianceBuffers {
  const SvgfGuide* guide;  // from the temporal stage
  const uint32_t* material;
  const Vec2* depth_slope;
  const Vec4* color;    // temporal output: illumination, temporal variance
  const Vec4* moments;  // temporal output: (m1, m2, length, 0)
  Vec4* out;            // illumination, variance
};

// Structure-of-arrays form of the same inputs for the CPU driver: one
// plane per component, so that a row loop loads 8 neighbouring pixels'
// values with one vector load instead of de-interleaving 16-byte records
// (the CPU's vectorised tap loops spent more instructions on that than on
// the weights). The device reads the records (SvgfVarianceBuffers).
struct SvgfGuidePlanes {
  const float* normal_x;
  const float* normal_y;
  const float* normal_z;
  const float* depth;
  const uint32_t* material;
  const Vec2* depth_slope;  // per centre only: a record is fine
};
struct SvgfVariancePlanes {
  SvgfGuidePlanes guide;
  const float* r;  // temporal illumination
  const float* g;
  const float* b;
  const float* m1;  // temporal luminance moments
  const float* m2;
  const Vec4* moments;  // (m1, m2, length, 0), for the centre's history length
};

// Tap reads of the spatial stages, one overload per buffer form: the
// per-pixel functions below are the same code for both.
TANDEM_HD SvgfGuide svgf_tap_guide(const SvgfVarianceBuffers& b, ptrdiff_t j) {
  return b.guide[j];
}
TANDEM_HD SvgfGuide svgf_tap_guide(const SvgfGuidePlanes& g, ptrdiff_t j) {
  SvgfGuide q;
  q.normal = make_vec3(g.normal_x[j], g.normal_y[j], g.normal_z[j]);
  q.depth = g.depth[j];
  return q;
}
TANDEM_HD SvgfGuide svgf_tap_guide(const SvgfVariancePlanes& b, ptrdiff_t j) {
  return svgf_tap_guide(b.guide, j);
}
TANDEM_HD uint32_t svgf_tap_material(const SvgfVarianceBuffers& b, ptrdiff_t j) {
  return b.material[j];
}
TANDEM_HD uint32_t svgf_tap_material(const SvgfVariancePlanes& b, ptrdiff_t j) {
  return b.guide.material[j];
}
TANDEM_HD Vec2 svgf_tap_slope(const SvgfVarianceBuffers& b, ptrdiff_t j) {
  return b.depth_slope[j];
}
TANDEM_HD Vec2 svgf_tap_slope(const SvgfVariancePlanes& b, ptrdiff_t j) {
  return b.guide.depth_slope[j];
}
TANDEM_HD Vec3 svgf_tap_color(const SvgfVarianceBuffers& b, ptrdiff_t j) {
  return xyz(b.color[j]);
}
TANDEM_HD Vec3 svgf_tap_color(const SvgfVariancePlanes& b, ptrdiff_t j) {
  return make_vec3(b.r[j], b.g[j], b.b[j]);
}
// (m1, m2) of the luminance moments.
TANDEM_HD Vec2 svgf_tap_moments(const SvgfVarianceBuffers& b, ptrdiff_t j) {
  return make_vec2(b.moments[j].x, b.moments[j].y);
}
TANDEM_HD Vec2 svgf_tap_moments(const SvgfVariancePlanes& b, ptrdiff_t j) {
  return make_vec2(b.m1[j], b.m2[j]);
}

// Below this many frames of history the moments are too young to trust.
constexpr float kSvgfMinHistoryForVariance = 4.0f;

// The spatial estimate of svgf_variance_pixel for pixel (x, y) with
// `history` frames (< kSvgfMinHistoryForVariance): luminance moments over
// 7x7 pixels of the same surface, boosted while the history is short so
// that the filter smooths harder there. kCheckBounds = false is for pixels
// at least 3 away from every image border: then the loop has no branches
// (other surfaces weigh 0 by a product) and the CPU driver's row loop over
// a run of such pixels vectorises like the a-trous one.
template <bool kCheckBounds, class B>
TANDEM_SVGF_INLINE Vec4 svgf_variance_spatial(const SvgfParams& p, const B& b, int x, int y,
                                              float history) {
  const ptrdiff_t i = ptrdiff_t(y) * ptrdiff_t(p.width) + x;
  const int w = int(p.width), h = int(p.height);
  const SvgfEdgeCenter c =
      svgf_edge_center(p, svgf_tap_guide(b, i), svgf_tap_material(b, i), svgf_tap_slope(b, i));
  // 1 / expected depth change per |offset| (0..3 on each axis): 16
  // divisions per pixel instead of one per tap.
  float inv_exp[4][4];
  TANDEM_SVGF_UNROLL
  for (int a = 0; a < 4; ++a)
    TANDEM_SVGF_UNROLL
  for (int bb = 0; bb < 4; ++bb)
    inv_exp[a][bb] = svgf_inv_expected_depth(c, a, bb);
  // The centre's own weight is 1.
  const Vec2 cm = svgf_tap_moments(b, i);
  float wsum = 1.0f, m1 = cm.x, m2 = cm.y;
  Vec3 col = svgf_tap_color(b, i);
  TANDEM_SVGF_UNROLL
  for (int dy = -3; dy <= 3; ++dy) {
    TANDEM_SVGF_UNROLL
    for (int dx = -3; dx <= 3; ++dx) {
      if (dx == 0 && dy == 0) continue;
      const int qx = x + dx, qy = y + dy;
      if (kCheckBounds && (qx < 0 || qy < 0 || qx >= w || qy >= h)) continue;
      // Offsets from i (signed, affine in x): addresses the vectoriser can
      // follow along the row.
      const ptrdiff_t j = i + ptrdiff_t(dy) * ptrdiff_t(p.width) + dx;
      const float same = svgf_tap_material(b, j) == c.material ? 1.0f : 0.0f;
      const float wt =
          same * svgf_guide_weight(p, c, svgf_tap_guide(b, j),
                                   inv_exp[dx < 0 ? -dx : dx][dy < 0 ? -dy : dy], 0.0f);
      const Vec2 m = svgf_tap_moments(b, j);
      m1 += m.x * wt;
      m2 += m.y * wt;
      col += svgf_tap_color(b, j) * wt;
      wsum += wt;
    }
  }
  const float inv = 1.0f / wsum;
  m1 *= inv;
  m2 *= inv;
  const float variance =
      max_f(0.0f, m2 - m1 * m1) * (kSvgfMinHistoryForVariance / history) * p.variance_scale;
  return make_vec4(col * inv, variance);
}

TANDEM_HD void svgf_variance_pixel(const SvgfParams& p, const SvgfVarianceBuffers& b, uint32_t x,
                                   uint32_t y) {
  const size_t i = size_t(y) * p.width + x;
  const float history = b.moments[i].z;
  b.out[i] = history >= kSvgfMinHistoryForVariance
                 ? b.color[i]
                 : svgf_variance_spatial<true>(p, b, int(x), int(y), history);
}

// --- a-trous ------------------------------------------------------------------

struct SvgfAtrousBuffers {
  const SvgfGuide* guide;  // from the temporal stage
  const uint32_t* material;
  const Vec2* depth_slope;
  const Vec4* in;  // illumination, variance
};

// The CPU driver's structure-of-arrays form (see SvgfVariancePlanes).
struct SvgfAtrousPlanes {
  SvgfGuidePlanes guide;
  const float* r;  // illumination
  const float* g;
  const float* b;
  const float* var;  // its variance
};

TANDEM_HD SvgfGuide svgf_tap_guide(const SvgfAtrousBuffers& b, ptrdiff_t j) {
  return b.guide[j];
}
TANDEM_HD SvgfGuide svgf_tap_guide(const SvgfAtrousPlanes& b, ptrdiff_t j) {
  return svgf_tap_guide(b.guide, j);
}
TANDEM_HD uint32_t svgf_tap_material(const SvgfAtrousBuffers& b, ptrdiff_t j) {
  return b.material[j];
}
TANDEM_HD uint32_t svgf_tap_material(const SvgfAtrousPlanes& b, ptrdiff_t j) {
  return b.guide.material[j];
}
TANDEM_HD Vec2 svgf_tap_slope(const SvgfAtrousBuffers& b, ptrdiff_t j) {
  return b.depth_slope[j];
}
TANDEM_HD Vec2 svgf_tap_slope(const SvgfAtrousPlanes& b, ptrdiff_t j) {
  return b.guide.depth_slope[j];
}
TANDEM_HD Vec3 svgf_tap_color(const SvgfAtrousBuffers& b, ptrdiff_t j) {
  return xyz(b.in[j]);
}
TANDEM_HD Vec3 svgf_tap_color(const SvgfAtrousPlanes& b, ptrdiff_t j) {
  return make_vec3(b.r[j], b.g[j], b.b[j]);
}
TANDEM_HD float svgf_tap_variance(const SvgfAtrousBuffers& b, ptrdiff_t j) {
  return b.in[j].w;
}
TANDEM_HD float svgf_tap_variance(const SvgfAtrousPlanes& b, ptrdiff_t j) {
  return b.var[j];
}

// 1D kernel taps: radius 1 (1/4, 1/2, 1/4); radius 2 the B3 spline
// (1/16, 1/4, 3/8, 1/4, 1/16).
TANDEM_HD float svgf_kernel_tap(uint32_t radius, int d) {
  const int a = d < 0 ? -d : d;
  if (radius <= 1) return a == 0 ? 0.5f : 0.25f;
  return a == 0 ? 0.375f : (a == 1 ? 0.25f : 0.0625f);
}

// Which taps of an a-trous pixel are inside the image, for a run of pixels
// near the border where that is the same for every pixel of the run (the
// CPU driver splits rows at the pixels where a tap crosses the border):
// a tap outside is read at offset 0 (the centre's row or column, always
// inside) and weighs 0, so the run's loop has no branches and vectorises
// like the interior one. Indexed by tap + 2 (radius <= 2).
struct SvgfTapMask {
  float ok_x[5], ok_y[5];  // 1 inside, 0 outside
  int off_x[5];            // pixel offset of the tap column: kx * step inside, else 0
  int off_y[5];            // the same for the tap row (in rows)
};

// How svgf_atrous_pixel_core treats the image border.
enum SvgfBorderMode : int {
  kSvgfUnchecked = 0,  // pixel at least R * step + 1 away from every border
  kSvgfChecked = 1,    // any pixel: taps outside are skipped (branches)
  kSvgfMasked = 2,     // taps outside given by a SvgfTapMask; pixel not on the image's edge
};

// One a-trous iteration at (x, y) with tap spacing `step` and a kernel of
// radius R (svgf_kernel_tap); returns the filtered illumination and its
// variance. kSvgfUnchecked and kSvgfMasked are for the CPU driver's row
// loops, which the compiler vectorises (no branches on pixel data, only
// selects); the device always checks. All three give the same result.
template <int kMode, int R, class B>
TANDEM_SVGF_INLINE Vec4 svgf_atrous_pixel_core(const SvgfParams& p, const B& b, uint32_t step,
                                               int x, int y, const SvgfTapMask* mask) {
  constexpr bool kCheckBounds = kMode == kSvgfChecked;
  // Signed pixel indices: an unsigned one may wrap, and the vectoriser
  // then cannot follow the addresses along the row.
  const ptrdiff_t i = ptrdiff_t(y) * ptrdiff_t(p.width) + x;
  const int w = int(p.width), h = int(p.height);
  const SvgfEdgeCenter c =
      svgf_edge_center(p, svgf_tap_guide(b, i), svgf_tap_material(b, i), svgf_tap_slope(b, i));
  const Vec3 center = svgf_tap_color(b, i);
  const float center_var = svgf_tap_variance(b, i);
  const float lum_c = luminance(center);
  // The luminance edge stop uses the variance blurred over 3x3 pixels: the
  // raw per-pixel estimate is itself noisy.
  float var_blur = 0.0f, var_w = 0.0f;
  TANDEM_SVGF_UNROLL
  for (int dy = -1; dy <= 1; ++dy) {
    TANDEM_SVGF_UNROLL
    for (int dx = -1; dx <= 1; ++dx) {
      const int qx = x + dx, qy = y + dy;
      if (kCheckBounds && (qx < 0 || qy < 0 || qx >= w || qy >= h)) continue;
      const float k = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
      // Offsets from i (signed, affine in x) rather than (qy * width + qx):
      // the vectoriser needs addresses it can follow along the row.
      var_blur += svgf_tap_variance(b, ptrdiff_t(i) + ptrdiff_t(dy) * ptrdiff_t(p.width) + dx) * k;
      var_w += k;
    }
  }
  const float lum_scale = 1.0f / (p.sigma_luminance * safe_sqrt(var_blur / var_w) + 1e-10f);
  // 1 / expected depth change per |offset| in taps (0..R on each axis).
  float inv_exp[R + 1][R + 1];
  const int s = int(step);
  TANDEM_SVGF_UNROLL
  for (int a = 0; a <= R; ++a)
    TANDEM_SVGF_UNROLL
  for (int bb = 0; bb <= R; ++bb)
    inv_exp[a][bb] = svgf_inv_expected_depth(c, a * s, bb * s);

  const float k0 = svgf_kernel_tap(R, 0);
  Vec3 sum = center * (k0 * k0);  // centre tap, edge weight 1
  float var_sum = center_var * (k0 * k0) * (k0 * k0), wsum = k0 * k0;
  TANDEM_SVGF_UNROLL
  for (int ky = -R; ky <= R; ++ky) {
    const int qy = y + ky * s;
    if (kCheckBounds && (qy < 0 || qy >= h)) continue;
    const float tap_y = svgf_kernel_tap(R, ky) * (kMode == kSvgfMasked ? mask->ok_y[ky + 2] : 1.0f);
    const int row_offset = kMode == kSvgfMasked ? mask->off_y[ky + 2] : ky * s;
    const ptrdiff_t row = ptrdiff_t(i) + ptrdiff_t(row_offset) * ptrdiff_t(p.width);
    TANDEM_SVGF_UNROLL
    for (int kx = -R; kx <= R; ++kx) {
      if (kx == 0 && ky == 0) continue;
      const int qx = x + kx * s;
      if (kCheckBounds && (qx < 0 || qx >= w)) continue;
      const ptrdiff_t j = row + (kMode == kSvgfMasked ? mask->off_x[kx + 2] : kx * s);
      const Vec3 q = svgf_tap_color(b, j);
      // Another material (also: hit against miss) weighs nothing.
      const float same = svgf_tap_material(b, j) == c.material ? 1.0f : 0.0f;
      const float e = same * svgf_guide_weight(p, c, svgf_tap_guide(b, j),
                                               inv_exp[kx < 0 ? -kx : kx][ky < 0 ? -ky : ky],
                                               fabsf(luminance(q) - lum_c) * lum_scale);
      const float tap_x =
          svgf_kernel_tap(R, kx) * (kMode == kSvgfMasked ? mask->ok_x[kx + 2] : 1.0f);
      const float hw = tap_x * tap_y * e;
      sum += q * hw;
      var_sum += svgf_tap_variance(b, j) * hw * hw;
      wsum += hw;
    }
  }
  const float inv = 1.0f / wsum;
  return make_vec4(sum * inv, var_sum * inv * inv);
}

template <bool kCheckBounds, int R, class B>
TANDEM_SVGF_INLINE Vec4 svgf_atrous_pixel_r(const SvgfParams& p, const B& b, uint32_t step, int x,
                                            int y) {
  return svgf_atrous_pixel_core < kCheckBounds ? kSvgfChecked : kSvgfUnchecked,
         R > (p, b, step, x, y, nullptr);
}

template <bool kCheckBounds>
TANDEM_HD Vec4 svgf_atrous_pixel(const SvgfParams& p, const SvgfAtrousBuffers& b, uint32_t step,
                                 uint32_t x, uint32_t y) {
  return p.kernel_radius <= 1 ? svgf_atrous_pixel_r<kCheckBounds, 1>(p, b, step, int(x), int(y))
                              : svgf_atrous_pixel_r<kCheckBounds, 2>(p, b, step, int(x), int(y));
}

// Filtered illumination times albedo: the final radiance.
TANDEM_HD Vec3 svgf_modulate_pixel(const PixelFeatures& f, const Vec4& illumination) {
  return xyz(illumination) * svgf_guard_albedo(f.albedo);
}

TANDEM_KERNEL_END
}  // namespace tandem
