#include "core/render/svgf_cpu.h"

#include "core/render/svgf_cpu_rows.h"

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

using svgf_cpu_detail::IllumPlanes;
using svgf_cpu_detail::store;

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

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

// for_each_row in bands with `stop` asked between them (a stop abandons the
// whole filter, so a stage may end half done). Returns false when stopped.
template <class F>
bool for_each_row_until_stopped(uint32_t height, const PassStop& stop, const F& f) {
  constexpr uint32_t kBands = 4;
  const uint32_t band = stop ? std::max((height + kBands - 1) / kBands, 16u) : height;
  for (uint32_t y0 = 0; y0 < height; y0 += band) {
    if (y0 > 0 && pass_should_stop(stop)) return false;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(y0, std::min(y0 + band, height), 4),
                      [&](const tbb::blocked_range<uint32_t>& rows) {
                        for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                          f(int(y));
                      });
  }
  return true;
}

// --- the planes ----------------------------------------------------------------

// The structure-of-arrays work space (SvgfFrame::planes): this frame's
// features and radiance split into planes for the temporal loop, the temporal
// illumination, its variance and moments that the spatial variance reads at
// its taps, and two sets of illumination + variance planes that the a-trous
// iterations ping-pong between, svgf_cpu_plane_stride apart. The guide has
// planes of its own (SvgfCpuGuide), kept from one frame to the next.
enum SvgfPlane : size_t {
  kAlbedoR,
  kAlbedoG,
  kAlbedoB,
  kReprojectedDepth,
  kMotionX,
  kMotionY,
  kRadianceR,
  kRadianceG,
  kRadianceB,
  kTemporalR,
  kTemporalG,
  kTemporalB,
  kTemporalVar,
  kM1,
  kM2,
  kIllumA,  // r, g, b, variance
  kIllumB = kIllumA + 4,
  kPlaneCount = kIllumB + 4
};

IllumPlanes illum_planes(float* planes, size_t stride, size_t first) {
  return IllumPlanes{planes + first * stride, planes + (first + 1) * stride,
                     planes + (first + 2) * stride, planes + (first + 3) * stride};
}

// The temporal stage's buffers in the CPU driver's form (the overloads of
// svgf_cur_pixel ... svgf_store_temporal below). GCC vectorises no loop
// that reads the 64-byte feature records (a stride of 16 floats), so the
// first pass splits this frame's records into planes and the pixel loop
// reads only those, last frame's compact guide at the reprojection taps
// (gathers), and writes the planes the spatial stages read straight from
// the pixel function, without a copy pass or intermediate records.
struct SvgfTemporalPlanes {
  const float* normal_x;  // this frame's guide (the first pass's output)
  const float* normal_y;
  const float* normal_z;
  const float* depth;
  const uint32_t* material;
  const uint32_t* instance;
  const float* albedo_r;  // the rest of this frame's features
  const float* albedo_g;
  const float* albedo_b;
  const float* reprojected_depth;  // PixelFeatures::prev_depth
  const float* motion_x;
  const float* motion_y;
  const float* radiance_r;
  const float* radiance_g;
  const float* radiance_b;
  const Vec4* prev_color;
  const Vec4* prev_moments;
  const float* prev_normal_x;  // last frame's guide
  const float* prev_normal_y;
  const float* prev_normal_z;
  const float* prev_depth;
  const uint32_t* prev_material;
  const uint32_t* prev_instance;
  Vec2* depth_slope;  // out
  float* r;           // out: temporal illumination, its variance, moments
  float* g;
  float* b;
  float* var;
  float* m1;
  float* m2;
  Vec4* moments;  // out: (m1, m2, length, 0), the next frame's history
};

