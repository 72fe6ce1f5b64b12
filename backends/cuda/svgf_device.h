// The denoiser's filter on the CUDA backend's device: the stages of
// svgf_run_cpu (core/render/svgf_cpu.h) as the kernels of svgf_kernels.cu,
// through DeviceOps like every other kernel, so that the simulated device
// runs them in CI and fault injection covers them. The per-pixel code is
// the CPU's (core/kernel/svgf.h); the two agree within float rounding (the
// GPU's expf and powf).
#pragma once

#include <memory>

#include "backends/cuda/device_ops.h"
#include "core/render/temporal_denoiser.h"

namespace tandem {

class DeviceSvgf {
 public:
  explicit DeviceSvgf(std::shared_ptr<DeviceOps> device);
  ~DeviceSvgf();
  DeviceSvgf(const DeviceSvgf&) = delete;
  DeviceSvgf& operator=(const DeviceSvgf&) = delete;

  // One frame in the stage order of svgf_run_cpu: the inputs of `frame`
  // are copied to the device, the stages run there and the outputs
  // (history_color_out, moments_out, output) are copied back; the CPU's
  // work space in `frame` is not used. The device buffers are kept for the
  // next frame of the same size. Throws DeviceError when the device fails.
  SvgfStageSeconds run(const SvgfParams& params, const SvgfFrame& frame);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The filter of a TemporalDenoiser on `device` (TemporalDenoiser::
// set_offload): when the device fails, the failure is logged once and that
// frame and every later one are filtered on the CPU, as the backend factory
// falls back after a failure in render().
std::shared_ptr<SvgfOffload> make_device_svgf_offload(std::shared_ptr<DeviceOps> device);

}  // namespace tandem
