// Everything tandem-view does per frame except the window: the scene and
// its motion (arena simulation, glTF animations), the core tracer, adaptive
// quality, and the display image (tone map, optional denoise, split-view
// tint). The SDL/ImGui front end and the headless mode both drive this, so
// the screenshot a test checks is made by the same code the window shows.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "app/scene_setup.h"
#include "app/view/adaptive_quality.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/tracer/core_tracer.h"
#include "scenes/arena_scene.h"
#include "scenes/gltf_animation.h"

namespace tandem {

struct ViewOptions {
  std::string scene = "builtin:arena";
  uint32_t width = 1280, height = 720;  // window / output resolution
  BackendKind backend = BackendKind::kAuto;
  BackendOptions backend_options;  // the CUDA backend's kernel
  double target_fps = 30.0;
  float fixed_scale = 0.0f;  // > 0: fixed resolution scale, no adaptation
  uint32_t max_spp_per_frame = 16;
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

  // Poses the scene's moving content for time t (seconds); returns whether
  // the scene has any (false for static scenes or when paused).
  bool advance_scene(double t);
  bool has_motion() const { return arena_ != nullptr || !animations_.empty(); }
  bool paused = false;

  Scene& scene() { return scene_; }
  const Camera& camera() const { return scene_.camera(); }
  void set_camera(const Camera& camera);

  // Renders one frame; `moving` says whether anything changed since the
  // previous one (then quality drops to hold the frame rate).
  const FrameMetrics& render(bool moving);
  const Quality& quality() const { return quality_; }
  double last_frame_seconds() const { return last_seconds_; }

  // Tone-mapped sRGB of the last frame at render resolution.
  const std::vector<uint8_t>& display() const { return display_; }
  uint32_t display_width() const { return display_w_; }
  uint32_t display_height() const { return display_h_; }
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
  void set_denoise(bool on) { options_.denoise = on; }
  void set_split_view(bool on) { options_.split_view = on; }

  CoreTracer& tracer() { return *tracer_; }
  uint64_t frames() const { return frames_; }

 private:
  void make_display(bool moving);
  TracerSettings tracer_settings() const;

  ViewOptions options_;
  Scene scene_;
  std::unique_ptr<ArenaSimulation> arena_;
  GltfAnimations animations_;
  std::unique_ptr<CoreTracer> tracer_;
  AdaptiveQuality adaptive_;
  Quality quality_;
  double last_seconds_ = 0.0;
  uint64_t frames_ = 0;
  float light_scale_ = 1.0f;
  std::vector<float> light_intensity_, emissive_strength_;  // as loaded
  std::vector<uint8_t> display_;
  uint32_t display_w_ = 0, display_h_ = 0;
};

}  // namespace tandem
