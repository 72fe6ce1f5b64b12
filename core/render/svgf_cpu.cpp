#include "core/render/svgf_cpu.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstring>

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

template <class F>
double for_each_pixel(uint32_t width, uint32_t height, const F& f) {
  const auto start = Clock::now();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, height, 4),
                    [&](const tbb::blocked_range<uint32_t>& rows) {
                      for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                        for (uint32_t x = 0; x < width; ++x)
                          f(x, y);
                    });
  return seconds_since(start);
}

// One row's interior [x0, x1) of an a-trous iteration: the unchecked
// pixel function in a loop the compiler vectorises. The restrict pointers
// tell it that the outputs alias no input (it would otherwise give up on
// the run-time alias checks of so many streams). Writes the illumination
// to `out`, or (out null) the albedo-modulated radiance to `radiance`.
template <int R>
void atrous_interior(const SvgfParams& params, const SvgfGuide* __restrict guide,
                     const uint32_t* __restrict material, const Vec2* __restrict slope,
                     const Vec4* __restrict in, uint32_t step, int y, int x0, int x1,
                     Vec4* __restrict out, Vec3* __restrict radiance,
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

// One a-trous iteration over the image: the interior of each row through
// atrous_interior, the border (where taps fall outside) through the
// checked pixel function.
template <int R>
void atrous_pass_r(const SvgfParams& p, const SvgfAtrousBuffers& ab, uint32_t step, Vec4* out,
                   Vec3* radiance, const PixelFeatures* features) {
  const int margin = R * int(step);
  const int w = int(p.width), h = int(p.height);
  auto checked = [&](int x, int y) {
    const size_t i = size_t(y) * p.width + size_t(x);
    const Vec4 v = svgf_atrous_pixel_r<true, R>(p, ab, step, x, y);
    if (out)
      out[i] = v;
    else
      radiance[i] = svgf_modulate_pixel(features[i], v);
  };
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(h), 4),
                    [&](const tbb::blocked_range<uint32_t>& rows) {
                      for (int y = int(rows.begin()); y != int(rows.end()); ++y) {
                        if (y < margin || y + margin >= h || 2 * margin >= w) {
                          for (int x = 0; x < w; ++x)
                            checked(x, y);
                          continue;
                        }
                        for (int x = 0; x < margin; ++x)
                          checked(x, y);
                        atrous_interior<R>(p, ab.guide, ab.material, ab.depth_slope, ab.in, step, y,
                                           margin, w - margin, out, radiance, features);
                        for (int x = w - margin; x < w; ++x)
                          checked(x, y);
                      }
                    });
}

void atrous_pass(const SvgfParams& p, const SvgfAtrousBuffers& ab, uint32_t step, Vec4* out,
                 Vec3* radiance, const PixelFeatures* features) {
  if (p.kernel_radius <= 1)
    atrous_pass_r<1>(p, ab, step, out, radiance, features);
  else
    atrous_pass_r<2>(p, ab, step, out, radiance, features);
}

}  // namespace

SvgfStageSeconds svgf_run_cpu(const SvgfParams& p, const SvgfFrame& fr) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const SvgfTemporalBuffers tb{fr.features,     fr.radiance,  fr.prev_features, fr.prev_color,
                               fr.prev_moments, fr.scratch_a, fr.moments_out,   fr.depth_slope,
                               fr.guide,        fr.material};
  t.temporal = for_each_pixel(p.width, p.height,
                              [&](uint32_t x, uint32_t y) { svgf_temporal_pixel(p, tb, x, y); });
  const SvgfVarianceBuffers vb{fr.guide,     fr.material,    fr.depth_slope,
                               fr.scratch_a, fr.moments_out, fr.scratch_b};
  t.variance = for_each_pixel(p.width, p.height,
                              [&](uint32_t x, uint32_t y) { svgf_variance_pixel(p, vb, x, y); });
  // scratch_b holds the input of the first iteration.
  const Vec4* in = fr.scratch_b;
  const auto atrous_start = Clock::now();
  if (p.iterations == 0) std::memcpy(fr.history_color_out, fr.scratch_b, n * sizeof(Vec4));
  for (uint32_t it = 0; it < p.iterations; ++it) {
    const SvgfAtrousBuffers ab{fr.guide, fr.material, fr.depth_slope, in};
    const uint32_t step = 1u << it;
    Vec4* out = it == 0 ? fr.history_color_out : (in == fr.scratch_a ? fr.scratch_b : fr.scratch_a);
    atrous_pass(p, ab, step, out, nullptr, fr.features);
    in = out;
  }
  t.atrous = seconds_since(atrous_start);
  const Vec4* result = in;
  t.modulate = for_each_pixel(p.width, p.height, [&](uint32_t x, uint32_t y) {
    const size_t i = size_t(y) * p.width + x;
    fr.output[i] = svgf_modulate_pixel(fr.features[i], result[i]);
  });
  return t;
}

}  // namespace tandem
