#include "core/render/svgf_cpu.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cstring>

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

template <class F>
double for_each_pixel(uint32_t width, uint32_t height, const F& f) {
  const auto start = Clock::now();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, height, 4),
                    [&](const tbb::blocked_range<uint32_t>& rows) {
                      for (uint32_t y = rows.begin(); y != rows.end(); ++y)
                        for (uint32_t x = 0; x < width; ++x)
                          f(x, y);
                    });
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

SvgfStageSeconds svgf_run_cpu(const SvgfParams& p, const SvgfFrame& fr) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const SvgfTemporalBuffers tb{fr.features,     fr.radiance,  fr.prev_features, fr.prev_color,
                               fr.prev_moments, fr.scratch_a, fr.moments_out,   fr.depth_slope};
  t.temporal = for_each_pixel(p.width, p.height,
                              [&](uint32_t x, uint32_t y) { svgf_temporal_pixel(p, tb, x, y); });
  const SvgfVarianceBuffers vb{fr.features, fr.depth_slope, fr.scratch_a, fr.moments_out,
                               fr.scratch_b};
  t.variance = for_each_pixel(p.width, p.height,
                              [&](uint32_t x, uint32_t y) { svgf_variance_pixel(p, vb, x, y); });
  // scratch_b holds the input of the first iteration.
  const Vec4* in = fr.scratch_b;
  const auto atrous_start = Clock::now();
  for (uint32_t it = 0; it < p.iterations; ++it) {
    Vec4* out = it == 0 ? fr.history_color_out : (in == fr.scratch_a ? fr.scratch_b : fr.scratch_a);
    const SvgfAtrousBuffers ab{fr.features, fr.depth_slope, in, out};
    const uint32_t step = 1u << it;
    for_each_pixel(p.width, p.height,
                   [&](uint32_t x, uint32_t y) { svgf_atrous_pixel(p, ab, step, x, y); });
    in = out;
  }
  t.atrous = std::chrono::duration<double>(Clock::now() - atrous_start).count();
  if (p.iterations == 0) std::memcpy(fr.history_color_out, fr.scratch_b, n * sizeof(Vec4));
  const Vec4* result = in;
  t.modulate = for_each_pixel(p.width, p.height, [&](uint32_t x, uint32_t y) {
    const size_t i = size_t(y) * p.width + x;
    fr.output[i] = svgf_modulate_pixel(fr.features[i], result[i]);
  });
  return t;
}

}  // namespace tandem
