#include "core/render/svgf_cpu.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Every row kernel below exists twice: compiled for baseline x86-64 (SSE2:
// 4 floats per vector instruction) and, where GCC or Clang can target it,
// for AVX2 + FMA (8 floats, fused multiply-adds), chosen at run time by
// what the CPU supports. The build itself stays baseline, so the binary
// runs on any x86-64. Both clones compile the same always-inlined body (the
// per-pixel functions of svgf.h), so they differ only in float rounding
// (FMA contraction, the order of the vector reductions).
#if defined(__x86_64__) && defined(__GNUC__)
#define TANDEM_SVGF_HAVE_AVX2 1
#define TANDEM_SVGF_AVX2 __attribute__((target("avx2,fma")))
#else
#define TANDEM_SVGF_HAVE_AVX2 0
#define TANDEM_SVGF_AVX2
#endif

// "No loop-carried dependences" for the vectoriser (see variance_run_body).
#if defined(__GNUC__) && !defined(__clang__)
#define TANDEM_SVGF_IVDEP _Pragma("GCC ivdep")
#else
#define TANDEM_SVGF_IVDEP
#endif

template <class F>
double for_each_row(uint32_t height, const F& f) {
  const auto start = Clock::now();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, height, 4),
                    [&](const tbb::blocked_range<uint32_t>& rows) {
                      for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                        f(int(y));
                    });
  return seconds_since(start);
}

// --- the planes ----------------------------------------------------------------

// The structure-of-arrays work space (SvgfFrame::planes): the guide and the
// temporal illumination and moments that the spatial variance reads at its
// taps, and two sets of illumination + variance planes that the a-trous
// iterations ping-pong between.
enum SvgfPlane : size_t {
  kNormalX,
  kNormalY,
  kNormalZ,
  kDepth,
  kTemporalR,
  kTemporalG,
  kTemporalB,
  kM1,
  kM2,
  kIllumA,  // r, g, b, variance
  kIllumB = kIllumA + 4,
  kPlaneCount = kIllumB + 4
};

struct IllumPlanes {
  float* r;
  float* g;
  float* b;
  float* var;
};

IllumPlanes illum_planes(float* planes, size_t n, size_t first) {
  return IllumPlanes{planes + first * n, planes + (first + 1) * n, planes + (first + 2) * n,
                     planes + (first + 3) * n};
}

// --- row bodies (always inlined into both clones) -------------------------

// One row of the temporal stage: the branch-free pixel function in a loop
// the compiler vectorises (gathers for the bilinear taps), restrict
// pointers as in atrous_interior_body. Then the row's guide, illumination
// and moments are copied into their planes for the spatial stages (while
// they are in the cache).
template <bool kHasHistory>
TANDEM_SVGF_INLINE void temporal_row_body(
    const SvgfParams& params, const PixelFeatures* __restrict features,
    const Vec3* __restrict radiance, const PixelFeatures* __restrict prev_features,
    const Vec4* __restrict prev_color, const Vec4* __restrict prev_moments, Vec4* __restrict color,
    Vec4* __restrict moments, Vec2* __restrict depth_slope, SvgfGuide* __restrict guide,
    uint32_t* __restrict material, float* __restrict planes, int y) {
  const SvgfParams p = params;
  const SvgfTemporalBuffers tb{features, radiance, prev_features, prev_color, prev_moments,
                               color,    moments,  depth_slope,   guide,      material};
  for (uint32_t x = 0; x < p.width; ++x)
    svgf_temporal_pixel_h<kHasHistory>(p, tb, x, uint32_t(y));
  const size_t n = size_t(p.width) * p.height, row = size_t(y) * p.width;
  float* __restrict nx = planes + kNormalX * n;
  float* __restrict ny = planes + kNormalY * n;
  float* __restrict nz = planes + kNormalZ * n;
  float* __restrict depth = planes + kDepth * n;
  float* __restrict r = planes + kTemporalR * n;
  float* __restrict g = planes + kTemporalG * n;
  float* __restrict b = planes + kTemporalB * n;
  float* __restrict m1 = planes + kM1 * n;
  float* __restrict m2 = planes + kM2 * n;
  for (size_t i = row; i < row + p.width; ++i) {
    nx[i] = guide[i].normal.x;
    ny[i] = guide[i].normal.y;
    nz[i] = guide[i].normal.z;
    depth[i] = guide[i].depth;
    r[i] = color[i].x;
    g[i] = color[i].y;
    b[i] = color[i].z;
    m1[i] = moments[i].x;
    m2[i] = moments[i].y;
  }
}

