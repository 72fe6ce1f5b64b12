// Holds a target frame rate while things move, converges when they stop.
//
// While the camera or the scene moves, every frame restarts accumulation, so
// the only knobs are resolution and samples: we render one sample per pixel
// and scale the resolution so a frame fits the budget (1 / target fps). When
// everything is still, the full resolution comes back and the samples per
// frame grow to fill the budget, so the image converges as fast as the
// frame rate allows. Pure logic: fed measured frame times, testable.
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

  // Scale steps are coarse so small timing jitter does not change the
  // resolution (and resize the film) every frame.
  static constexpr float kScaleStep = 0.05f;

 private:
  AdaptiveSettings settings_;
  float motion_scale_;  // kept between motion periods: the next one starts there
  uint32_t still_spp_ = 1;
  bool was_moving_ = false;
  Quality last_;
};

}  // namespace tandem
