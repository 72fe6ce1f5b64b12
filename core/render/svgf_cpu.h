// One frame of the variance-guided filter (core/kernel/svgf.h) over host
// buffers, each stage a TBB loop over rows running the shared per-pixel
// functions. backends/cuda/svgf_device.h runs the same sequence on the GPU.
#pragma once

#include "core/kernel/svgf.h"

namespace tandem {

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
};

struct SvgfStageSeconds {
  double temporal = 0.0, variance = 0.0, atrous = 0.0, modulate = 0.0;
  double total() const { return temporal + variance + atrous + modulate; }
};

// The stage order both drivers follow: temporal -> variance -> a-trous
// iterations (the first one's output is the next frame's colour history, as
// in Schied et al.; the last one multiplies the albedo back in).
SvgfStageSeconds svgf_run_cpu(const SvgfParams& params, const SvgfFrame& frame);

}  // namespace tandem
