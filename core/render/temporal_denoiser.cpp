#include "core/render/temporal_denoiser.h"

#include <stdexcept>
#include <string>

namespace tandem {

ImageRGB TemporalDenoiser::process(const std::vector<PixelFeatures>& features,
                                   const ImageRGB& radiance) {
  ImageRGB out;
  process(features, radiance, out, {});
  return out;
}

bool TemporalDenoiser::process(const std::vector<PixelFeatures>& features, const ImageRGB& radiance,
                               ImageRGB& out, const PassStop& stop) {
  const size_t n = size_t(radiance.width) * radiance.height;
  if (features.size() != n) {
    throw std::invalid_argument("TemporalDenoiser: " + std::to_string(features.size()) +
                                " feature records for a " + std::to_string(radiance.width) + "x" +
                                std::to_string(radiance.height) + " image");
  }
  if (radiance.width != width_ || radiance.height != height_) {
    width_ = radiance.width;
    height_ = radiance.height;
    has_history_ = false;
    for (int k = 0; k < 2; ++k) {
      features_[k].assign(n, PixelFeatures{});
      color_[k].assign(n, Vec4{});
      moments_[k].assign(n, Vec4{});
    }
    scratch_a_.assign(n, Vec4{});
    scratch_b_.assign(n, Vec4{});
    radiance_.assign(n, Vec3{});
    output_.assign(n, Vec3{});
    depth_slope_.assign(n, Vec2{});
    guide_.assign(n, SvgfGuide{});
    material_.assign(n, 0u);
    planes_.assign(svgf_cpu_plane_floats(width_, height_), 0.0f);
    for (SvgfCpuGuide& g : cpu_guide_)
      g.resize(n);
    cpu_guide_current_[0] = cpu_guide_current_[1] = false;
  }
  for (size_t i = 0; i < n; ++i)
    radiance_[i] = make_vec3(radiance.rgb[3 * i], radiance.rgb[3 * i + 1], radiance.rgb[3 * i + 2]);
  const int prev = current_, next = 1 - current_;
  features_[next] = features;
  SvgfParams p = params_;
  p.width = width_;
  p.height = height_;
  SvgfFrame frame{features_[next].data(),
                  radiance_.data(),
                  has_history_ ? features_[prev].data() : nullptr,
                  color_[prev].data(),
                  moments_[prev].data(),
                  color_[next].data(),
                  moments_[next].data(),
                  output_.data(),
                  scratch_a_.data(),
                  scratch_b_.data(),
                  depth_slope_.data(),
                  guide_.data(),
                  material_.data(),
                  planes_.data()};
  if (pass_should_stop(stop)) {
    has_history_ = false;  // features_[next] is this frame's, the rest last frame's
    return false;
  }
  last_on_cpu_ = !offload_ || !offload_->run(p, frame, &last_seconds_);
  if (last_on_cpu_) {
    frame.guide_out = &cpu_guide_[next];
    // The previous frame's guide only if the CPU filter wrote it; without
    // it svgf_run_cpu derives it from the previous features.
    if (has_history_ && cpu_guide_current_[prev]) frame.prev_guide = &cpu_guide_[prev];
    last_seconds_ = svgf_run_cpu(p, frame, SvgfCpuIsa::kAuto, stop);
    if (last_seconds_.stopped) {
      // The next frame's history (colour, moments, guide) is half written.
      cpu_guide_current_[next] = false;
      has_history_ = false;
      return false;
    }
  }
  cpu_guide_current_[next] = last_on_cpu_;
  current_ = next;
  has_history_ = true;
  out = ImageRGB(width_, height_);
  for (size_t i = 0; i < n; ++i) {
    out.rgb[3 * i] = output_[i].x;
    out.rgb[3 * i + 1] = output_[i].y;
    out.rgb[3 * i + 2] = output_[i].z;
  }
  return true;
}

}  // namespace tandem