TANDEM_SVGF_INLINE PixelFeatures svgf_cur_pixel(const SvgfTemporalPlanes& b, size_t i) {
  PixelFeatures f;
  f.albedo = make_vec3(b.albedo_r[i], b.albedo_g[i], b.albedo_b[i]);
  f.depth = b.depth[i];
  f.normal = make_vec3(b.normal_x[i], b.normal_y[i], b.normal_z[i]);
  f.prev_depth = b.reprojected_depth[i];
  f.motion = make_vec2(b.motion_x[i], b.motion_y[i]);
  f.instance = b.instance[i];
  f.prim = 0;
  f.material = b.material[i];
  f.pad[0] = f.pad[1] = f.pad[2] = 0;
  return f;
}
TANDEM_SVGF_INLINE Vec3 svgf_cur_radiance(const SvgfTemporalPlanes& b, size_t i) {
  return make_vec3(b.radiance_r[i], b.radiance_g[i], b.radiance_b[i]);
}
TANDEM_SVGF_INLINE float svgf_cur_depth(const SvgfTemporalPlanes& b, ptrdiff_t j) {
  return b.depth[j];
}
TANDEM_SVGF_INLINE bool svgf_cur_hit(const SvgfTemporalPlanes& b, ptrdiff_t j) {
  return b.instance[j] != kInvalidIndex;
}
TANDEM_SVGF_INLINE SvgfPrevSurface svgf_prev_surface(const SvgfTemporalPlanes& b, int j) {
  SvgfPrevSurface s;
  s.normal = make_vec3(b.prev_normal_x[j], b.prev_normal_y[j], b.prev_normal_z[j]);
  s.depth = b.prev_depth[j];
  s.instance = b.prev_instance[j];
  s.material = b.prev_material[j];
  return s;
}

TANDEM_SVGF_INLINE void svgf_store_temporal(const SvgfTemporalPlanes& b, size_t i,
                                            const PixelFeatures& f, Vec2 slope, Vec4 color,
                                            Vec4 moments) {
  b.depth_slope[i] = slope;
  b.r[i] = color.x;
  b.g[i] = color.y;
  b.b[i] = color.z;
  b.var[i] = color.w;
  b.m1[i] = moments.x;
  b.m2[i] = moments.y;
  b.moments[i] = moments;
}

// --- row bodies (always inlined into both clones) -------------------------