TANDEM_SVGF_INLINE void store(const IllumPlanes& out, size_t i, const Vec4& v) {
  out.r[i] = v.x;
  out.g[i] = v.y;
  out.b[i] = v.z;
  out.var[i] = v.w;
}

// Spatial variance of the pixels [x0, x1) of row y, all at least 3 from
// every border: the unchecked, branch-free function in a loop the compiler
// vectorises. The plane pointers are members of structures, where restrict
// does not reach: ivdep tells the vectoriser that the outputs alias no
// input (it would otherwise give up on the run-time checks of so many
// streams).
TANDEM_SVGF_INLINE void variance_run_body(const SvgfParams& params, const SvgfVariancePlanes& vp,
                                          const IllumPlanes& out, int y, int x0, int x1) {
  const SvgfParams p = params;
  const SvgfVariancePlanes b = vp;
  const IllumPlanes o = out;
  const size_t row = size_t(y) * p.width;
  TANDEM_SVGF_IVDEP
  for (int x = x0; x < x1; ++x)
    store(o, row + size_t(x),
          svgf_variance_spatial<false>(p, b, x, y, b.moments[row + size_t(x)].z));
}

// One row of the variance stage: the temporal estimate is copied where the
// history is long enough; the runs of short-history pixels (disocclusions,
// every pixel of a first frame) get the spatial estimate, through the
// vectorised run loop away from the border.
using VarianceRunFn = void (*)(const SvgfParams&, const SvgfVariancePlanes&, const IllumPlanes&,
                               int y, int x0, int x1);

TANDEM_SVGF_INLINE void variance_row_body(const SvgfParams& p, const SvgfVariancePlanes& vp,
                                          const Vec4* color, const IllumPlanes& out, int y,
                                          VarianceRunFn run) {
  const int w = int(p.width), h = int(p.height);
  const size_t row = size_t(y) * p.width;
  const bool border_row = y < 3 || y + 3 >= h;
  int x = 0;
  while (x < w) {
    const float history = vp.moments[row + size_t(x)].z;
    if (history >= kSvgfMinHistoryForVariance) {
      store(out, row + size_t(x), color[row + size_t(x)]);
      ++x;
      continue;
    }
    int end = x + 1;
    while (end < w && vp.moments[row + size_t(end)].z < kSvgfMinHistoryForVariance)
      ++end;
    // [x, end) needs the spatial estimate; its interior part [a, b) is 3
    // from the left and right borders.
    const int a = border_row ? end : std::max(x, 3), b = border_row ? end : std::min(end, w - 3);
    for (int q = x; q < std::min(a, end); ++q)
      store(out, row + size_t(q),
            svgf_variance_spatial<true>(p, vp, q, y, vp.moments[row + size_t(q)].z));
    if (a < b) run(p, vp, out, y, a, b);
    for (int q = std::max(a, b); q < end; ++q)
      store(out, row + size_t(q),
            svgf_variance_spatial<true>(p, vp, q, y, vp.moments[row + size_t(q)].z));
    x = end;
  }
}

// One row's interior [x0, x1) of an a-trous iteration: the unchecked
// pixel function in a loop the compiler vectorises (ivdep as in
// variance_run_body).
template <int R>
TANDEM_SVGF_INLINE void atrous_interior_body(const SvgfParams& params, const SvgfAtrousPlanes& in,
                                             uint32_t step, int y, int x0, int x1,
                                             const IllumPlanes& out) {
  const SvgfParams p = params;
  const SvgfAtrousPlanes ab = in;
  const IllumPlanes o = out;
  const size_t row = size_t(y) * p.width;
  TANDEM_SVGF_IVDEP
  for (int x = x0; x < x1; ++x)
    store(o, row + size_t(x), svgf_atrous_pixel_r<false, R>(p, ab, step, x, y));
}

// Pixels [x0, x1) of an a-trous row near the border, all with the taps
// inside that `mask` says: the branch-free masked pixel function in a loop
// the compiler vectorises (ivdep as in variance_run_body).
template <int R>
TANDEM_SVGF_INLINE void atrous_masked_body(const SvgfParams& params, const SvgfAtrousPlanes& in,
                                           uint32_t step, int y, int x0, int x1,
                                           const IllumPlanes& out, const SvgfTapMask& tap_mask) {
  const SvgfParams p = params;
  const SvgfAtrousPlanes ab = in;
  const IllumPlanes o = out;
  const SvgfTapMask mask = tap_mask;
  const size_t row = size_t(y) * p.width;
  TANDEM_SVGF_IVDEP
  for (int x = x0; x < x1; ++x)
    store(o, row + size_t(x), svgf_atrous_pixel_core<kSvgfMasked, R>(p, ab, step, x, y, &mask));
}

