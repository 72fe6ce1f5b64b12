// The denoiser on the device: the feature pass (core/kernel/features.h) and
// the stages of the variance-guided filter (core/kernel/svgf.h), one thread
// per pixel, the per-pixel code the CPU runs (backends/cpu_loops/
// cpu_features.h, core/render/svgf_cpu.h).
#include "backends/cuda/device_exec.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/features.h"
#include "core/kernel/svgf.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

template <class Exec>
TANDEM_DEVICE_FN void Features::run(Exec& ex, const Args& a) {
  const KernelData& kd = load_kernel_data(ex, a.kd);
  const uint32_t x = ex.pixel_x();
  const uint32_t y = ex.pixel_y();
  if (x < a.width && y < a.height)
    a.out[size_t(y) * a.width + x] = compute_pixel_features(kd, BvhTracer{&kd}, a.pass, x, y);
}

template <class Exec>
TANDEM_DEVICE_FN void SvgfTemporal::run(Exec& ex, const Args& a) {
  const uint32_t x = ex.pixel_x();
  const uint32_t y = ex.pixel_y();
  // Copies: read through the one parameter struct, the temporal stage took
  // 64 registers instead of 44 (ptxas, sm_90).
  const SvgfParams p = a.params;
  const SvgfTemporalBuffers b = a.buffers;
  if (x < p.width && y < p.height) svgf_temporal_pixel(p, b, x, y);
}

template <class Exec>
TANDEM_DEVICE_FN void SvgfVariance::run(Exec& ex, const Args& a) {
  const uint32_t x = ex.pixel_x();
  const uint32_t y = ex.pixel_y();
  if (x < a.params.width && y < a.params.height) svgf_variance_pixel(a.params, a.buffers, x, y);
}

template <class Exec>
TANDEM_DEVICE_FN void SvgfAtrous::run(Exec& ex, const Args& a) {
  const uint32_t x = ex.pixel_x();
  const uint32_t y = ex.pixel_y();
  if (x >= a.params.width || y >= a.params.height) return;
  const size_t i = size_t(y) * a.params.width + x;
  const Vec4 v = svgf_atrous_pixel<true>(a.params, a.buffers, a.step, x, y);
  if (a.out) a.out[i] = v;
  if (a.radiance) a.radiance[i] = svgf_modulate_pixel(a.features[i], v);
}

template <class Exec>
TANDEM_DEVICE_FN void SvgfModulate::run(Exec& ex, const Args& a) {
  const uint32_t x = ex.pixel_x();
  const uint32_t y = ex.pixel_y();
  if (x >= a.params.width || y >= a.params.height) return;
  const size_t i = size_t(y) * a.params.width + x;
  a.out[i] = svgf_modulate_pixel(a.features[i], a.illumination[i]);
}

TANDEM_KERNEL_END
}  // namespace tandem

TANDEM_KERNEL_REGISTRY(svgf) {
  register_kernels<Features, SvgfTemporal, SvgfVariance, SvgfAtrous, SvgfModulate>(table);
}
