// Everything tandem-view does per frame except the window: the scene and
// its motion (arena simulation, glTF animations), the core tracer, adaptive
// quality, and the display image (tone map, optional denoise, split-view
// tint). The SDL/ImGui front end and the headless mode both drive this, so
// the screenshot a test checks is made by the same code the window shows.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/scene_setup.h"
#include "app/view/adaptive_quality.h"
#include "app/view/denoise_view.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/render/temporal_denoiser.h"
#include "core/world/motion_history.h"
#include "scenes/scene_animator.h"
#include "tracer/core_tracer.h"

namespace tandem {

struct ViewOptions {
  std::string scene = "builtin:arena";
  uint32_t width = 1280, height = 720;  // window / output resolution
  BackendKind backend = BackendKind::kAuto;
  BackendOptions backend_options;  // the CUDA backend's kernel
  double target_fps = 30.0;
  float fixed_scale = 0.0f;  // > 0: fixed resolution scale, no adaptation
  // The lowest scale adaptation goes to while things move. Chosen from the
  // motion relMSE and frame rate of fixed scales (docs/performance.md).
  float min_scale = 0.15f;
  // > 0 (with fixed_scale): this many samples every frame (`bench --frames`).
  uint32_t fixed_samples_per_frame = 0;
  uint32_t max_spp_per_frame = 16;
  // Samples per pixel at which a still image counts as converged: the
  // viewer stops rendering it until something changes.
  uint32_t target_spp = 1024;
  uint32_t max_depth = 4;
  LightSampler light_sampler = RenderSettings{}.light_sampler;
  float exposure = 0.0f;  // stops
  // SVGF on every frame until the accumulated image takes over
  // (app/view/denoise_view.h says what is shown when).
  bool denoise = true;
  ViewBuffer view_buffer = ViewBuffer::kImage;  // what the display shows
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
  // Wall time of the last advance_scene() that posed anything (its
  // skinning and morphing included), in seconds.
  double last_pose_seconds() const { return last_pose_seconds_; }
  double scene_time() const { return scene_time_; }

  Scene& scene() { return scene_; }
  const Camera& camera() const { return scene_.camera(); }
  void set_camera(const Camera& camera);
  // The camera the scene was loaded with (or framed on load): Home/R.
  const Camera& initial_camera() const { return initial_camera_; }
  void reset_camera() { set_camera(initial_camera_); }
  // The glTF file's cameras (its scene's camera nodes, `--camera N`): the
  // next one, which Home/R then return to; nothing with fewer than two.
  void next_file_camera();
  size_t file_camera_count() const { return file_cameras_.size(); }
  int file_camera_index() const { return camera_index_; }

  // One frame of the core tracer's loop, the same for the window, the
  // headless script and `bench --frames`: renders the scene as it is now
  // (`camera_moved`: the camera changed since the previous frame; a scene
  // posed since then counts as motion too), and while the backends render
  // poses the scene for `next_scene_time` (the next frame's time; none: no
  // next frame, or nothing to pose) and compiles the next frame where the
  // backends allow it.
  //
  // With `poll`, the caller reads input while the frame renders: poll() is
  // called every input_slice_seconds() until the backends are done, and
  // its returning true cancels the frame (CoreTracer::cancel_frame: it ends
  // after the tiles in flight, its samples dropped, the display kept as it
  // was; FrameMetrics::cancelled). The feature pass and the denoiser that
  // follow call it between their parts (bands of rows, filter stages);
  // true there gives the frame up too (cancelled, the display kept; the
  // samples stay accumulated and the denoiser starts afresh). poll() must
  // not change the session: the caller keeps what it reads for after.
  using InputPoll = std::function<bool()>;
  const FrameMetrics& render_frame(bool camera_moved, std::optional<double> next_scene_time,
                                   const InputPoll& poll = {});
  // How often render_frame() polls: well under the 50 ms a key may wait.
  static constexpr double input_slice_seconds() { return 0.01; }
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
  // The linear radiance display() tone-maps (the image view), at render
  // resolution: what the motion quality is measured on.
  ImageRGB shown_linear() const;
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
  // Turning the denoiser off or on drops its history (the next frame starts
  // it afresh).
  void set_denoise(bool on);
  bool denoise() const { return options_.denoise; }
  // Which buffer the display shows (the image or a denoiser debug view).
  void set_view_buffer(ViewBuffer b);
  ViewBuffer view_buffer() const { return view_buffer_; }
  // Whether the last frame's display contains the SVGF output (false: the
  // denoiser is off, the accumulated image has taken over, or no backend
  // has a feature pass), and with what weight the accumulated image is
  // blended in.
  bool showing_denoised() const {
    return options_.denoise && denoised_frame_ == frames_ && frames_ > 0;
  }
  float accumulated_weight() const { return blend_; }
  // The last frame's own samples (what the denoiser filtered), its output,
  // its features and the denoiser itself, for tests and the panel.
  const ImageRGB& frame_radiance() const { return frame_radiance_; }
  const ImageRGB& denoised_image() const { return denoised_; }
  const std::vector<PixelFeatures>& features() const { return features_; }
  const TemporalDenoiser& denoiser() const { return denoiser_; }
  // Seconds the last frame spent in the feature pass and the filter.
  double last_denoise_seconds() const { return denoise_seconds_; }
  void set_split_view(bool on) {
    options_.split_view = on;
    display_stale_ = frames_ > 0;
  }

  CoreTracer& tracer() { return *tracer_; }
  uint64_t frames() const { return frames_; }

 private:
  void make_display() const;
  TracerSettings tracer_settings() const;
  // After a frame: this frame's samples, features, the filter, the blend,
  // reading input through `poll` between their parts. Returns false, having
  // changed nothing shown, when poll() asked to stop.
  bool denoise_frame(const FrameMetrics& m, const InputPoll& poll);
  void drop_denoise_history();

  ViewOptions options_;
  Scene scene_;
  std::unique_ptr<SceneAnimator> animator_;
  Camera initial_camera_;
  std::vector<Camera> file_cameras_;  // the first 100 of the file's, as loaded
  int camera_index_ = 0;
  double scene_time_ = 0.0;
  bool scene_posed_ = false;  // posed since the last rendered frame
  double last_pose_seconds_ = 0.0;
  bool last_moving_ = true;
  bool restart_pending_ = false;  // a setting changed that the next frame applies
  std::unique_ptr<CoreTracer> tracer_;
  AdaptiveQuality adaptive_;
  Quality quality_;
  double last_seconds_ = 0.0;
  FrameMetrics stopped_metrics_;  // what render_frame() returns for a frame given up in the filter
  uint64_t frames_ = 0;
  float light_scale_ = 1.0f;
  std::vector<float> light_intensity_, emissive_strength_;  // as loaded
  // The denoiser's state (app/view/denoise_view.h).
  ViewBuffer view_buffer_;
  MotionHistory motion_;
  TemporalDenoiser denoiser_;
  std::vector<PixelFeatures> features_;
  uint64_t features_frame_ = 0;  // frames_ value the features belong to (0: none)
  ImageRGB accumulated_, frame_radiance_, denoised_;
  uint32_t accumulated_spp_before_ = 0;  // spp of accumulated_ before the last frame
  uint64_t denoised_frame_ = 0;          // frames_ value denoised_ belongs to (0: none)
  float blend_ = 1.0f;
  double denoise_seconds_ = 0.0;
  mutable std::vector<uint8_t> display_;
  mutable uint32_t display_w_ = 0, display_h_ = 0;
  mutable bool display_stale_ = false;
};

}  // namespace tandem