// One row of the temporal stage: the branch-free pixel function in a loop
// the compiler vectorises (gathers for the bilinear taps; ivdep as in
// variance_run_body).
// The pixels of the image's edge (first and last row and column) go through
// the checked function, scalar.
template <bool kHasHistory>
TANDEM_SVGF_INLINE void temporal_row_body(const SvgfParams& params, const SvgfTemporalPlanes& tp,
                                          int y) {
  const SvgfParams p = params;
  const SvgfTemporalPlanes b = tp;
  if (y == 0 || uint32_t(y) + 1 >= p.height || p.width < 3) {
    for (uint32_t x = 0; x < p.width; ++x)
      svgf_temporal_pixel_h<kHasHistory, true>(p, b, x, uint32_t(y));
    return;
  }
  svgf_temporal_pixel_h<kHasHistory, true>(p, b, 0, uint32_t(y));
  TANDEM_SVGF_IVDEP
  for (uint32_t x = 1; x < p.width - 1; ++x)
    svgf_temporal_pixel_h<kHasHistory, false>(p, b, x, uint32_t(y));
  svgf_temporal_pixel_h<kHasHistory, true>(p, b, p.width - 1, uint32_t(y));
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
                                          const float* temporal_var, const IllumPlanes& out, int y,
                                          VarianceRunFn run) {
  const int w = int(p.width), h = int(p.height);
  const size_t row = size_t(y) * p.width;
  const bool border_row = y < 3 || y + 3 >= h;
  // The temporal estimate for the whole row (copies of the planes' row),
  // then the spatial one over the runs of short-history pixels.
  const size_t bytes = size_t(w) * sizeof(float);
  std::memcpy(out.r + row, vp.r + row, bytes);
  std::memcpy(out.g + row, vp.g + row, bytes);
  std::memcpy(out.b + row, vp.b + row, bytes);
  std::memcpy(out.var + row, temporal_var + row, bytes);
  int x = 0;
  while (x < w) {
    const float history = vp.moments[row + size_t(x)].z;
    if (history >= kSvgfMinHistoryForVariance) {
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
  void (*temporal[2])(const SvgfParams&, const SvgfTemporalPlanes&, int y);  // no history, history
  void (*variance)(const SvgfParams&, const SvgfVariancePlanes&, const float* temporal_var,
                   const IllumPlanes& out, int y);
  void (*atrous[2])(const SvgfParams&, const SvgfAtrousPlanes&, uint32_t step,
                    const IllumPlanes& out, Vec4* history, int y);  // R = 1, 2
};

// The run loops (temporal, variance, a-trous interior) are functions of
// their own: inlined into the row function, GCC loses the no-alias facts
// and gives up vectorising.
#define TANDEM_SVGF_ROW_KERNELS(suffix, target)                                                   \
  template <bool kHasHistory>                                                                     \
  target void temporal_row_##suffix(const SvgfParams& p, const SvgfTemporalPlanes& b, int y) {    \
    temporal_row_body<kHasHistory>(p, b, y);                                                      \
  }                                                                                               \
  target __attribute__((noinline)) void variance_run_##suffix(                                    \
      const SvgfParams& p, const SvgfVariancePlanes& vp, const IllumPlanes& out, int y, int x0,   \
      int x1) {                                                                                   \
    variance_run_body(p, vp, out, y, x0, x1);                                                     \
  }                                                                                               \
  target void variance_row_##suffix(const SvgfParams& p, const SvgfVariancePlanes& vp,            \
                                    const float* temporal_var, const IllumPlanes& out, int y) {   \
    variance_row_body(p, vp, temporal_var, out, y, variance_run_##suffix);                        \
  }                                                                                               \
  template <int R>                                                                                \
  target __attribute__((noinline)) void atrous_interior_##suffix(                                 \
      const SvgfParams& p, const SvgfAtrousPlanes& in, uint32_t step, int y, int x0, int x1,      \
      const IllumPlanes& out) {                                                                   \
    if constexpr (R == 1) {                                                                       \
      if (kHandInterior1_##suffix) return kHandInterior1_##suffix(p, in, step, y, x0, x1, out);   \
    }                                                                                             \
    atrous_interior_body<R>(p, in, step, y, x0, x1, out);                                         \
  }                                                                                               \
  template <int R>                                                                                \
  target __attribute__((noinline)) void atrous_masked_##suffix(                                   \
      const SvgfParams& p, const SvgfAtrousPlanes& in, uint32_t step, int y, int x0, int x1,      \
      const IllumPlanes& out, const SvgfTapMask& mask) {                                          \
    atrous_masked_body<R>(p, in, step, y, x0, x1, out, mask);                                     \
  }                                                                                               \
  template <int R>                                                                                \
  target void atrous_row_##suffix(const SvgfParams& p, const SvgfAtrousPlanes& ab, uint32_t step, \
                                  const IllumPlanes& out, Vec4* history, int y) {                 \
    atrous_row_body<R>(p, ab, step, out, history, y, atrous_interior_##suffix<R>,                 \
                       atrous_masked_##suffix<R>);                                                \
  }                                                                                               \
  const SvgfRowKernels kRowKernels_##suffix = {                                                   \
      {temporal_row_##suffix<false>, temporal_row_##suffix<true>},                                \
      variance_row_##suffix,                                                                      \
      {atrous_row_##suffix<1>, atrous_row_##suffix<2>}};

// The hand-written interior loops (3x3; null: the generic one).
constexpr AtrousInteriorFn<1> kHandInterior1_baseline = nullptr;
#if TANDEM_SVGF_HAVE_AVX2
constexpr AtrousInteriorFn<1> kHandInterior1_avx2 = svgf_cpu_detail::svgf_atrous_interior_r1_avx2;
#endif

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

size_t svgf_cpu_plane_stride(size_t n) {
  return (n + 1023) / 1024 * 1024 + 16;
}

void SvgfCpuGuide::resize(size_t n) {
  pixels_ = n;
  stride_ = svgf_cpu_plane_stride(n);
  floats_.assign(4 * stride_, 0.0f);
  ids_.assign(kIdLead + 2 * stride_, 0u);
}

size_t svgf_cpu_plane_floats(uint32_t width, uint32_t height) {
  return kPlaneCount * svgf_cpu_plane_stride(size_t(width) * height);
}

SvgfStageSeconds svgf_run_cpu(const SvgfParams& p, const SvgfFrame& fr, SvgfCpuIsa isa,
                              const PassStop& stop) {
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
  SvgfCpuGuide own_guide, own_prev_guide;
  SvgfCpuGuide* guide_out = fr.guide_out;
  if (!guide_out) guide_out = &own_guide;
  if (guide_out->size() != n) guide_out->resize(n);
  const size_t ps = svgf_cpu_plane_stride(n);
  const auto temporal_start = Clock::now();
  const SvgfCpuGuide* prev = fr.prev_guide;
  if (fr.prev_features && !prev) {
    // No compact guide of last frame (a caller with records only): made
    // here from its feature records.
    own_prev_guide.resize(n);
    float* nx = own_prev_guide.normal_x();
    float* ny = own_prev_guide.normal_y();
    float* nz = own_prev_guide.normal_z();
    float* depth = own_prev_guide.depth();
    uint32_t* material = own_prev_guide.material();
    uint32_t* instance = own_prev_guide.instance();
    for_each_row(p.height, [&](int y) {
      for (size_t i = size_t(y) * p.width; i < size_t(y + 1) * p.width; ++i) {
        const PixelFeatures& f = fr.prev_features[i];
        nx[i] = f.normal.x;
        ny[i] = f.normal.y;
        nz[i] = f.normal.z;
        depth[i] = f.depth;
        material[i] = f.material;
        instance[i] = f.instance;
      }
    });
    prev = &own_prev_guide;
  }
  const bool history = fr.prev_features != nullptr;
  float* albedo_r = planes + kAlbedoR * ps;
  float* albedo_g = planes + kAlbedoG * ps;
  float* albedo_b = planes + kAlbedoB * ps;
  float* reprojected_depth = planes + kReprojectedDepth * ps;
  float* motion_x = planes + kMotionX * ps;
  float* motion_y = planes + kMotionY * ps;
  float* radiance_r = planes + kRadianceR * ps;
  float* radiance_g = planes + kRadianceG * ps;
  float* radiance_b = planes + kRadianceB * ps;
  SvgfTemporalPlanes tp{};
  tp.normal_x = guide_out->normal_x();
  tp.normal_y = guide_out->normal_y();
  tp.normal_z = guide_out->normal_z();
  tp.depth = guide_out->depth();
  tp.material = guide_out->material();
  tp.instance = guide_out->instance();
  float* g_nx = guide_out->normal_x();
  float* g_ny = guide_out->normal_y();
  float* g_nz = guide_out->normal_z();
  float* g_depth = guide_out->depth();
  uint32_t* g_material = guide_out->material();
  uint32_t* g_instance = guide_out->instance();
  // This frame's records into planes (the guide among them).
  auto stopped_at = [&t] {
    t.stopped = true;
    return t;
  };
  const bool split = for_each_row_until_stopped(p.height, stop, [&](int y) {
    for (size_t i = size_t(y) * p.width; i < size_t(y + 1) * p.width; ++i) {
      const PixelFeatures& f = fr.features[i];
      g_nx[i] = f.normal.x;
      g_ny[i] = f.normal.y;
      g_nz[i] = f.normal.z;
      g_depth[i] = f.depth;
      g_material[i] = f.material;
      g_instance[i] = f.instance;
      albedo_r[i] = f.albedo.x;
      albedo_g[i] = f.albedo.y;
      albedo_b[i] = f.albedo.z;
      reprojected_depth[i] = f.prev_depth;
      motion_x[i] = f.motion.x;
      motion_y[i] = f.motion.y;
      radiance_r[i] = fr.radiance[i].x;
      radiance_g[i] = fr.radiance[i].y;
      radiance_b[i] = fr.radiance[i].z;
    }
  });
  if (!split) return stopped_at();
  tp.albedo_r = albedo_r;
  tp.albedo_g = albedo_g;
  tp.albedo_b = albedo_b;
  tp.reprojected_depth = reprojected_depth;
  tp.motion_x = motion_x;
  tp.motion_y = motion_y;
  tp.radiance_r = radiance_r;
  tp.radiance_g = radiance_g;
  tp.radiance_b = radiance_b;
  if (history) {
    tp.prev_color = fr.prev_color;
    tp.prev_moments = fr.prev_moments;
    tp.prev_normal_x = prev->normal_x();
    tp.prev_normal_y = prev->normal_y();
    tp.prev_normal_z = prev->normal_z();
    tp.prev_depth = prev->depth();
    tp.prev_material = prev->material();
    tp.prev_instance = prev->instance();
  }
  tp.depth_slope = fr.depth_slope;
  tp.r = planes + kTemporalR * ps;
  tp.g = planes + kTemporalG * ps;
  tp.b = planes + kTemporalB * ps;
  tp.var = planes + kTemporalVar * ps;
  tp.m1 = planes + kM1 * ps;
  tp.m2 = planes + kM2 * ps;
  tp.moments = fr.moments_out;
  const auto temporal = k.temporal[history ? 1 : 0];
  const bool temporal_done =
      for_each_row_until_stopped(p.height, stop, [&](int y) { temporal(p, tp, y); });
  t.temporal = seconds_since(temporal_start);
  if (!temporal_done || pass_should_stop(stop)) return stopped_at();
  const SvgfGuidePlanes guide{tp.normal_x, tp.normal_y, tp.normal_z,
                              tp.depth,    tp.material, fr.depth_slope};
  const SvgfVariancePlanes vp{guide, tp.r, tp.g, tp.b, tp.m1, tp.m2, fr.moments_out};
  const IllumPlanes pa = illum_planes(planes, ps, kIllumA), pb = illum_planes(planes, ps, kIllumB);
  const auto variance_start = Clock::now();
  const bool variance_done =
      for_each_row_until_stopped(p.height, stop, [&](int y) { k.variance(p, vp, tp.var, pa, y); });
  t.variance = seconds_since(variance_start);
  if (!variance_done || pass_should_stop(stop)) return stopped_at();
  // pa holds the input of the first iteration; the first iteration's
  // output is also written as records: the next frame's colour history.
  IllumPlanes in = pa;
  const auto atrous_start = Clock::now();
  if (p.iterations == 0) {
    for (size_t i = 0; i < n; ++i)
      fr.history_color_out[i] = make_vec4(pa.r[i], pa.g[i], pa.b[i], pa.var[i]);
  }
  const auto atrous = k.atrous[p.kernel_radius <= 1 ? 0 : 1];
  // Modulation: each row of the last iteration as soon as it is done (in
  // the cache), with the albedo from its plane (the temporal stage's first
  // pass split it out of the records). The product is svgf_modulate_pixel's.
  auto modulate_row = [&](const IllumPlanes& v, uint32_t y) {
    for (size_t i = size_t(y) * p.width; i < size_t(y + 1) * p.width; ++i) {
      fr.output[i] = make_vec3(v.r[i], v.g[i], v.b[i]) *
                     svgf_guard_albedo(make_vec3(albedo_r[i], albedo_g[i], albedo_b[i]));
    }
  };
  for (uint32_t it = 0; it < p.iterations; ++it) {
    if (it > 0 && pass_should_stop(stop)) {
      t.atrous = seconds_since(atrous_start);
      return stopped_at();
    }
    const SvgfAtrousPlanes ab{guide, in.r, in.g, in.b, in.var};
    const uint32_t step = 1u << it;
    const IllumPlanes out = in.r == pa.r ? pb : pa;
    Vec4* history = it == 0 ? fr.history_color_out : nullptr;
    const bool last = it + 1 == p.iterations;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, p.height, 4),
                      [&](const tbb::blocked_range<uint32_t>& rows) {
                        for (uint32_t y = rows.begin(); y != rows.end(); ++y) {
                          atrous(p, ab, step, out, history, int(y));
                          if (last) modulate_row(out, y);
                        }
                      });
    in = out;
  }
  t.atrous = seconds_since(atrous_start);
  if (p.iterations == 0)
    t.modulate = for_each_row(p.height, [&](int y) { modulate_row(in, uint32_t(y)); });
  return t;
}

}  // namespace tandem
