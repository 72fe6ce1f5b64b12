// tandem::Renderer over the engine: a Scene edited through the API's checks,
// a CoreTracer running the Brigade loop, and every engine exception turned
// into tandem::Error at this boundary.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <new>
#include <optional>
#include <stdexcept>
#include <utility>

#include <tbb/global_control.h>

#include <thread>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "api/api_convert.h"
#include "api/api_ids.h"
#include "api/tandem/tandem.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/render/denoise_blend.h"
#include "core/render/device_error.h"
#include "core/render/temporal_denoiser.h"
#include "core/util/errors.h"
#include "core/util/log.h"
#include "core/world/motion_history.h"
#include "core/world/scene_ranges.h"
#include "scenes/gltf_loader.h"
#include "scenes/scene_loader.h"
#include "tracer/core_tracer.h"

#ifndef TANDEM_VERSION_STRING
#define TANDEM_VERSION_STRING "0.0.0"
#endif

namespace tandem {
inline namespace embed_v0 {

using api_detail::invalid;

namespace {

// Runs `body`, translating what the engine throws into the API's one
// exception type. `input_error_kind` says what an InputError means there:
// a bad file (loading, writing) or an unusable device (creating backends,
// rendering).
template <class F>
auto guarded(F&& body, Error::Kind input_error_kind = Error::Kind::kFile) -> decltype(body()) {
  try {
    return body();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const DeviceError& e) {
    throw Error(Error::Kind::kDevice, e.what());
  } catch (const InputError& e) {
    throw Error(input_error_kind, e.what());
  } catch (const UsageError& e) {
    throw Error(Error::Kind::kInvalidArgument, e.what());
  } catch (const std::length_error& e) {  // e.g. a scene too large for the BVH
    throw Error(Error::Kind::kInvalidArgument, e.what());
  } catch (const std::logic_error& e) {
    throw Error(Error::Kind::kInvalidState, e.what());
  } catch (const std::exception& e) {
    throw Error(Error::Kind::kInternal, e.what());
  }
}

BackendKind to_backend_kind(BackendChoice choice) {
  switch (choice) {
    case BackendChoice::kCpu:
      return BackendKind::kCpu;
    case BackendChoice::kCuda:
      return BackendKind::kCuda;
    case BackendChoice::kHetero:
      return BackendKind::kHetero;
    case BackendChoice::kAuto:
      break;
  }
  return BackendKind::kAuto;
}

ToneMap to_tone_map(ToneCurve curve) {
  switch (curve) {
    case ToneCurve::kAces:
      return ToneMap::kAces;
    case ToneCurve::kReinhard:
      return ToneMap::kReinhard;
    case ToneCurve::kStandard:
      break;
  }
  return ToneMap::kStandard;
}

float aspect(const RendererOptions& o) {
  return float(o.width) / float(o.height);
}

template <class Id>
uint32_t checked(Id id, size_t count, const char* what, const char* kind) {
  if (id.index >= count) {
    invalid(std::string(what) + ": " + kind + " " + std::to_string(id.index) +
            " does not exist (there are " + std::to_string(count) + ")");
  }
  return id.index;
}

}  // namespace

const char* version() {
  return TANDEM_VERSION_STRING;
}

namespace {
// Whether the host chose where messages go; until it does, none are shown.
std::atomic<bool> g_host_chose_logging{false};
}  // namespace

void set_log_callback(LogCallback callback) {
  g_host_chose_logging = true;
  if (!callback) {
    set_log_sink({});
    set_log_level(LogLevel::kQuiet);
    return;
  }
  set_log_sink([callback = std::move(callback)](LogLevel level, const std::string& message) {
    callback(level == LogLevel::kWarning ? LogSeverity::kWarning : LogSeverity::kInfo, message);
  });
  set_log_level(LogLevel::kWarning);
}

void set_warnings_to_stderr(bool enabled) {
  g_host_chose_logging = true;
  set_log_sink({});
  set_log_level(enabled ? LogLevel::kWarning : LogLevel::kQuiet);
}

bool cuda_available(std::string* reason) {
  std::string why;
  const bool ok = cuda_device_available(&why);
  if (!ok && reason) *reason = why;
  return ok;
}

Transform Transform::translation(float x, float y, float z) {
  Transform t;
  t.m[12] = x, t.m[13] = y, t.m[14] = z;
  return t;
}

Transform Transform::scale(float x, float y, float z) {
  Transform t;
  t.m[0] = x, t.m[5] = y, t.m[10] = z;
  return t;
}

Transform Transform::rotation(float radians, float x, float y, float z) {
  const glm::vec3 axis(x, y, z);
  if (!(glm::length(axis) > 0.0f)) return {};
  const glm::mat4 r = glm::rotate(glm::mat4(1.0f), radians, glm::normalize(axis));
  Transform t;
  std::copy(glm::value_ptr(r), glm::value_ptr(r) + 16, t.m);
  return t;
}

Transform operator*(const Transform& a, const Transform& b) {
  const glm::mat4 p = glm::make_mat4(a.m) * glm::make_mat4(b.m);
  Transform t;
  std::copy(glm::value_ptr(p), glm::value_ptr(p) + 16, t.m);
  return t;
}

// The CPU threads `o` allows: threads (0 = one per core) less the cores
// reserved for the host, at least 1.
uint32_t thread_budget(const RendererOptions& o) {
  const uint32_t cores = std::max(1u, std::thread::hardware_concurrency());
  const uint32_t threads = o.threads > 0 ? o.threads : cores;
  return threads > o.reserve_cores ? threads - o.reserve_cores : 1u;
}

struct Renderer::Impl {
  RendererOptions options;
  // TBB's process-wide limit while this renderer lives: every CPU stage of
  // the engine runs on TBB (the texture decoders read the same limit).
  std::optional<tbb::global_control> thread_limit;
  Scene scene;
  std::unique_ptr<CoreTracer> tracer;
  std::vector<std::string> last_backend_names;  // of the last completed frame
  // The denoiser (RendererOptions::denoise) and the feature pass.
  MotionHistory motion;
  std::vector<PixelFeatures> features;
  uint64_t features_frame = 0;  // frames + 1 of the frame `features` belong to; 0: none
  TemporalDenoiser denoiser;
  ImageRGB accumulated;  // the image after the previous frame, for its samples
  uint32_t accumulated_spp = 0;
  ImageRGB denoised;  // blended as image_denoised() returns it
  bool in_flight = false;
  bool image_valid = false;
  uint64_t frames = 0;
  // Ids to slots (api_ids.h). A removed instance's slot is hidden and kept
  // for the next instance of its mesh: per mesh slot, those free slots and
  // how many instances are alive.
  api_detail::IdTable mesh_ids, instance_ids, light_ids;
  std::vector<std::vector<uint32_t>> free_instance_slots;
  std::vector<uint32_t> mesh_instances_alive;
  uint32_t instances_alive = 0;
  std::vector<float> texture_peaks;  // per texture: its largest texel value (1 for 8-bit)

  // Ids for the scene as it is now (a new one: loaded, cleared).
  void reset_ids() {
    mesh_ids.reset(uint32_t(scene.mesh_count()));
    instance_ids.reset(uint32_t(scene.instances().size()));
    light_ids.reset(uint32_t(scene.lights().size()));
    free_instance_slots.assign(scene.mesh_count(), {});
    mesh_instances_alive.assign(scene.mesh_count(), 0);
    for (const Instance& inst : scene.instances()) {
      if (inst.mesh < mesh_instances_alive.size()) ++mesh_instances_alive[inst.mesh];
    }
    instances_alive = uint32_t(scene.instances().size());
    texture_peaks.assign(scene.textures().size(), 1.0f);  // a file's textures are 8-bit
  }

  void apply_thread_budget() {
    thread_limit.reset();
    const uint32_t budget = thread_budget(options);
    if (budget < std::max(1u, std::thread::hardware_concurrency()) || options.threads > 0)
      thread_limit.emplace(tbb::global_control::max_allowed_parallelism, budget);
  }

  TracerSettings tracer_settings() const {
    TracerSettings s;
    s.render.width = options.width;
    s.render.height = options.height;
    s.render.max_depth = options.max_depth;
    s.render.seed = options.seed;
    s.samples_per_frame = options.samples_per_frame;
    return s;
  }

  std::string gpu_unused;  // why kAuto/kHetero run without a GPU; empty otherwise

  // A new tracer compiles the whole scene on its first frame.
  void create_tracer() {
    gpu_unused.clear();
    if (options.backend == BackendChoice::kAuto || options.backend == BackendChoice::kHetero) {
      std::string why;
      if (!cuda_device_available(&why)) gpu_unused = why.empty() ? "no usable GPU" : why;
    }
    tracer = guarded(
        [&] {
          std::vector<std::unique_ptr<Backend>> backends =
              create_backends(to_backend_kind(options.backend));
          // A device that is there but would not start (out of memory, a
          // driver fault) leaves kAuto/kHetero on the CPU too.
          const bool cuda = std::any_of(backends.begin(), backends.end(),
                                        [](const auto& b) { return b->name() == "cuda"; });
          if (!cuda && gpu_unused.empty() && options.backend != BackendChoice::kCpu)
            gpu_unused = "the CUDA backend failed to start";
          return std::make_unique<CoreTracer>(std::move(backends), tracer_settings());
        },
        Error::Kind::kDevice);
    image_valid = false;
    last_backend_names.clear();
  }

  // After a frame: its features, the filter of its own samples, and the
  // blend with the accumulated image (the viewer's recipe).
  void denoise_frame(bool restarted) {
    const ImageRGB now = tracer->image();
    const uint32_t spp = tracer->accumulated_spp();
    if (restarted || now.width != accumulated.width || now.height != accumulated.height) {
      accumulated_spp = 0;
      denoiser.reset();
    }
    const bool have =
        guarded([&] { return tracer->render_features(motion, features); }, Error::Kind::kDevice);
    features_frame = have ? frames + 1 : 0;
    if (have) {
      const ImageRGB own = frame_samples(now, spp, accumulated, accumulated_spp);
      const ImageRGB filtered = denoiser.process(features, own);
      denoised = blend_images(filtered, now, accumulated_blend_weight(spp));
    } else {
      denoised = now;  // no feature pass (a GPU-only list): the image as it is
    }
    accumulated = now;
    accumulated_spp = spp;
  }

  void require_idle(const char* what) const {
    if (in_flight) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": not allowed while a frame is in flight");
    }
  }

