// Holds a target frame rate while things move, converges when they stop.
//
// While the camera or the scene moves, every frame restarts accumulation, so
// the only knobs are resolution and samples: we render one sample per pixel
// and scale the resolution so a frame fits the budget (1 / target fps). When
// everything is still, the full resolution comes back and the samples per
// frame grow to fill the budget, so the image converges as fast as the
// frame rate allows. Pure logic: fed measured frame times, testable.
//
// The controller measures what a frame costs per unit of work (seconds per
// sample of the full-resolution frame; a frame at scale s with n samples is
// s^2 * n units) and picks scales from that cost:
// - a frame slower than kSlowFraction of the budget drops the scale at once
//   to the level its own cost says fits kAimFraction of the budget;
// - frames faster than kFastFraction of the budget, kFastFramesToRise in a
//   row, raise it by up to kMaxRiseLevels levels (never past the level the
//   smoothed cost says fits), so it climbs back in steps while motion goes on;
// - in between nothing changes (hysteresis). Levels are a geometric ladder
//   (kLevelRatio apart) so one level up costs at most kLevelRatio^2 = 1.21
//   times the time, less than kAimFraction / kFastFraction: a rise from a
//   fast frame can never land on a slow one, hence no oscillation.
#pragma once

#include <cstdint>

namespace tandem {

struct AdaptiveSettings {
  double target_fps = 30.0;
  float min_scale = 0.15f;  // of the window's resolution
  float max_scale = 1.0f;
  uint32_t max_spp = 16;  // per frame, when still
  bool enabled = true;    // false: always max_scale and 1 spp
};

struct Quality {
  float scale = 1.0f;
  uint32_t samples_per_frame = 1;
  bool operator==(const Quality&) const = default;
};

class AdaptiveQuality {
 public:
  explicit AdaptiveQuality(AdaptiveSettings settings = {});

  // Quality for the next frame, given whether anything moves in it and how
  // long the previous frame took (<= 0: unknown).
  Quality next(bool moving, double last_frame_seconds);
  const AdaptiveSettings& settings() const { return settings_; }
  void set_target_fps(double fps) { settings_.target_fps = fps; }
  double budget_seconds() const { return 1.0 / settings_.target_fps; }
  // Smoothed seconds per sample of the full-resolution frame; 0 until a
  // frame was measured.
  double cost_per_unit() const { return cost_; }

  static constexpr double kSlowFraction = 1.2;
  static constexpr double kFastFraction = 0.7;
  static constexpr double kAimFraction = 0.85;
  static constexpr int kFastFramesToRise = 2;
  static constexpr int kMaxRiseLevels = 2;
  static constexpr float kLevelRatio = 1.1f;

 private:
  int level_of(float scale) const;  // the highest level not above `scale`
  float scale_of(int level) const;
  int top_level() const;
  // The highest level whose frame is predicted to take at most kAimFraction
  // of the budget at `cost` seconds per unit.
  int fitting_level(double cost) const;

  AdaptiveSettings settings_;
  int motion_level_;  // kept between motion periods
  uint32_t still_spp_ = 1;
  bool was_moving_ = false;
  int fast_frames_ = 0;
  double cost_ = 0.0;
  Quality last_;
};

}  // namespace tandem
