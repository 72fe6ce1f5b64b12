#include "app/view/adaptive_quality.h"

#include <algorithm>
#include <cmath>

namespace tandem {

namespace {
// Weight of the newest frame in the smoothed cost: a few frames of memory,
// enough to ride over timing jitter, short enough to follow a new view.
constexpr double kCostSmoothing = 0.3;
}  // namespace

AdaptiveQuality::AdaptiveQuality(AdaptiveSettings settings) : settings_(settings) {
  motion_level_ = top_level();
  last_.scale = settings_.max_scale;
}

int AdaptiveQuality::top_level() const {
  const double ratio = double(settings_.max_scale) / double(settings_.min_scale);
  if (ratio <= 1.0) return 0;
  return int(std::ceil(std::log(ratio) / std::log(double(kLevelRatio)) - 1e-9));
}

float AdaptiveQuality::scale_of(int level) const {
  level = std::clamp(level, 0, top_level());
  if (level == top_level()) return settings_.max_scale;
  return std::min(settings_.max_scale,
                  float(double(settings_.min_scale) * std::pow(double(kLevelRatio), level)));
}

int AdaptiveQuality::level_of(float scale) const {
  if (scale >= settings_.max_scale) return top_level();
  if (scale <= settings_.min_scale) return 0;
  const double l =
      std::log(double(scale) / double(settings_.min_scale)) / std::log(double(kLevelRatio));
  return std::clamp(int(std::floor(l + 1e-6)), 0, top_level());
}

int AdaptiveQuality::fitting_level(double cost) const {
  if (cost <= 0.0) return top_level();
  const double fit = std::sqrt(kAimFraction * budget_seconds() / cost);
  return level_of(float(std::min(fit, double(settings_.max_scale))));
}

Quality AdaptiveQuality::next(bool moving, double last_seconds) {
  if (!settings_.enabled) {
    last_ = {settings_.max_scale, 1};
    return last_;
  }
  const double budget = budget_seconds();
  const bool measured = last_seconds > 0.0;
  double frame_cost = 0.0;  // of the last frame alone
  if (measured) {
    const double units =
        double(last_.scale) * double(last_.scale) * double(std::max(last_.samples_per_frame, 1u));
    frame_cost = last_seconds / std::max(units, 1e-12);
    cost_ = cost_ > 0.0 ? (1.0 - kCostSmoothing) * cost_ + kCostSmoothing * frame_cost : frame_cost;
  }
  if (moving) {
    if (measured && !was_moving_) {
      // Motion starts after still frames: their cost says where to begin.
      motion_level_ = fitting_level(frame_cost);
      fast_frames_ = 0;
    } else if (measured) {
      const int current = level_of(last_.scale);
      if (last_seconds > kSlowFraction * budget) {
        // Too slow: a late frame is visible, drop at once.
        motion_level_ = std::min(fitting_level(frame_cost), std::max(current - 1, 0));
        fast_frames_ = 0;
      } else if (last_seconds < kFastFraction * budget) {
        if (++fast_frames_ >= kFastFramesToRise) {
          const int fit = std::min(fitting_level(cost_), fitting_level(frame_cost));
          // One level always fits after a fast frame (see the header); the
          // smoothed cost may allow more.
          const int rise = std::clamp(fit - current, 1, kMaxRiseLevels);
          motion_level_ = std::min(current + rise, top_level());
          fast_frames_ = 0;
        }
      } else {
        fast_frames_ = 0;  // inside the band: keep the resolution
      }
    }
    last_ = {scale_of(motion_level_), 1};
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
    fast_frames_ = 0;
  }
  was_moving_ = moving;
  return last_;
}

}  // namespace tandem
