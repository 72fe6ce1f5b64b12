// tandem-view's denoising policy and its debug views, as pure functions the
// session (app/view/view_session.h) calls and the view tests check.
//
// What a user sees:
//   moving (every frame restarts accumulation): the SVGF output of this
//     frame's samples (core/render/temporal_denoiser.h), whose history
//     follows the camera and the moving objects through the motion vectors;
//   still (samples accumulate): SVGF keeps filtering each frame's own
//     samples and the display blends from it to the plain accumulated image
//     as the samples grow (accumulated_blend_weight): at kDenoiseBlendStartSpp
//     the filtered image, at kDenoiseBlendEndSpp the accumulated one, which
//     then converges without the filter's bias (blur of fine detail). The
//     filter stops running once the blend no longer needs it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/image/image.h"
#include "core/kernel/features.h"
#include "core/render/denoise_blend.h"

namespace tandem {

// What the viewer shows: the image, or one of the denoiser's buffers.
enum class ViewBuffer : int {
  kImage = 0,
  kAlbedo,    // base colour at the primary hit (sRGB)
  kNormal,    // shading normal, n * 0.5 + 0.5
  kDepth,     // linear depth, near bright, normalised by the frame's farthest hit
  kMotion,    // motion vector: 0.5 + motion / (2 * kMotionViewPixels) in red/green
  kVariance,  // luminance standard deviation of the history, s / (1 + s)
  kHistory,   // history length / max history (grey); red where it was just rejected
  kCount
};
const char* view_buffer_name(ViewBuffer b);
// The buffer a name (view_buffer_name, or its first word) stands for.
std::optional<ViewBuffer> parse_view_buffer(const std::string& name);

// Motion of this many pixels per frame saturates the motion view.
constexpr float kMotionViewPixels = 16.0f;

// 8-bit RGB of a debug view (not kImage) at the features' resolution.
// `moments` (the denoiser's (m1, m2, length, 0) per pixel) may be empty:
// variance and history then show black.
std::vector<uint8_t> feature_view_rgb8(ViewBuffer view, const std::vector<PixelFeatures>& features,
                                       const std::vector<Vec4>& moments, uint32_t max_history,
                                       uint32_t width, uint32_t height);

}  // namespace tandem