  void require_image(const char* what) const {
    if (in_flight) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": the image is not ready while a frame is in flight");
    }
    if (!image_valid) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": no frame has been rendered yet");
    }
  }

  // Without a camera from the caller or the file, one that frames the
  // scene as it is at the first frame (and stays, so that motion in the
  // scene does not move it).
  void place_camera() {
    if (scene.has_camera()) return;
    Camera c = frame_bounds_camera(scene.bounds(), 0.6911112f, aspect(options));
    // Bounds near the range Tandem traces can put the framing camera beyond
    // it: the default camera is better than a refusal.
    scene.set_camera(camera_problem(c).empty() ? c : Camera{});
  }
};

Renderer::Renderer(const RendererOptions& options) : impl_(std::make_unique<Impl>()) {
  if (!g_host_chose_logging) set_log_level(LogLevel::kQuiet);  // before the backends speak
  api_detail::check_options(options, "Renderer");
  impl_->options = options;
  impl_->apply_thread_budget();
  impl_->create_tracer();
}

Renderer::~Renderer() = default;  // CoreTracer's destructor joins a frame in flight
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

TextureId Renderer::add_texture(const TextureDesc& texture) {
  float peak = 1.0f;
  Texture t = api_detail::to_texture(texture, "add_texture", &peak);
  impl_->texture_peaks.push_back(peak);
  return {impl_->scene.add_texture(std::move(t))};
}

