#include "core/render/svgf_cpu.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

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

// --- row bodies (always inlined into both clones) -------------------------

// One row of the temporal stage: the branch-free pixel function in a loop
// the compiler vectorises (gathers for the bilinear taps), restrict
// pointers as in atrous_interior_body.
template <bool kHasHistory>
TANDEM_SVGF_INLINE void temporal_row_body(
    const SvgfParams& params, const PixelFeatures* __restrict features,
    const Vec3* __restrict radiance, const PixelFeatures* __restrict prev_features,
    const Vec4* __restrict prev_color, const Vec4* __restrict prev_moments, Vec4* __restrict color,
    Vec4* __restrict moments, Vec2* __restrict depth_slope, SvgfGuide* __restrict guide,
    uint32_t* __restrict material, int y) {
  const SvgfParams p = params;
  const SvgfTemporalBuffers tb{features, radiance, prev_features, prev_color, prev_moments,
                               color,    moments,  depth_slope,   guide,      material};
  for (uint32_t x = 0; x < p.width; ++x)
    svgf_temporal_pixel_h<kHasHistory>(p, tb, x, uint32_t(y));
}

// Spatial variance of the pixels [x0, x1) of row y, all at least 3 from
// every border: the unchecked, branch-free function in a loop the compiler
// vectorises. Restrict pointers as in atrous_interior_body.
TANDEM_SVGF_INLINE void variance_run_body(
    const SvgfParams& params, const SvgfGuide* __restrict guide,
    const uint32_t* __restrict material, const Vec2* __restrict slope, const Vec4* __restrict color,
    const Vec4* __restrict moments, Vec4* __restrict out, int y, int x0, int x1) {
  const SvgfParams p = params;
  const SvgfVarianceBuffers vb{guide, material, slope, color, moments, out};
  const size_t row = size_t(y) * p.width;
  for (int x = x0; x < x1; ++x)
    out[row + size_t(x)] = svgf_variance_spatial<false>(p, vb, x, y, moments[row + size_t(x)].z);
}

// One row of the variance stage: the temporal estimate is copied where the
// history is long enough; the runs of short-history pixels (disocclusions,
// every pixel of a first frame) get the spatial estimate, through the
// vectorised run loop away from the border.
using VarianceRunFn = void (*)(const SvgfParams&, const SvgfGuide* __restrict,
                               const uint32_t* __restrict, const Vec2* __restrict,
                               const Vec4* __restrict, const Vec4* __restrict, Vec4* __restrict,
                               int y, int x0, int x1);

TANDEM_SVGF_INLINE void variance_row_body(const SvgfParams& p, const SvgfVarianceBuffers& vb, int y,
                                          VarianceRunFn run) {
  const int w = int(p.width), h = int(p.height);
  const size_t row = size_t(y) * p.width;
  const bool border_row = y < 3 || y + 3 >= h;
  int x = 0;
  while (x < w) {
    const float history = vb.moments[row + size_t(x)].z;
    if (history >= kSvgfMinHistoryForVariance) {
      vb.out[row + size_t(x)] = vb.color[row + size_t(x)];
      ++x;
      continue;
    }
    int end = x + 1;
    while (end < w && vb.moments[row + size_t(end)].z < kSvgfMinHistoryForVariance)
      ++end;
    // [x, end) needs the spatial estimate; its interior part [a, b) is 3
    // from the left and right borders.
    const int a = border_row ? end : std::max(x, 3), b = border_row ? end : std::min(end, w - 3);
    for (int q = x; q < std::min(a, end); ++q)
      vb.out[row + size_t(q)] =
          svgf_variance_spatial<true>(p, vb, q, y, vb.moments[row + size_t(q)].z);
    if (a < b) run(p, vb.guide, vb.material, vb.depth_slope, vb.color, vb.moments, vb.out, y, a, b);
    for (int q = std::max(a, b); q < end; ++q)
      vb.out[row + size_t(q)] =
          svgf_variance_spatial<true>(p, vb, q, y, vb.moments[row + size_t(q)].z);
    x = end;
  }
}

