// One frame of the variance-guided filter (core/kernel/svgf.h) over host
// buffers, each stage a TBB loop over rows running the shared per-pixel
// functions. backends/cuda/svgf_device.h runs the same sequence on the GPU.
#pragma once

#include <vector>

#include "core/kernel/svgf.h"
#include "core/render/pass_stop.h"

namespace tandem {

// Distance in floats between the CPU driver's planes of n pixels: n rounded
// up to 1024 plus 16, so that the planes start 64 bytes (one cache line)
// apart modulo 4 KiB. Planes n floats apart start at the same offset
// whenever 4 bytes * n is a multiple of 4 KiB (640x360, 1280x720, 1920x1080
// all are): the pixel loops, which read and write a dozen or more planes at
// the same index, then map them all to one set of the 8-way L1 cache.
size_t svgf_cpu_plane_stride(size_t n);

// The compact per-pixel guide the CPU driver's temporal stage writes: what
// the spatial stages read at every tap (normal, depth, material) and what
// the next frame's reprojection test reads at its bilinear taps (those and
// the instance), one plane per component: 24 bytes a pixel instead of the
// 64 of a PixelFeatures record.
class SvgfCpuGuide {
 public:
  void resize(size_t n);  // pixels
  size_t size() const { return pixels_; }
  float* normal_x() { return floats_.data(); }
  float* normal_y() { return floats_.data() + stride_; }
  float* normal_z() { return floats_.data() + 2 * stride_; }
  float* depth() { return floats_.data() + 3 * stride_; }
  uint32_t* material() { return ids_.data() + kIdLead; }
  uint32_t* instance() { return ids_.data() + kIdLead + stride_; }
  const float* normal_x() const { return floats_.data(); }
  const float* normal_y() const { return floats_.data() + stride_; }
  const float* normal_z() const { return floats_.data() + 2 * stride_; }
  const float* depth() const { return floats_.data() + 3 * stride_; }
  const uint32_t* material() const { return ids_.data() + kIdLead; }
  const uint32_t* instance() const { return ids_.data() + kIdLead + stride_; }

 private:
  // The id planes start 4 cache lines on, past the float planes' offsets.
  static constexpr size_t kIdLead = 64;
  size_t pixels_ = 0, stride_ = 0;
  std::vector<float> floats_;  // normal x, y, z, depth
  std::vector<uint32_t> ids_;  // material, instance
};

// Host buffers of one filter frame, all width * height elements.
struct SvgfFrame {
  const PixelFeatures* features;       // this frame
  const Vec3* radiance;                // this frame's noisy radiance
  const PixelFeatures* prev_features;  // last frame's; null: no history (first frame, reset)
  const Vec4* prev_color;              // last frame's history_color_out
  const Vec4* prev_moments;            // last frame's moments_out
  Vec4* history_color_out;             // out: next frame's colour history
  Vec4* moments_out;                   // out: next frame's moments
  Vec3* output;                        // out: filtered radiance
  Vec4* scratch_a;                     // work space
  Vec4* scratch_b;
  Vec2* depth_slope;   // work space
  SvgfGuide* guide;    // work space
  uint32_t* material;  // work space
  // Work space of svgf_cpu_plane_floats(width, height) floats for the CPU
  // driver's structure-of-arrays planes; null: svgf_run_cpu allocates it
  // per call (the device driver does not use it).
  float* planes = nullptr;
  // Optional, CPU driver only: this frame's compact guide (out), kept for the
  // next frame, and last frame's, which the reprojection then reads instead
  // of prev_features (still required: its presence says there is history).
  // Null guide_out: work space of svgf_run_cpu's own; null prev_guide: the
  // temporal stage compacts prev_features first.
  SvgfCpuGuide* guide_out = nullptr;
  const SvgfCpuGuide* prev_guide = nullptr;
};

size_t svgf_cpu_plane_floats(uint32_t width, uint32_t height);

struct SvgfStageSeconds {
  double temporal = 0.0, variance = 0.0, atrous = 0.0, modulate = 0.0;
  // svgf_run_cpu's PassStop said stop: the outputs are incomplete.
  bool stopped = false;
  double total() const { return temporal + variance + atrous + modulate; }
};

// Which instruction set the CPU filter's row loops use: kBaseline is
// x86-64's SSE2 (what the build targets), kAvx2 AVX2 with FMA (clones of the
// same loops, compiled for it with target attributes), kAuto the best the
// CPU supports (AVX2 unless the environment sets TANDEM_SVGF_ISA=baseline).
// The two give the same image within float rounding.
enum class SvgfCpuIsa { kAuto, kBaseline, kAvx2 };
bool svgf_cpu_avx2_supported();
// What `isa` resolves to on this CPU (kAuto never comes back). Throws
// std::invalid_argument for kAvx2 on a CPU without AVX2 and FMA.
SvgfCpuIsa svgf_cpu_isa(SvgfCpuIsa isa = SvgfCpuIsa::kAuto);
const char* svgf_cpu_isa_name(SvgfCpuIsa isa);

// The stage order both drivers follow: temporal -> variance -> a-trous
// iterations (the first one's output is the next frame's colour history, as
// in Schied et al.; the last one multiplies the albedo back in). Throws
// std::invalid_argument for kAvx2 on a CPU without AVX2 and FMA. `stop` is
// asked between the stages and the iterations; when it says stop, the
// filter returns with `stopped` set and its outputs (the history among
// them) half written.
SvgfStageSeconds svgf_run_cpu(const SvgfParams& params, const SvgfFrame& frame,
                              SvgfCpuIsa isa = SvgfCpuIsa::kAuto, const PassStop& stop = {});

}  // namespace tandem