MaterialId Renderer::add_material(const MaterialDesc& material) {
  Material m = api_detail::to_material(material, impl_->texture_peaks, "add_material");
  return {impl_->scene.add_material(std::move(m))};
}

void Renderer::set_material(MaterialId id, const MaterialDesc& material) {
  const uint32_t i = checked(id, impl_->scene.materials().size(), "set_material", "material");
  Material m = api_detail::to_material(material, impl_->texture_peaks, "set_material");
  impl_->scene.edit_material(i) = std::move(m);
}

MeshId Renderer::add_mesh(const MeshData& mesh, MaterialId material) {
  const uint32_t mat = checked(material, impl_->scene.materials().size(), "add_mesh", "material");
  Mesh m = api_detail::to_mesh(mesh, mat, "add_mesh");
  Impl& im = *impl_;
  const uint32_t slot = im.scene.add_mesh(std::move(m));
  im.free_instance_slots.emplace_back();
  im.mesh_instances_alive.push_back(0);
  return {im.mesh_ids.add(slot)};
}

void Renderer::remove_mesh(MeshId id) {
  Impl& im = *impl_;
  const uint32_t m = im.mesh_ids.slot(id.index, "remove_mesh", "mesh");
  if (im.mesh_instances_alive[m] > 0) {
    throw Error(Error::Kind::kInvalidState,
                "remove_mesh: mesh " + std::to_string(id.index) + " still has " +
                    std::to_string(im.mesh_instances_alive[m]) + " instance(s); remove them first");
  }
  // The mesh goes with its free (hidden) instance slots; later slots move.
  im.instance_ids.remap(im.scene.remove_mesh(m));
  im.mesh_ids.erase_slot(m);
  im.free_instance_slots.erase(im.free_instance_slots.begin() + m);
  im.mesh_instances_alive.erase(im.mesh_instances_alive.begin() + m);
  for (std::vector<uint32_t>& slots : im.free_instance_slots)
    slots.clear();
  for (uint32_t i = 0; i < im.scene.instances().size(); ++i) {
    if (im.scene.instances()[i].hidden)
      im.free_instance_slots[im.scene.instances()[i].mesh].push_back(i);
  }
}

