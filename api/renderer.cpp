// tandem::Renderer over the engine: a Scene edited through the API's checks,
// a CoreTracer running the Brigade loop, and every engine exception turned
// into tandem::Error at this boundary.
#include "api/renderer_impl.h"

#ifndef TANDEM_VERSION_STRING
#define TANDEM_VERSION_STRING "0.0.0"
#endif

namespace tandem {
inline namespace embed_v0 {

namespace {

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
  // A new backend, or the CUDA backend's image mirror switched: new backends.
  if (options.backend != im.options.backend || options.cuda_image != im.options.cuda_image) {
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

}  // namespace embed_v0
}  // namespace tandem
