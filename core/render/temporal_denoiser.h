// The temporal denoiser a frame loop calls once per frame: SVGF
// (core/kernel/svgf.h) with its history kept between calls.
//
//   MotionHistory motion;          // core/world/motion_history.h
//   TemporalDenoiser denoiser;
//   per frame: render 1 spp -> radiance; features for the same KernelScene
//   (Backend::render_features(motion.advance(kd), ...) or
//   CoreTracer::render_features(motion, features)); then
//   ImageRGB clean = denoiser.process(features, radiance);
//
// The history follows the camera and moving instances through the motion
// vectors in the features; it is dropped where the surface changed
// (disocclusion) and entirely by reset() (a cut, a scene switch) or a new
// resolution.
#pragma once

#include <memory>
#include <vector>

#include "core/image/image.h"
#include "core/render/svgf_cpu.h"

namespace tandem {

// A filter that runs the stages of svgf_run_cpu somewhere else (a GPU:
// backends/cuda/svgf_device.h), reading the frame's inputs and writing its
// outputs (history_color_out, moments_out, output) but not the CPU's work
// space. run() returns false when it could not (its device failed): the
// frame is then filtered on the CPU.
class SvgfOffload {
 public:
  virtual ~SvgfOffload() = default;
  virtual bool run(const SvgfParams& params, const SvgfFrame& frame, SvgfStageSeconds* seconds) = 0;
};

class TemporalDenoiser {
 public:
  TemporalDenoiser() = default;
  // params.width/height are ignored: each process() call uses its image size.
  explicit TemporalDenoiser(const SvgfParams& params) : params_(params) {}

  // Filters `radiance` (this frame's noisy image) guided by `features` (this
  // frame's, width * height of them, motion relative to the previous call).
  ImageRGB process(const std::vector<PixelFeatures>& features, const ImageRGB& radiance);
  // process() asking `stop` between the CPU filter's stages (a GPU filter
  // runs whole): returns false, with `out` untouched and the history
  // dropped (it was half written), when it said stop.
  bool process(const std::vector<PixelFeatures>& features, const ImageRGB& radiance, ImageRGB& out,
               const PassStop& stop);
  // Filters on `offload` from the next frame on, and on the CPU whenever it
  // cannot (null: the CPU only).
  void set_offload(std::shared_ptr<SvgfOffload> offload) { offload_ = std::move(offload); }
  // Whether the last process() filtered on the CPU.
  bool last_on_cpu() const { return last_on_cpu_; }

  // Forget the history: the next frame starts fresh.
  void reset() { has_history_ = false; }
  bool has_history() const { return has_history_; }

  // Seconds the stages of the last process() took.
  const SvgfStageSeconds& last_seconds() const { return last_seconds_; }
  const SvgfParams& params() const { return params_; }
  void set_params(const SvgfParams& params) { params_ = params; }

  // The history the next frame reprojects (for tests and debugging views):
  // (m1, m2, history length, 0) per pixel.
  const std::vector<Vec4>& moments() const { return moments_[current_]; }

 private:
  // The buffers for width x height images, dropping the history; false
  // when `stop` said stop first (the size is then set again next time).
  bool size_for(uint32_t width, uint32_t height, const PassStop& stop);

  SvgfParams params_ = svgf_default_params(0, 0);
  bool has_history_ = false;
  uint32_t width_ = 0, height_ = 0;
  int current_ = 0;  // which of the double buffers holds the latest history
  std::vector<PixelFeatures> features_[2];
  std::vector<Vec4> color_[2], moments_[2];
  std::vector<Vec4> scratch_a_, scratch_b_;
  std::vector<Vec3> radiance_, output_;
  std::vector<Vec2> depth_slope_;
  std::vector<SvgfGuide> guide_;
  std::vector<uint32_t> material_;
  std::vector<float> planes_;  // svgf_run_cpu's work space
  SvgfCpuGuide
      cpu_guide_[2];  // double-buffered like the history: the reprojection reads last frame's
  bool cpu_guide_current_[2] = {false, false};  // written by the CPU filter of that frame
  std::shared_ptr<SvgfOffload> offload_;
  bool last_on_cpu_ = true;
  SvgfStageSeconds last_seconds_;
};

}  // namespace tandem