void Renderer::set_mesh_vertices(MeshId id, const MeshData& vertices) {
  const uint32_t i = impl_->mesh_ids.slot(id.index, "set_mesh_vertices", "mesh");
  // Checked before anything changes: a failed call changes nothing.
  impl_->scene.pose_mesh(i, api_detail::vertices_pose(vertices, impl_->scene.mesh_vertex_count(i),
                                                      "set_mesh_vertices"));
}

InstanceId Renderer::add_instance(MeshId mesh, const Transform& transform) {
  Impl& im = *impl_;
  const uint32_t m = im.mesh_ids.slot(mesh.index, "add_instance", "mesh");
  const glm::mat4 matrix = api_detail::to_matrix(transform, "add_instance");
  uint32_t slot;
  std::vector<uint32_t>& free = im.free_instance_slots[m];
  if (!free.empty()) {
    // A removed instance of the same mesh: shown again where this one is
    // (a TLAS update, as for a move).
    slot = free.back();
    free.pop_back();
    im.scene.set_instance_transform(slot, matrix);
    im.scene.set_instance_hidden(slot, false);
  } else {
    Instance inst;
    inst.mesh = m;
    inst.transform = matrix;
    slot = im.scene.add_instance(std::move(inst));
  }
  ++im.mesh_instances_alive[m];
  ++im.instances_alive;
  return {im.instance_ids.add(slot)};
}

void Renderer::remove_instance(InstanceId id) {
  Impl& im = *impl_;
  const uint32_t slot = im.instance_ids.slot(id.index, "remove_instance", "instance");
  const uint32_t m = im.scene.instances()[slot].mesh;
  im.scene.set_instance_hidden(slot, true);
  im.instance_ids.release(slot);
  im.free_instance_slots[m].push_back(slot);
  --im.mesh_instances_alive[m];
  --im.instances_alive;
}

void Renderer::set_instance_transform(InstanceId id, const Transform& transform) {
  const uint32_t i = impl_->instance_ids.slot(id.index, "set_instance_transform", "instance");
  impl_->scene.set_instance_transform(i,
                                      api_detail::to_matrix(transform, "set_instance_transform"));
}

LightId Renderer::add_light(const LightDesc& light) {
  Light l = api_detail::to_light(light, "add_light");
  return {impl_->light_ids.add(impl_->scene.add_light(std::move(l)))};
}

void Renderer::set_light(LightId id, const LightDesc& light) {
  const uint32_t i = impl_->light_ids.slot(id.index, "set_light", "light");
  Light l = api_detail::to_light(light, "set_light");
  impl_->scene.edit_light(i) = std::move(l);
}

void Renderer::remove_light(LightId id) {
  const uint32_t i = impl_->light_ids.slot(id.index, "remove_light", "light");
  impl_->scene.remove_light(i);
  impl_->light_ids.erase_slot(i);
}

void Renderer::set_camera(const CameraDesc& camera) {
  impl_->scene.set_camera(api_detail::to_camera(camera, "set_camera"));
}