// One row's interior [x0, x1) of an a-trous iteration: the unchecked
// pixel function in a loop the compiler vectorises. The restrict pointers
// tell it that the outputs alias no input (it would otherwise give up on
// the run-time alias checks of so many streams). Writes the illumination
// to `out`, or (out null) the albedo-modulated radiance to `radiance`.
template <int R>
TANDEM_SVGF_INLINE void atrous_interior_body(
    const SvgfParams& params, const SvgfGuide* __restrict guide,
    const uint32_t* __restrict material, const Vec2* __restrict slope, const Vec4* __restrict in,
    uint32_t step, int y, int x0, int x1, Vec4* __restrict out, Vec3* __restrict radiance,
    const PixelFeatures* __restrict features) {
  const SvgfParams p = params;
  const SvgfAtrousBuffers ab{guide, material, slope, in};
  const size_t row = size_t(y) * p.width;
  if (out) {
    for (int x = x0; x < x1; ++x)
      out[row + size_t(x)] = svgf_atrous_pixel_r<false, R>(p, ab, step, x, y);
  } else {
    for (int x = x0; x < x1; ++x) {
      const size_t i = row + size_t(x);
      radiance[i] =
          svgf_modulate_pixel(features[i], svgf_atrous_pixel_r<false, R>(p, ab, step, x, y));
    }
  }
}

// Pixels [x0, x1) of an a-trous row through the checked pixel function.
template <int R>
TANDEM_SVGF_INLINE void atrous_checked_body(const SvgfParams& p, const SvgfAtrousBuffers& ab,
                                            uint32_t step, Vec4* out, Vec3* radiance,
                                            const PixelFeatures* features, int y, int x0, int x1) {
  for (int x = x0; x < x1; ++x) {
    const size_t i = size_t(y) * p.width + size_t(x);
    const Vec4 v = svgf_atrous_pixel_r<true, R>(p, ab, step, x, y);
    if (out)
      out[i] = v;
    else
      radiance[i] = svgf_modulate_pixel(features[i], v);
  }
}

// One a-trous row: the interior through atrous_interior_body, the border
// (where taps fall outside) through the checked pixel function. (No
// lambdas in the row bodies: a lambda is a function of its own, compiled
// for the baseline target even inside an AVX2 clone.)
template <int R>
using AtrousInteriorFn = void (*)(const SvgfParams&, const SvgfGuide* __restrict,
                                  const uint32_t* __restrict, const Vec2* __restrict,
                                  const Vec4* __restrict, uint32_t step, int y, int x0, int x1,
                                  Vec4* __restrict, Vec3* __restrict,
                                  const PixelFeatures* __restrict);

template <int R>
TANDEM_SVGF_INLINE void atrous_row_body(const SvgfParams& p, const SvgfAtrousBuffers& ab,
                                        uint32_t step, Vec4* out, Vec3* radiance,
                                        const PixelFeatures* features, int y,
                                        AtrousInteriorFn<R> interior) {
  const int margin = R * int(step);
  const int w = int(p.width), h = int(p.height);
  if (y < margin || y + margin >= h || 2 * margin >= w) {
    atrous_checked_body<R>(p, ab, step, out, radiance, features, y, 0, w);
    return;
  }
  atrous_checked_body<R>(p, ab, step, out, radiance, features, y, 0, margin);
  interior(p, ab.guide, ab.material, ab.depth_slope, ab.in, step, y, margin, w - margin, out,
           radiance, features);
  atrous_checked_body<R>(p, ab, step, out, radiance, features, y, w - margin, w);
}

// --- the clones ---------------------------------------------------------------

// The row kernels of one instruction set.
struct SvgfRowKernels {
  void (*temporal)(const SvgfParams&, const SvgfTemporalBuffers&, int y);
  void (*variance)(const SvgfParams&, const SvgfVarianceBuffers&, int y);
  void (*atrous[2])(const SvgfParams&, const SvgfAtrousBuffers&, uint32_t step, Vec4* out,
                    Vec3* radiance, const PixelFeatures* features, int y);  // R = 1, 2
};

