#include "app/view/view_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>

#include "app/view/image_filters.h"
#include "core/util/errors.h"
#include "scenes/gltf_loader.h"

namespace tandem {

namespace {

AdaptiveSettings adaptive_settings(const ViewOptions& o) {
  AdaptiveSettings a;
  a.target_fps = o.target_fps;
  a.max_spp = o.max_spp_per_frame;
  a.min_scale = o.min_scale;
  if (o.fixed_scale > 0.0f) {
    a.enabled = false;
    a.max_scale = o.fixed_scale;
  }
  return a;
}

}  // namespace

ViewSession::ViewSession(const ViewOptions& options)
    : options_(options), adaptive_(adaptive_settings(options)), view_buffer_(options.view_buffer) {
  GltfAnimations animations;
  SceneRequest request{options.scene, options.scene_load, options.environment, true};
  request.load.animations = &animations;  // tandem-view plays node animations
  GltfSummary gltf;
  request.load.gltf_summary = &gltf;  // the file's cameras, for C
  scene_ = load_requested_scene(request, "tandem-view");
  file_cameras_ = std::move(gltf.camera_list);
  camera_index_ = std::max(options.scene_load.camera, 0);
  animator_ = make_scene_animator(scene_, std::move(animations));
  if (!scene_.has_camera()) {
    // Over the whole animation, which the viewer plays.
    scene_.set_camera(frame_bounds_camera(animation_bounds(*animator_, scene_), 0.6911112f,
                                          float(options.width) / float(options.height)));
  }
  initial_camera_ = scene_.camera();
  for (const Light& l : scene_.lights())
    light_intensity_.push_back(l.intensity);
  for (const Material& m : scene_.materials())
    emissive_strength_.push_back(m.emissive_strength);
  tracer_ = std::make_unique<CoreTracer>(
      create_backends(options_.backend, options_.backend_options), tracer_settings());
}

TracerSettings ViewSession::tracer_settings() const {
  TracerSettings s;
  const float scale = quality_.scale;
  s.render.width = std::max(8u, uint32_t(std::lround(float(options_.width) * scale)));
  s.render.height = std::max(8u, uint32_t(std::lround(float(options_.height) * scale)));
  s.render.max_depth = options_.max_depth;
  s.render.light_sampler = options_.light_sampler;
  s.samples_per_frame = options_.fixed_samples_per_frame > 0 && options_.fixed_scale > 0.0f
                            ? options_.fixed_samples_per_frame
                            : quality_.samples_per_frame;
  s.tile_size = 32;
  return s;
}

bool ViewSession::advance_scene(double t) {
  if (paused || !has_motion()) return false;
  const auto start = std::chrono::steady_clock::now();
  animator_->pose(t, scene_);
  last_pose_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  scene_time_ = t;
  scene_posed_ = true;
  return true;
}

void ViewSession::set_camera(const Camera& camera) {
  scene_.edit_camera() = camera;
}

void ViewSession::next_file_camera() {
  if (file_cameras_.size() < 2) return;
  camera_index_ = (camera_index_ + 1) % int(file_cameras_.size());
  // Where the loader focused the first one: the lens keeps its setting.
  Camera c = file_cameras_[size_t(camera_index_)];
  c.aperture_radius = scene_.camera().aperture_radius;
  c.focus_distance = scene_.camera().focus_distance;
  set_camera(c);
  initial_camera_ = scene_.camera();  // Home/R return to the chosen one
}

bool ViewSession::converged() const {
  return !last_moving_ && !restart_pending_ && !scene_.any_dirty() &&
         tracer_->accumulated_spp() >= options_.target_spp;
}

const FrameMetrics& ViewSession::render_frame(bool camera_moved,
                                              std::optional<double> next_scene_time,
                                              const InputPoll& poll) {
  const bool moving = camera_moved || scene_posed_;
  quality_ = adaptive_.next(moving, last_seconds_);
  TracerSettings settings = tracer_settings();
  if (!moving && !(options_.fixed_scale > 0.0f)) {
    // Land on the target exactly instead of overshooting it.
    const uint32_t have = tracer_->accumulated_spp();
    const uint32_t left = options_.target_spp > have ? options_.target_spp - have : 1u;
    settings.samples_per_frame = std::clamp(settings.samples_per_frame, 1u, left);
  }
  // Only a change of resolution or depth restarts accumulation; samples per
  // frame just add more samples to the same pixels.
  tracer_->set_settings(settings);
  scene_posed_ = false;
  restart_pending_ = false;
  std::function<void(Scene&)> advance;
  if (next_scene_time && has_motion() && !paused) {
    const double t = *next_scene_time;
    advance = [this, t](Scene&) { advance_scene(t); };
  }
  // The next frame is posed while this one renders. With features to take
  // (the denoiser, a debug view) it is compiled only at the next
  // begin_frame(), after the feature pass has seen this frame's scene;
  // otherwise prepare_next_frame() compiles it now where the backends
  // allow it (GPU-only lists).
  const bool features = options_.denoise || view_buffer_ != ViewBuffer::kImage;
  tracer_->begin_frame(scene_);
  try {
    if (advance) {
      advance(scene_);
      if (!features) tracer_->prepare_next_frame(scene_);
    }
    if (poll) {
      bool cancelled = false;
      while (!tracer_->wait_rendered(input_slice_seconds())) {
        if (poll() && !cancelled) {
          tracer_->cancel_frame();
          cancelled = true;
        }
      }
    }
  } catch (...) {
    tracer_->end_frame();  // the render threads must be joined before anything else
    throw;
  }
  const FrameMetrics& m = tracer_->end_frame();
  if (m.cancelled) {
    // Nothing of it is shown; the next frame starts accumulating afresh.
    restart_pending_ = true;
    return m;
  }
  if (!denoise_frame(m, poll)) {
    // Input came while the frame was filtered: it is not shown (its
    // samples stay accumulated; the next frame shows them with its own).
    restart_pending_ = true;
    stopped_metrics_ = m;
    stopped_metrics_.cancelled = true;
    return stopped_metrics_;
  }
  last_moving_ = moving;
  ++frames_;
  // The filter is part of what a frame costs: adaptive quality sees both.
  last_seconds_ = m.total_seconds + denoise_seconds_;
  display_stale_ = true;
  return m;
}

void ViewSession::drop_denoise_history() {
  motion_.reset();
  denoiser_.reset();
}

bool ViewSession::denoise_frame(const FrameMetrics& m, const InputPoll& poll) {
  const auto start = std::chrono::steady_clock::now();
  const uint64_t frame = frames_ + 1;  // the frame being finished
  const uint32_t spp = tracer_->accumulated_spp();
  const uint32_t before = m.accumulation_reset ? 0u : accumulated_spp_before_;
  const float blend = options_.denoise ? accumulated_blend_weight(spp) : 1.0f;
  const bool filter = options_.denoise && blend < 1.0f;
  // The feature pass and the filter read input between their parts: at
  // full resolution on the CPU they take ~100 ms together.
  bool stopped = false;
  PassStop stop;
  if (poll) stop = [&] { return stopped = stopped || poll(); };
  auto give_up = [&] {
    drop_denoise_history();  // the motion history has advanced past it
    features_frame_ = 0;     // features_ is half written
    return false;
  };
  ImageRGB now = tracer_->image();
  if (filter || view_buffer_ != ViewBuffer::kImage) {
    if (pass_should_stop(stop)) return give_up();
    const bool have = tracer_->render_features(motion_, features_, stop);
    if (stopped) return give_up();
    features_frame_ = have ? frame : 0;
  }
  if (filter && features_frame_ == frame) {
    if (pass_should_stop(stop)) return give_up();
    frame_radiance_ = frame_samples(now, spp, accumulated_, before);
    if (!denoiser_.process(features_, frame_radiance_, denoised_, stop)) return give_up();
    denoised_frame_ = frame;
  } else if (options_.denoise && !filter) {
    // The accumulated image has taken over: when things move again the
    // filter starts afresh rather than from a stale history.
    drop_denoise_history();
  }
  blend_ = blend;
  accumulated_ = std::move(now);
  accumulated_spp_before_ = spp;
  denoise_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return true;
}

void ViewSession::set_denoise(bool on) {
  if (on == options_.denoise) return;
  options_.denoise = on;
  drop_denoise_history();
  display_stale_ = frames_ > 0;
}

void ViewSession::set_view_buffer(ViewBuffer b) {
  if (b == view_buffer_) return;
  view_buffer_ = b;
  if (b != ViewBuffer::kImage && frames_ > 0 && features_frame_ != frames_) {
    // A still, converged view renders no more frames: the buffers of the
    // frame on screen now (nothing moved since it, so no motion either).
    MotionHistory still;
    features_frame_ = tracer_->render_features(still, features_) ? frames_ : 0;
  }
  display_stale_ = frames_ > 0;
}

const std::vector<uint8_t>& ViewSession::display() const {
  if (display_stale_) make_display();
  return display_;
}
uint32_t ViewSession::display_width() const {
  if (display_stale_) make_display();
  return display_w_;
}
uint32_t ViewSession::display_height() const {
  if (display_stale_) make_display();
  return display_h_;
}

void ViewSession::make_display() const {
  const uint32_t w = accumulated_.width, h = accumulated_.height;
  if (view_buffer_ != ViewBuffer::kImage) {
    static const std::vector<Vec4> kNoMoments;
    const bool fresh = denoised_frame_ == frames_;
    display_ =
        features_frame_ == frames_
            ? feature_view_rgb8(view_buffer_, features_, fresh ? denoiser_.moments() : kNoMoments,
                                denoiser_.params().max_history, w, h)
            : std::vector<uint8_t>(size_t(w) * h * 3, 0);
    display_w_ = w;
    display_h_ = h;
    display_stale_ = false;
    return;
  }
  // shown_linear() without copying the image shown as it is.
  const ImageRGB* img = showing_denoised() ? &denoised_ : &accumulated_;
  ImageRGB blended;
  if (showing_denoised() && blend_ > 0.0f) {
    blended = blend_images(denoised_, accumulated_, blend_);
    img = &blended;
  }
  display_ = tone_map_to_srgb8(*img, options_.exposure, ToneMap::kAces);
  display_w_ = img->width;
  display_h_ = img->height;
  if (options_.split_view) {
    tint_tile_owners(display_, display_w_, display_h_, tracer_->tiles(), tracer_->tile_owners());
  }
  display_stale_ = false;
}

ImageRGB ViewSession::shown_linear() const {
  if (!showing_denoised()) return accumulated_;
  return blend_ > 0.0f ? blend_images(denoised_, accumulated_, blend_) : denoised_;
}

void ViewSession::screenshot(const std::filesystem::path& path) const {
  if (frames_ == 0) throw InputError(path.string() + ": no frame has been rendered yet");
  write_png_rgb8(
      path, options_.width, options_.height,
      resize_rgb8(display(), display_width(), display_height(), options_.width, options_.height));
}

void ViewSession::set_backend(BackendKind kind) {
  if (kind == options_.backend) return;
  // A new tracer compiles the scene from scratch on its first frame.
  tracer_ = std::make_unique<CoreTracer>(create_backends(kind, options_.backend_options),
                                         tracer_settings());
  options_.backend = kind;
  last_seconds_ = 0.0;
  drop_denoise_history();
}

void ViewSession::set_output_size(uint32_t width, uint32_t height) {
  options_.width = std::max(width, 8u);
  options_.height = std::max(height, 8u);
  restart_pending_ = true;
}

void ViewSession::set_max_depth(uint32_t depth) {
  options_.max_depth = depth;
  restart_pending_ = true;
}

void ViewSession::set_max_spp_per_frame(uint32_t spp) {
  options_.max_spp_per_frame = std::max(spp, 1u);
  adaptive_ = AdaptiveQuality(adaptive_settings(options_));
  tracer_->reset_accumulation();
}

void ViewSession::set_target_fps(double fps) {
  options_.target_fps = std::max(fps, 1.0);
  adaptive_.set_target_fps(options_.target_fps);
}

void ViewSession::set_exposure(float stops) {
  options_.exposure = stops;
  display_stale_ = frames_ > 0;
}

void ViewSession::set_light_scale(float scale) {
  if (scale == light_scale_) return;
  light_scale_ = scale;
  for (size_t i = 0; i < light_intensity_.size(); ++i)
    scene_.edit_light(uint32_t(i)).intensity = light_intensity_[i] * scale;
  for (size_t i = 0; i < emissive_strength_.size(); ++i) {
    if (scene_.materials()[i].emissive == glm::vec3(0.0f)) continue;  // not a light
    scene_.edit_material(uint32_t(i)).emissive_strength = emissive_strength_[i] * scale;
  }
}

void ViewSession::set_lens(float aperture, float focus_distance) {
  const Camera& c = scene_.camera();
  if (c.aperture_radius == aperture && c.focus_distance == focus_distance) return;
  Camera& e = scene_.edit_camera();
  e.aperture_radius = std::max(aperture, 0.0f);
  e.focus_distance = std::max(focus_distance, 1e-3f);
}

}  // namespace tandem