void Renderer::set_environment_color(float r, float g, float b) {
  const float c[3] = {r, g, b};
  for (float v : c) {
    if (!std::isfinite(v) || v < 0.0f)
      invalid("set_environment_color: each component must be a finite number >= 0");
    // Radiance is summed in float over many samples: beyond this it
    // becomes infinity and renders black (the command line's limit too).
    if (v > 1e30f) invalid("set_environment_color: a radiance above 1e30 cannot be accumulated");
  }
  Environment& env = impl_->scene.edit_environment();
  env = Environment{};
  env.color = glm::vec3(r, g, b);
}

namespace {

void check_environment_scale(float intensity, float rotation, const char* what) {
  if (!std::isfinite(intensity) || intensity < 0.0f)
    invalid(std::string(what) + ": intensity must be a finite number >= 0");
  if (!std::isfinite(rotation) || std::fabs(rotation) > 1e6f)
    invalid(std::string(what) + ": rotation must be finite radians within 1e6");
}

// Builds an environment with `set` (one of the scene loader's functions)
// in a scene of its own, so that a failure leaves the renderer's as it
// was, then takes it turned by `rotation`.
template <class F>
void install_environment(Scene& scene, float rotation, F&& set,
                         Error::Kind error_kind = Error::Kind::kFile) {
  Scene probe;
  guarded([&] { set(probe); }, error_kind);
  Environment env = probe.environment();
  env.rotation = rotation;
  scene.edit_environment() = std::move(env);
}

}  // namespace

void Renderer::set_environment_map(const std::string& path, float intensity, float rotation) {
  check_environment_scale(intensity, rotation, "set_environment_map");
  install_environment(impl_->scene, rotation,
                      [&](Scene& s) { load_environment_map(s, path, intensity); });
}

void Renderer::set_environment_pixels(uint32_t width, uint32_t height, const float* rgb,
                                      float intensity, float rotation) {
  const char* what = "set_environment_pixels";
  check_environment_scale(intensity, rotation, what);
  if (rgb == nullptr) invalid(std::string(what) + ": the pixels are null");
  if (width == 0 || height == 0 || uint64_t(width) * height > kMaxEnvironmentPixels) {
    invalid(std::string(what) + ": " + std::to_string(width) + "x" + std::to_string(height) +
            " is empty or more than " + std::to_string(kMaxEnvironmentPixels) + " pixels");
  }
  ImageRGB image{width, height};
  for (size_t i = 0; i < image.rgb.size(); ++i) {
    if (!std::isfinite(rgb[i]) || rgb[i] < 0.0f) {
      invalid(std::string(what) + ": value " + std::to_string(i) + " is not a finite number >= 0");
    }
    image.rgb[i] = rgb[i];
  }
  install_environment(
      impl_->scene, rotation,
      [&](Scene& s) { tandem::set_environment_map(s, image, "the pixels", intensity); },
      Error::Kind::kInvalidArgument);
}

void Renderer::use_default_sky(float intensity, float rotation) {
  check_environment_scale(intensity, rotation, "use_default_sky");
  install_environment(impl_->scene, rotation, [&](Scene& s) {
    tandem::set_environment_map(s, default_environment_image(), kDefaultEnvironmentName, intensity);
  });
}

void Renderer::load_gltf(const std::string& path) {
  impl_->require_idle("load_gltf");
  Scene loaded = guarded([&] { return tandem::load_gltf(path); });
  if (impl_->options.default_sky) {
    guarded([&] {
      tandem::set_environment_map(loaded, default_environment_image(), kDefaultEnvironmentName,
                                  1.0f);
    });
    log_info(path + ": lit by the built-in sky (" + kDefaultEnvironmentName +
             "); RendererOptions::default_sky = false turns it off");
  }
  // A new tracer compiles the new scene from scratch (its compiler's
  // bookkeeping describes the old one).
  impl_->scene = std::move(loaded);
  impl_->reset_ids();
  impl_->create_tracer();
}

void Renderer::clear_scene() {
  impl_->require_idle("clear_scene");
  impl_->scene = Scene{};
  impl_->reset_ids();
  impl_->create_tracer();
}

uint32_t Renderer::material_count() const {
  return uint32_t(impl_->scene.materials().size());
}
uint32_t Renderer::mesh_count() const {
  return uint32_t(impl_->scene.mesh_count());
}
uint32_t Renderer::instance_count() const {
  return impl_->instances_alive;
}
uint32_t Renderer::light_count() const {
  return uint32_t(impl_->scene.lights().size());
}
uint32_t Renderer::texture_count() const {
  return uint32_t(impl_->scene.textures().size());
}