// The run loops (variance, a-trous interior) are functions of their own
// with restrict parameters: inlined into the row function, GCC loses the
// no-alias facts and gives up vectorising.
#define TANDEM_SVGF_ROW_KERNELS(suffix, target)                                                    \
  template <bool kHasHistory>                                                                      \
  target __attribute__((noinline)) void temporal_run_##suffix(                                     \
      const SvgfParams& p, const PixelFeatures* __restrict features,                               \
      const Vec3* __restrict radiance, const PixelFeatures* __restrict prev_features,              \
      const Vec4* __restrict prev_color, const Vec4* __restrict prev_moments,                      \
      Vec4* __restrict color, Vec4* __restrict moments, Vec2* __restrict depth_slope,              \
      SvgfGuide* __restrict guide, uint32_t* __restrict material, int y) {                         \
    temporal_row_body<kHasHistory>(p, features, radiance, prev_features, prev_color, prev_moments, \
                                   color, moments, depth_slope, guide, material, y);               \
  }                                                                                                \
  void temporal_row_##suffix(const SvgfParams& p, const SvgfTemporalBuffers& b, int y) {           \
    (b.prev_features ? temporal_run_##suffix<true>                                                 \
                     : temporal_run_##suffix<false>)(p, b.features, b.radiance, b.prev_features,   \
                                                     b.prev_color, b.prev_moments, b.color,        \
                                                     b.moments, b.depth_slope, b.guide,            \
                                                     b.material, y);                               \
  }                                                                                                \
  target __attribute__((noinline)) void variance_run_##suffix(                                     \
      const SvgfParams& p, const SvgfGuide* __restrict guide, const uint32_t* __restrict material, \
      const Vec2* __restrict slope, const Vec4* __restrict color, const Vec4* __restrict moments,  \
      Vec4* __restrict out, int y, int x0, int x1) {                                               \
    variance_run_body(p, guide, material, slope, color, moments, out, y, x0, x1);                  \
  }                                                                                                \
  target void variance_row_##suffix(const SvgfParams& p, const SvgfVarianceBuffers& vb, int y) {   \
    variance_row_body(p, vb, y, variance_run_##suffix);                                            \
  }                                                                                                \
  template <int R>                                                                                 \
  target __attribute__((noinline)) void atrous_interior_##suffix(                                  \
      const SvgfParams& p, const SvgfGuide* __restrict guide, const uint32_t* __restrict material, \
      const Vec2* __restrict slope, const Vec4* __restrict in, uint32_t step, int y, int x0,       \
      int x1, Vec4* __restrict out, Vec3* __restrict radiance,                                     \
      const PixelFeatures* __restrict features) {                                                  \
    atrous_interior_body<R>(p, guide, material, slope, in, step, y, x0, x1, out, radiance,         \
                            features);                                                             \
  }                                                                                                \
  template <int R>                                                                                 \
  target void atrous_row_##suffix(const SvgfParams& p, const SvgfAtrousBuffers& ab, uint32_t step, \
                                  Vec4* out, Vec3* radiance, const PixelFeatures* features,        \
                                  int y) {                                                         \
    atrous_row_body<R>(p, ab, step, out, radiance, features, y, atrous_interior_##suffix<R>);      \
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

SvgfStageSeconds svgf_run_cpu(const SvgfParams& p, const SvgfFrame& fr, SvgfCpuIsa isa) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const SvgfRowKernels& k = row_kernels(resolve_isa(isa));
  const SvgfTemporalBuffers tb{fr.features,     fr.radiance,  fr.prev_features, fr.prev_color,
                               fr.prev_moments, fr.scratch_a, fr.moments_out,   fr.depth_slope,
                               fr.guide,        fr.material};
  t.temporal = for_each_row(p.height, [&](int y) { k.temporal(p, tb, y); });
  const SvgfVarianceBuffers vb{fr.guide,     fr.material,    fr.depth_slope,
                               fr.scratch_a, fr.moments_out, fr.scratch_b};
  t.variance = for_each_row(p.height, [&](int y) { k.variance(p, vb, y); });
  // scratch_b holds the input of the first iteration.
  const Vec4* in = fr.scratch_b;
  const auto atrous_start = Clock::now();
  if (p.iterations == 0) std::memcpy(fr.history_color_out, fr.scratch_b, n * sizeof(Vec4));
  const auto atrous = k.atrous[p.kernel_radius <= 1 ? 0 : 1];
  // Modulation stays a pass of its own: fused into the last iteration, the
  // albedo read from the 64-byte feature records inside the vectorised loop
  // cost more than the pass (callgrind, 640x360: about 80 M instructions a
  // frame more in the a-trous loops, against 14 M for the separate pass).
  for (uint32_t it = 0; it < p.iterations; ++it) {
    const SvgfAtrousBuffers ab{fr.guide, fr.material, fr.depth_slope, in};
    const uint32_t step = 1u << it;
    Vec4* out = it == 0 ? fr.history_color_out : (in == fr.scratch_a ? fr.scratch_b : fr.scratch_a);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, p.height, 4),
                      [&](const tbb::blocked_range<uint32_t>& rows) {
                        for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                          atrous(p, ab, step, out, fr.output, fr.features, int(y));
                      });
    in = out;
  }
  t.atrous = seconds_since(atrous_start);
  {
    const Vec4* result = in;
    t.modulate = for_each_row(p.height, [&](int y) {
      for (uint32_t x = 0; x < p.width; ++x) {
        const size_t i = size_t(y) * p.width + x;
        fr.output[i] = svgf_modulate_pixel(fr.features[i], result[i]);
      }
    });
  }
  return t;
}

}  // namespace tandem
