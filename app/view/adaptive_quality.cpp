#include "app/view/adaptive_quality.h"

#include <algorithm>
#include <cmath>

namespace tandem {

AdaptiveQuality::AdaptiveQuality(AdaptiveSettings settings)
    : settings_(settings), motion_scale_(settings.max_scale) {
  last_.scale = settings_.max_scale;
}

Quality AdaptiveQuality::next(bool moving, double last_seconds) {
  if (!settings_.enabled) {
    last_ = {settings_.max_scale, 1};
    return last_;
  }
  const double budget = budget_seconds();
  const bool measured = last_seconds > 0.0;
  if (moving) {
    // Frame cost is roughly proportional to pixels, i.e. to scale^2. The
    // previous frame's time is only meaningful for the previous quality.
    if (measured && was_moving_) {
      const double per_sample = last_seconds / double(std::max(last_.samples_per_frame, 1u));
      float factor = float(std::sqrt(budget / std::max(per_sample, 1e-6)));
      // Fall fast (a slow frame is visible), climb slowly (avoid oscillation).
      factor = std::clamp(factor, 0.5f, 1.1f);
      if (factor > 0.95f && factor < 1.05f) factor = 1.0f;  // dead band
      float s = last_.scale * factor;
      s = std::round(s / kScaleStep) * kScaleStep;
      motion_scale_ = std::clamp(s, settings_.min_scale, settings_.max_scale);
    }
    last_ = {motion_scale_, 1};
    still_spp_ = 1;
  } else {
    if (measured && !was_moving_) {
      // Grow (or shrink) the samples per frame towards the budget.
      const double per_sample = last_seconds / double(std::max(last_.samples_per_frame, 1u));
      const double fit = std::floor(budget / std::max(per_sample, 1e-6));
      const uint32_t want = uint32_t(std::clamp(fit, 1.0, double(settings_.max_spp)));
      // Double at most per frame so one fast frame cannot stall the next.
      still_spp_ = std::min(want, std::max(still_spp_ * 2, 1u));
    } else {
      still_spp_ = 1;
    }
    last_ = {settings_.max_scale, still_spp_};
  }
  was_moving_ = moving;
  return last_;
}

}  // namespace tandem