void Renderer::set_options(const RendererOptions& options) {
  api_detail::check_options(options, "set_options");
  Impl& im = *impl_;
  if (options.backend != im.options.backend) {
    im.require_idle("set_options (a new backend)");
    const RendererOptions old = im.options;
    im.options = options;
    im.apply_thread_budget();
    try {
      im.create_tracer();
    } catch (...) {
      im.options = old;  // the old tracer is still there
      throw;
    }
    return;
  }
  if (options.threads != im.options.threads || options.reserve_cores != im.options.reserve_cores) {
    im.require_idle("set_options (a new thread budget)");
    im.options = options;
    im.apply_thread_budget();
  }
  im.options = options;
  // A frame in flight keeps its settings; these apply from the next one.
  im.tracer->set_settings(im.tracer_settings());
}

const RendererOptions& Renderer::options() const {
  return impl_->options;
}

std::string Renderer::backend_names() const {
  std::string names;
  for (const std::string& n : impl_->last_backend_names)
    names += (names.empty() ? "" : "+") + n;
  return names;
}

std::string Renderer::gpu_unused_reason() const {
  return impl_->gpu_unused;
}

void Renderer::reset_accumulation() {
  impl_->tracer->reset_accumulation();
}

void Renderer::begin_frame() {
  Impl& im = *impl_;
  if (im.in_flight)
    throw Error(Error::Kind::kInvalidState, "begin_frame: the previous frame was not ended");
  if (im.instances_alive == 0)
    throw Error(Error::Kind::kInvalidState, "begin_frame: the scene has no instance to render");
  im.place_camera();
  guarded([&] { im.tracer->begin_frame(im.scene); }, Error::Kind::kDevice);
  im.in_flight = true;
}

bool Renderer::prepare_next_frame() {
  Impl& im = *impl_;
  if (!im.in_flight)
    throw Error(Error::Kind::kInvalidState, "prepare_next_frame: no frame in flight");
  im.place_camera();
  return guarded([&] { return im.tracer->prepare_next_frame(im.scene); }, Error::Kind::kDevice);
}

