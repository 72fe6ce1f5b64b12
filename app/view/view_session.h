// Everything tandem-view does per frame except the window: the scene and
// its motion (arena simulation, glTF animations), the core tracer, adaptive
// quality, and the display image (tone map, optional denoise, split-view
// tint). The SDL/ImGui front end and the headless mode both drive this, so
// the screenshot a test checks is made by the same code the window shows.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/scene_setup.h"
#include "app/view/adaptive_quality.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/tracer/core_tracer.h"
#include "scenes/scene_animator.h"

namespace tandem {

struct ViewOptions {
  std::string scene = "builtin:arena";
  uint32_t width = 1280, height = 720;  // window / output resolution
  BackendKind backend = BackendKind::kAuto;
  BackendOptions backend_options;  // the CUDA backend's kernel
  double target_fps = 30.0;
  float fixed_scale = 0.0f;  // > 0: fixed resolution scale, no adaptation
  // > 0 (with fixed_scale): this many samples every frame (`bench --frames`).
  uint32_t fixed_samples_per_frame = 0;
  uint32_t max_spp_per_frame = 16;
  // Samples per pixel at which a still image counts as converged: the
  // viewer stops rendering it until something changes.
  uint32_t target_spp = 1024;
  uint32_t max_depth = 4;
  float exposure = 0.0f;  // stops
  bool denoise = true;    // edge-aware filter on motion frames
  bool split_view = false;
  // How `scene` is loaded and lit (app/scene_setup.h: one rule for every
  // command); parse_scene_request() fills both from the command line.
  SceneLoadOptions scene_load;
  EnvironmentRequest environment;
};

class ViewSession {
 public:
  explicit ViewSession(const ViewOptions& options);

  // Scene motion (arena simulation, glTF node animations).
  const SceneAnimator& animator() const { return *animator_; }
  bool has_motion() const { return animator_->animated(); }
  bool paused = false;
  // Poses the scene for time t (seconds) now; returns whether it has moving
  // content to pose (false for static scenes or when paused).
  bool advance_scene(double t);
  double scene_time() const { return scene_time_; }

  Scene& scene() { return scene_; }
  const Camera& camera() const { return scene_.camera(); }
  void set_camera(const Camera& camera);
  // The camera the scene was loaded with (or framed on load): Home/R.
  const Camera& initial_camera() const { return initial_camera_; }
  void reset_camera() { set_camera(initial_camera_); }

  // One frame of the core tracer's loop, the same for the window, the
  // headless script and `bench --frames`: renders the scene as it is now
  // (`camera_moved`: the camera changed since the previous frame; a scene
  // posed since then counts as motion too), and while the backends render
  // poses the scene for `next_scene_time` (the next frame's time; none: no
  // next frame, or nothing to pose) and compiles the next frame where the
  // backends allow it.
  const FrameMetrics& render_frame(bool camera_moved, std::optional<double> next_scene_time);
  // render_frame() without posing anything for the next frame.
  const FrameMetrics& render(bool moving) { return render_frame(moving, std::nullopt); }
  // Still, and the accumulated samples reached the target: rendering more
  // would not change what is seen until something moves.
  bool converged() const;
  uint32_t accumulated_spp() const { return tracer_->accumulated_spp(); }
  uint32_t target_spp() const { return options_.target_spp; }
  void set_target_spp(uint32_t spp) { options_.target_spp = std::max(spp, 1u); }
  // Whether the last rendered frame was a motion frame.
  bool last_frame_moving() const { return last_moving_; }
  const Quality& quality() const { return quality_; }
  double last_frame_seconds() const { return last_seconds_; }

  // Tone-mapped sRGB of the last frame at render resolution (made on first
  // use after each frame: a scripted run only pays for the last one).
  const std::vector<uint8_t>& display() const;
  uint32_t display_width() const;
  uint32_t display_height() const;
  // Writes the last frame resampled to the output resolution (atomic PNG).
  void screenshot(const std::filesystem::path& path) const;

  // --- panel controls (each restarts accumulation when it changes) ---------
  const ViewOptions& options() const { return options_; }
  void set_backend(BackendKind kind);
  BackendKind backend_kind() const { return options_.backend; }
  void set_output_size(uint32_t width, uint32_t height);
  void set_max_depth(uint32_t depth);
  void set_max_spp_per_frame(uint32_t spp);
  void set_target_fps(double fps);
  void set_exposure(float stops);  // display only: no restart
  void set_light_scale(float scale);
  float light_scale() const { return light_scale_; }
  void set_lens(float aperture, float focus_distance);
  void set_denoise(bool on) {
    options_.denoise = on;
    display_stale_ = frames_ > 0;
  }
  void set_split_view(bool on) {
    options_.split_view = on;
    display_stale_ = frames_ > 0;
  }

  CoreTracer& tracer() { return *tracer_; }
  uint64_t frames() const { return frames_; }

 private:
  void make_display() const;
  TracerSettings tracer_settings() const;

  ViewOptions options_;
  Scene scene_;
  std::unique_ptr<SceneAnimator> animator_;
  Camera initial_camera_;
  double scene_time_ = 0.0;
  bool scene_posed_ = false;  // posed since the last rendered frame
  bool last_moving_ = true;
  bool restart_pending_ = false;  // a setting changed that the next frame applies
  std::unique_ptr<CoreTracer> tracer_;
  AdaptiveQuality adaptive_;
  Quality quality_;
  double last_seconds_ = 0.0;
  uint64_t frames_ = 0;
  float light_scale_ = 1.0f;
  std::vector<float> light_intensity_, emissive_strength_;  // as loaded
  mutable std::vector<uint8_t> display_;
  mutable uint32_t display_w_ = 0, display_h_ = 0;
  mutable bool display_stale_ = false;
};

}  // namespace tandem
