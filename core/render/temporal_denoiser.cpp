#include "core/render/temporal_denoiser.h"

#include <functional>
#include <iterator>
#include <stdexcept>
#include <string>

namespace tandem {

ImageRGB TemporalDenoiser::process(const std::vector<PixelFeatures>& features,
                                   const ImageRGB& radiance) {
  ImageRGB out;
  process(features, radiance, out, {});
  return out;
}

bool TemporalDenoiser::size_for(uint32_t width, uint32_t height, const PassStop& stop) {
  if (width == width_ && height == height_) return true;
  const size_t n = size_t(width) * height;
  // No history from here on; no size either until every buffer has it.
  width_ = height_ = 0;
  has_history_ = false;
  cpu_guide_current_[0] = cpu_guide_current_[1] = false;
  // Without history nothing of these is read before the filter writes it:
  // they are sized, not cleared (a viewer switching between its motion and
  // still resolutions would otherwise rewrite them each time). The planes'
  // padding is cleared. A new, larger size faults in ~400 MB at 1280x720
  // (~80 ms here), so `stop` is asked between groups of buffers.
  const std::function<void()> groups[] = {
      [&] {
        features_[0].resize(n);
        features_[1].resize(n);
      },
      [&] {
        for (int k = 0; k < 2; ++k) {
          color_[k].resize(n);
          moments_[k].resize(n);
        }
      },
      [&] {
        scratch_a_.resize(n);
        scratch_b_.resize(n);
        radiance_.resize(n);
        output_.resize(n);
        depth_slope_.resize(n);
        guide_.resize(n);
        material_.resize(n);
      },
      [&] { planes_.assign(svgf_cpu_plane_floats(width, height), 0.0f); },
      [&] {
        for (SvgfCpuGuide& g : cpu_guide_)
          g.resize(n);
      },
  };
  for (size_t i = 0; i < std::size(groups); ++i) {
    if (i > 0 && pass_should_stop(stop)) return false;
    groups[i]();
  }
  width_ = width;
  height_ = height;
  return true;
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
    if (!size_for(radiance.width, radiance.height, stop) || pass_should_stop(stop)) return false;
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