FrameInfo Renderer::end_frame() {
  Impl& im = *impl_;
  if (!im.in_flight) throw Error(Error::Kind::kInvalidState, "end_frame: no frame in flight");
  im.in_flight = false;
  im.image_valid = false;
  const FrameMetrics& m = guarded([&]() -> const FrameMetrics& { return im.tracer->end_frame(); },
                                  Error::Kind::kDevice);
  im.image_valid = true;
  FrameInfo info;
  if (im.options.denoise) {
    const auto t0 = std::chrono::steady_clock::now();
    im.denoise_frame(m.accumulation_reset);
    info.denoise_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  im.last_backend_names.clear();
  for (const BackendFrameMetrics& b : m.backends) {
    im.last_backend_names.push_back(b.name);
    if (!b.failure.empty() && im.gpu_unused.empty()) {
      im.gpu_unused = "the GPU failed (" + b.failure + "); rendering on the CPU";
      info.gpu_failed = true;
    }
  }
  info.compile_seconds = m.sync_scene_seconds;
  info.bvh_seconds = m.update_accstruc_seconds;
  info.upload_seconds = m.sync_accstruc_seconds;
  info.render_seconds = m.render_seconds;
  info.frame = im.frames++;
  info.accumulated_spp = m.accumulated_spp;
  info.accumulation_reset = m.accumulation_reset;
  info.seconds = m.total_seconds;
  info.rays = m.rays();
  info.threads =
      uint32_t(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  uint64_t samples = 0;
  for (const BackendFrameMetrics& b : m.backends)
    samples += b.samples;
  for (const BackendFrameMetrics& b : m.backends) {
    BackendFrameStats s;
    s.name = b.name;
    s.share = samples > 0 ? double(b.samples) / double(samples) : 0.0;
    s.seconds = b.seconds;
    s.rays = b.rays;
    s.mrays_per_second = b.seconds > 0.0 ? double(b.rays) / b.seconds * 1e-6 : 0.0;
    s.upload_bytes = b.commit_bytes;
    info.backends.push_back(std::move(s));
  }
  return info;
}

FrameInfo Renderer::render_frame() {
  begin_frame();
  return end_frame();
}

bool Renderer::frame_in_flight() const {
  return impl_->in_flight;
}

uint32_t Renderer::width() const {
  impl_->require_image("width");
  return impl_->tracer->film().width();
}

uint32_t Renderer::height() const {
  impl_->require_image("height");
  return impl_->tracer->film().height();
}

std::vector<float> Renderer::image_linear() const {
  impl_->require_image("image_linear");
  return impl_->tracer->image().rgb;
}

namespace {

// A caller's buffer for the image of `film`: not null and large enough.
void check_image_buffer(const void* out, size_t count, const Film& film, const char* what,
                        const char* unit) {
  if (out == nullptr) invalid(std::string(what) + ": the buffer is null");
  const size_t needed = size_t(film.width()) * film.height() * 3;
  if (count < needed) {
    invalid(std::string(what) + ": the buffer holds " + std::to_string(count) + " " + unit +
            "; the " + std::to_string(film.width()) + "x" + std::to_string(film.height()) +
            " image needs " + std::to_string(needed));
  }
}

}  // namespace

void Renderer::copy_image_linear(float* out, size_t count) const {
  impl_->require_image("copy_image_linear");
  const Film& film = impl_->tracer->film();
  check_image_buffer(out, count, film, "copy_image_linear", "floats");
  film.resolve_into(out);
}

void Renderer::copy_image_srgb8(uint8_t* out, size_t count, float exposure_stops,
                                ToneCurve curve) const {
  impl_->require_image("copy_image_srgb8");
  if (!std::isfinite(exposure_stops)) invalid("copy_image_srgb8: exposure_stops is not finite");
  check_image_buffer(out, count, impl_->tracer->film(), "copy_image_srgb8", "bytes");
  tone_map_to_srgb8_into(impl_->tracer->image(), exposure_stops, to_tone_map(curve), out);
}

std::vector<float> Renderer::image_denoised() const {
  impl_->require_image("image_denoised");
  if (!impl_->options.denoise)
    throw Error(Error::Kind::kInvalidState, "image_denoised: RendererOptions::denoise is off");
  return impl_->denoised.rgb;
}

FeatureBuffers Renderer::features() {
  Impl& im = *impl_;
  im.require_image("features");
  if (im.features_frame != im.frames) {
    const bool have = guarded([&] { return im.tracer->render_features(im.motion, im.features); },
                              Error::Kind::kDevice);
    if (!have) {
      throw Error(Error::Kind::kDevice,
                  "features: no backend of this renderer traces feature buffers (a GPU-only "
                  "renderer); BackendChoice::kCpu or kHetero do");
    }
    im.features_frame = im.frames;
  }
  FeatureBuffers out;
  out.width = im.tracer->film().width();
  out.height = im.tracer->film().height();
  const size_t n = im.features.size();
  out.albedo.resize(3 * n);
  out.normal.resize(3 * n);
  out.depth.resize(n);
  out.motion.resize(2 * n);
  for (size_t i = 0; i < n; ++i) {
    const PixelFeatures& p = im.features[i];
    out.albedo[3 * i] = p.albedo.x, out.albedo[3 * i + 1] = p.albedo.y,
                   out.albedo[3 * i + 2] = p.albedo.z;
    out.normal[3 * i] = p.normal.x, out.normal[3 * i + 1] = p.normal.y,
                   out.normal[3 * i + 2] = p.normal.z;
    out.depth[i] = p.depth;
    out.motion[2 * i] = p.motion.x, out.motion[2 * i + 1] = p.motion.y;
  }
  return out;
}

std::vector<uint8_t> Renderer::image_srgb8(float exposure_stops, ToneCurve curve) const {
  impl_->require_image("image_srgb8");
  if (!std::isfinite(exposure_stops)) invalid("image_srgb8: exposure_stops is not finite");
  return tone_map_to_srgb8(impl_->tracer->image(), exposure_stops, to_tone_map(curve));
}

void Renderer::write_image(const std::string& path, float exposure_stops, ToneCurve curve) const {
  impl_->require_image("write_image");
  if (!std::isfinite(exposure_stops)) invalid("write_image: exposure_stops is not finite");
  ImageWriteOptions o;
  o.exposure = exposure_stops;
  o.tone_map = to_tone_map(curve);
  guarded([&] { tandem::write_image(path, impl_->tracer->image(), o); });
}

}  // namespace embed_v0
}  // namespace tandem