// Pixels [x0, x1) of an a-trous row through the checked pixel function.
template <int R>
TANDEM_SVGF_INLINE void atrous_checked_body(const SvgfParams& p, const SvgfAtrousPlanes& ab,
                                            uint32_t step, const IllumPlanes& out, int y, int x0,
                                            int x1) {
  for (int x = x0; x < x1; ++x)
    store(out, size_t(y) * p.width + size_t(x), svgf_atrous_pixel_r<true, R>(p, ab, step, x, y));
}

// One a-trous row. The pixels where some tap falls outside the image come
// in runs with the same taps outside (a row is split where x + kx * step
// crosses 0 or the width); those runs go through atrous_masked_body, the
// interior through atrous_interior_body, both vectorised. Only the image's
// edge pixels (first and last row and column, where the 3x3 variance blur
// leaves the image too) take the checked pixel function. `history` (the
// first iteration) also receives the row as records, the next frame's
// colour history. (No lambdas in the row bodies: a lambda is a function of
// its own, compiled for the baseline target even inside an AVX2 clone.)
template <int R>
using AtrousInteriorFn = void (*)(const SvgfParams&, const SvgfAtrousPlanes&, uint32_t step, int y,
                                  int x0, int x1, const IllumPlanes&);
template <int R>
using AtrousMaskedFn = void (*)(const SvgfParams&, const SvgfAtrousPlanes&, uint32_t step, int y,
                                int x0, int x1, const IllumPlanes&, const SvgfTapMask&);

template <int R>
TANDEM_SVGF_INLINE void atrous_row_body(const SvgfParams& p, const SvgfAtrousPlanes& ab,
                                        uint32_t step, const IllumPlanes& out, Vec4* history, int y,
                                        AtrousInteriorFn<R> interior, AtrousMaskedFn<R> masked) {
  const int s = int(step);
  const int w = int(p.width), h = int(p.height);
  if (y == 0 || y + 1 >= h || w < 3) {
    atrous_checked_body<R>(p, ab, step, out, y, 0, w);
  } else {
    SvgfTapMask mask{};
    bool rows_inside = true;
    for (int k = -R; k <= R; ++k) {
      const bool inside = y + k * s >= 0 && y + k * s < h;
      mask.ok_y[k + 2] = inside ? 1.0f : 0.0f;
      mask.off_y[k + 2] = inside ? k * s : 0;
      rows_inside = rows_inside && inside;
    }
    // Split points of [1, w - 1): where a tap column enters or leaves.
    int cuts[2 * R + 2];
    int n_cuts = 0;
    cuts[n_cuts++] = w - 1;
    for (int k = 1; k <= R; ++k) {
      cuts[n_cuts++] = std::clamp(k * s, 1, w - 1);
      cuts[n_cuts++] = std::clamp(w - k * s, 1, w - 1);
    }
    std::sort(cuts, cuts + n_cuts);
    atrous_checked_body<R>(p, ab, step, out, y, 0, 1);
    int x0 = 1;
    for (int c = 0; c < n_cuts; ++c) {
      const int x1 = cuts[c];
      if (x1 <= x0) continue;
      bool inside_all = rows_inside;
      for (int k = -R; k <= R; ++k) {
        // The same for every x of [x0, x1).
        const bool inside = x0 + k * s >= 0 && x0 + k * s < w;
        mask.ok_x[k + 2] = inside ? 1.0f : 0.0f;
        mask.off_x[k + 2] = inside ? k * s : 0;
        inside_all = inside_all && inside;
      }
      if (inside_all)
        interior(p, ab, step, y, x0, x1, out);
      else
        masked(p, ab, step, y, x0, x1, out, mask);
      x0 = x1;
    }
    atrous_checked_body<R>(p, ab, step, out, y, w - 1, w);
  }
  if (history) {
    const size_t row = size_t(y) * p.width;
    for (size_t i = row; i < row + p.width; ++i)
      history[i] = make_vec4(out.r[i], out.g[i], out.b[i], out.var[i]);
  }
}

// --- the clones ---------------------------------------------------------------

// The row kernels of one instruction set.
struct SvgfRowKernels {
  void (*temporal)(const SvgfParams&, const SvgfTemporalBuffers&, float* planes, int y);
  void (*variance)(const SvgfParams&, const SvgfVariancePlanes&, const Vec4* color,
                   const IllumPlanes& out, int y);
  void (*atrous[2])(const SvgfParams&, const SvgfAtrousPlanes&, uint32_t step,
                    const IllumPlanes& out, Vec4* history, int y);  // R = 1, 2
};

// The run loops (temporal, variance, a-trous interior) are functions of
// their own: inlined into the row function, GCC loses the no-alias facts
// and gives up vectorising.
#define TANDEM_SVGF_ROW_KERNELS(suffix, target)                                                    \
  template <bool kHasHistory>                                                                      \
  target __attribute__((noinline)) void temporal_run_##suffix(                                     \
      const SvgfParams& p, const PixelFeatures* __restrict features,                               \
      const Vec3* __restrict radiance, const PixelFeatures* __restrict prev_features,              \
      const Vec4* __restrict prev_color, const Vec4* __restrict prev_moments,                      \
      Vec4* __restrict color, Vec4* __restrict moments, Vec2* __restrict depth_slope,              \
      SvgfGuide* __restrict guide, uint32_t* __restrict material, float* __restrict planes,        \
      int y) {                                                                                     \
    temporal_row_body<kHasHistory>(p, features, radiance, prev_features, prev_color, prev_moments, \
                                   color, moments, depth_slope, guide, material, planes, y);       \
  }                                                                                                \
  void temporal_row_##suffix(const SvgfParams& p, const SvgfTemporalBuffers& b, float* planes,     \
                             int y) {                                                              \
    (b.prev_features ? temporal_run_##suffix<true>                                                 \
                     : temporal_run_##suffix<false>)(p, b.features, b.radiance, b.prev_features,   \
                                                     b.prev_color, b.prev_moments, b.color,        \
                                                     b.moments, b.depth_slope, b.guide,            \
                                                     b.material, planes, y);                       \
  }                                                                                                \
  target __attribute__((noinline)) void variance_run_##suffix(                                     \
      const SvgfParams& p, const SvgfVariancePlanes& vp, const IllumPlanes& out, int y, int x0,    \
      int x1) {                                                                                    \
    variance_run_body(p, vp, out, y, x0, x1);                                                      \
  }                                                                                                \
  target void variance_row_##suffix(const SvgfParams& p, const SvgfVariancePlanes& vp,             \
                                    const Vec4* color, const IllumPlanes& out, int y) {            \
    variance_row_body(p, vp, color, out, y, variance_run_##suffix);                                \
  }                                                                                                \
  template <int R>                                                                                 \
  target __attribute__((noinline)) void atrous_interior_##suffix(                                  \
      const SvgfParams& p, const SvgfAtrousPlanes& in, uint32_t step, int y, int x0, int x1,       \
      const IllumPlanes& out) {                                                                    \
    atrous_interior_body<R>(p, in, step, y, x0, x1, out);                                          \
  }                                                                                                \
  template <int R>                                                                                 \
  target __attribute__((noinline)) void atrous_masked_##suffix(                                    \
      const SvgfParams& p, const SvgfAtrousPlanes& in, uint32_t step, int y, int x0, int x1,       \
      const IllumPlanes& out, const SvgfTapMask& mask) {                                           \
    atrous_masked_body<R>(p, in, step, y, x0, x1, out, mask);                                      \
  }                                                                                                \
  template <int R>                                                                                 \
  target void atrous_row_##suffix(const SvgfParams& p, const SvgfAtrousPlanes& ab, uint32_t step,  \
                                  const IllumPlanes& out, Vec4* history, int y) {                  \
    atrous_row_body<R>(p, ab, step, out, history, y, atrous_interior_##suffix<R>,                  \
                       atrous_masked_##suffix<R>);                                                 \
  }                                                                                                \
  const SvgfRowKernels kRowKernels_##suffix = {temporal_row_##suffix,                              \
                                               variance_row_##suffix,                              \
                                               {atrous_row_##suffix<1>, atrous_row_##suffix<2>}};

TANDEM_SVGF_ROW_KERNELS(baseline, )
#if TANDEM_SVGF_HAVE_AVX2
TANDEM_SVGF_ROW_KERNELS(avx2, TANDEM_SVGF_AVX2)
#endif

bool cpu_has_avx2() {
#if TANDEM_SVGF_HAVE_AVX2
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

// kAuto: AVX2 where the CPU has it, unless TANDEM_SVGF_ISA=baseline (to
// measure the baseline loops on an AVX2 machine).
SvgfCpuIsa resolve_isa(SvgfCpuIsa isa) {
  if (isa == SvgfCpuIsa::kAvx2 && !cpu_has_avx2())
    throw std::invalid_argument("svgf_run_cpu: AVX2 + FMA requested on a CPU without them");
  if (isa != SvgfCpuIsa::kAuto) return isa;
  static const bool forced_baseline = [] {
    const char* v = std::getenv("TANDEM_SVGF_ISA");
    return v && std::string(v) == "baseline";
  }();
  return cpu_has_avx2() && !forced_baseline ? SvgfCpuIsa::kAvx2 : SvgfCpuIsa::kBaseline;
}

const SvgfRowKernels& row_kernels(SvgfCpuIsa isa) {
#if TANDEM_SVGF_HAVE_AVX2
  if (isa == SvgfCpuIsa::kAvx2) return kRowKernels_avx2;
#endif
  return kRowKernels_baseline;
}

}  // namespace

bool svgf_cpu_avx2_supported() {
  return cpu_has_avx2();
}

SvgfCpuIsa svgf_cpu_isa(SvgfCpuIsa isa) {
  return resolve_isa(isa);
}

const char* svgf_cpu_isa_name(SvgfCpuIsa isa) {
  switch (isa) {
    case SvgfCpuIsa::kAuto:
      return "auto";
    case SvgfCpuIsa::kBaseline:
      return "baseline x86-64";
    case SvgfCpuIsa::kAvx2:
      return "avx2+fma";
  }
  return "?";
}

size_t svgf_cpu_plane_floats(uint32_t width, uint32_t height) {
  return kPlaneCount * size_t(width) * height;
}

SvgfStageSeconds svgf_run_cpu(const SvgfParams& p, const SvgfFrame& fr, SvgfCpuIsa isa) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const SvgfRowKernels& k = row_kernels(resolve_isa(isa));
  std::vector<float> own_planes;
  float* planes = fr.planes;
  if (!planes) {
    own_planes.resize(svgf_cpu_plane_floats(p.width, p.height));
    planes = own_planes.data();
  }
  const SvgfTemporalBuffers tb{fr.features,     fr.radiance,  fr.prev_features, fr.prev_color,
                               fr.prev_moments, fr.scratch_a, fr.moments_out,   fr.depth_slope,
                               fr.guide,        fr.material};
  t.temporal = for_each_row(p.height, [&](int y) { k.temporal(p, tb, planes, y); });
  const SvgfGuidePlanes guide{planes + kNormalX * n, planes + kNormalY * n, planes + kNormalZ * n,
                              planes + kDepth * n,   fr.material,           fr.depth_slope};
  const SvgfVariancePlanes vp{guide,
                              planes + kTemporalR * n,
                              planes + kTemporalG * n,
                              planes + kTemporalB * n,
                              planes + kM1 * n,
                              planes + kM2 * n,
                              fr.moments_out};
  const IllumPlanes pa = illum_planes(planes, n, kIllumA), pb = illum_planes(planes, n, kIllumB);
  t.variance = for_each_row(p.height, [&](int y) { k.variance(p, vp, fr.scratch_a, pa, y); });
  // pa holds the input of the first iteration; the first iteration's
  // output is also written as records: the next frame's colour history.
  IllumPlanes in = pa;
  const auto atrous_start = Clock::now();
  if (p.iterations == 0) {
    for (size_t i = 0; i < n; ++i)
      fr.history_color_out[i] = make_vec4(pa.r[i], pa.g[i], pa.b[i], pa.var[i]);
  }
  const auto atrous = k.atrous[p.kernel_radius <= 1 ? 0 : 1];
  // Modulation stays a pass of its own: fused into the last iteration, the
  // albedo read from the 64-byte feature records inside the vectorised loop
  // cost more than the pass (callgrind, 640x360: about 80 M instructions a
  // frame more in the a-trous loops, against 14 M for the separate pass).
  for (uint32_t it = 0; it < p.iterations; ++it) {
    const SvgfAtrousPlanes ab{guide, in.r, in.g, in.b, in.var};
    const uint32_t step = 1u << it;
    const IllumPlanes out = in.r == pa.r ? pb : pa;
    Vec4* history = it == 0 ? fr.history_color_out : nullptr;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, p.height, 4),
                      [&](const tbb::blocked_range<uint32_t>& rows) {
                        for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                          atrous(p, ab, step, out, history, int(y));
                      });
    in = out;
  }
  t.atrous = seconds_since(atrous_start);
  t.modulate = for_each_row(p.height, [&](int y) {
    for (uint32_t x = 0; x < p.width; ++x) {
      const size_t i = size_t(y) * p.width + x;
      fr.output[i] =
          svgf_modulate_pixel(fr.features[i], make_vec4(in.r[i], in.g[i], in.b[i], 0.0f));
    }
  });
  return t;
}

}  // namespace tandem
