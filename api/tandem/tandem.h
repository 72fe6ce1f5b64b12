// Tandem's public API: the path tracer as a library for games and tools.
//
//   #include <tandem/tandem.h>
//
//   tandem::RendererOptions options;                     // backend, size, samples, depth
//   options.width = 640, options.height = 360;
//   tandem::Renderer r(options);
//   tandem::MeshId mesh = r.add_mesh(box_data, r.add_material({}));  // your arrays, copied
//   tandem::InstanceId box = r.add_instance(mesh, tandem::Transform::translation(0, 0.5f, 0));
//   r.add_light(tandem::LightDesc{});                    // or an emissive material
//   r.set_camera(tandem::CameraDesc{});                  // position, target, up, fov
//   for (int f = 0; f < 60; ++f) {
//     r.begin_frame();                                   // renders on Tandem's threads...
//     r.set_instance_transform(box, tandem::Transform::translation(0.01f * f, 0.5f, 0));
//     r.end_frame();                                     // ...while the game moved the box
//   }
//   std::vector<uint8_t> rgb = r.image_srgb8();          // width * height * 3 bytes
//
// Everything here is plain C++17 (structs of floats, pointers with counts,
// std::vector and std::string): no Embree, TBB, glm or CUDA type appears,
// so an application needs only this header and the `Tandem::tandem` CMake
// target. Units follow docs/scene-units.md: linear Rec. 709 RGB, radiance
// in W/(m^2 sr), angles in radians, lengths in scene units (metres by
// convention); transforms are column-major 4x4 matrices as in glTF.
//
// Errors: every function that can fail throws tandem::Error (and nothing
// else, bar std::bad_alloc), whose what() is one sentence naming the
// argument or file and the reason. A failed call leaves the scene and the
// options as they were. Identifiers (MeshId, ...) belong to the renderer
// that made them and stay valid until their object is removed or the scene
// is replaced (load_gltf, clear_scene); an id is never handed out twice, so
// a stale one is refused (kInvalidArgument), never taken for another object.
//
// Threads: one Renderer is used from one thread at a time (no call on it
// may overlap another; different Renderers may be used from different
// threads). Between begin_frame() and end_frame() it renders on its own
// worker threads (TBB, within RendererOptions::threads/reserve_cores, and
// the GPU), and the calling thread may go on editing the scene for the
// next frame. The log callback may be called from any of those threads.
// Pointers passed in (MeshData, TextureDesc, pixels) are read during the
// call only; nothing returned points into the renderer but the device
// pointers of cuda_image_linear() and cuda_image_srgb8().
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace tandem {
// The public names live in an inline namespace: users write tandem::Renderer,
// while the linker sees tandem::embed_v0::Renderer, so no public type can
// ever collide with one of the engine's internal tandem:: types.
inline namespace embed_v0 {

// The one exception type of the API.
class Error : public std::runtime_error {
 public:
  enum class Kind {
    kInvalidArgument,  // a value passed to a function is out of range, NaN, ...
    kInvalidState,     // the call is not allowed now (e.g. end_frame() without begin_frame())
    kFile,             // a file could not be read or written, or is not a valid scene/image
    kDevice,           // the requested backend cannot run (no GPU, GPU failure)
    kInternal,         // an unexpected failure inside the engine (please report it)
  };
  Error(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const noexcept { return kind_; }

 private:
  Kind kind_;
};

// The library's version, "MAJOR.MINOR.PATCH" (the CMake package's version).
const char* version();

// What the library has to say (a glTF texture that is missing, a GPU it
// falls back from) goes nowhere unless the host asks for it: to a callback
// (called from any thread, one message at a time; empty: nowhere again), or
// to stderr as "tandem: warning: ...". Either choice holds for the whole
// process; a Renderer made before any choice silences the library.
enum class LogSeverity { kWarning, kInfo };
using LogCallback = std::function<void(LogSeverity severity, const std::string& message)>;
void set_log_callback(LogCallback callback);
void set_warnings_to_stderr(bool enabled);

// Whether a CUDA device can be used by BackendChoice::kCuda; when not and
// `reason` is given, it is set to why (not built with CUDA, no GPU, ...).
bool cuda_available(std::string* reason = nullptr);

// Strongly typed ids (0, 1, 2, ... in order of creation, per kind; after
// load_gltf, the file's objects in its order).
struct MaterialId {
  uint32_t index = 0;
};
struct MeshId {
  uint32_t index = 0;
};
struct InstanceId {
  uint32_t index = 0;
};
struct LightId {
  uint32_t index = 0;
};
// A texture, or none (the default: a material slot without a texture).
struct TextureId {
  static constexpr uint32_t kNone = 0xffffffffu;
  uint32_t index = kNone;
};

// Object-to-world transform: a column-major 4x4 matrix (m[12..14] is the
// translation, within 1e9 of the origin), affine (last row 0 0 0 1). A
// singular one (a scale of 0, the usual way to hide an object) is allowed:
// the instance is not drawn while it is singular.
struct Transform {
  float m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

  static Transform identity() { return {}; }
  static Transform translation(float x, float y, float z);
  static Transform scale(float x, float y, float z);
  // Rotation by `radians` (counter-clockwise looking down the axis towards
  // the origin) about the axis (x, y, z), which need not be unit length;
  // a zero axis gives the identity.
  static Transform rotation(float radians, float x, float y, float z);
};
// a * b: applies b first, then a.
Transform operator*(const Transform& a, const Transform& b);

// A triangle mesh. The arrays are the caller's and are only read during the
// call that takes the MeshData (add_mesh, set_mesh_vertices): Tandem copies
// them. Triangles are counter-clockwise seen from their front.
struct MeshData {
  const float* positions = nullptr;  // vertex_count * 3 floats: x, y, z (object space)
  const float* normals = nullptr;    // vertex_count * 3 floats, or null: flat triangle normals
  const float* uvs = nullptr;        // vertex_count * 2 floats (u, v), or null
  size_t vertex_count = 0;
  const uint32_t* indices = nullptr;  // triangle_count * 3 vertex indices
  size_t triangle_count = 0;
};

enum class TextureWrap { kRepeat, kClampToEdge, kMirroredRepeat };

// How an 8-bit texture's RGB is encoded. kBySlot follows glTF: sRGB where
// a material reads it as a colour (base colour, emission, sheen colour),
// linear elsewhere (metallic-roughness, normal, transmission, clear coat,
// sheen roughness), so one texture may serve several slots; kSrgb and
// kLinear hold in every slot (a linear albedo, an sRGB-authored mask).
enum class TextureColorSpace { kBySlot, kSrgb, kLinear };

// An image for materials, copied by add_texture: 8-bit RGBA, or linear
// float RGBA for what 8 bits cannot hold (HDR emission, precise data).
// Exactly one of rgba8 and rgba32f is given. Alpha is linear.
struct TextureDesc {
  uint32_t width = 0, height = 0;  // each in [1, 16384]
  const uint8_t* rgba8 = nullptr;  // width * height * 4 bytes, row 0 at the top
  // width * height * 4 floats, row 0 at the top, each finite and in
  // [0, 1e6]; never sRGB-decoded (color_space must be kBySlot or kLinear).
  const float* rgba32f = nullptr;
  TextureColorSpace color_space = TextureColorSpace::kBySlot;
  TextureWrap wrap_u = TextureWrap::kRepeat, wrap_v = TextureWrap::kRepeat;
  bool nearest = false;  // magnification filter NEAREST
};

// How a material's alpha (alpha times the base colour texture's A) is
// used, as glTF's alphaMode: ignored, a cut-out below alpha_cutoff, or
// blended (the surface lets 1 - alpha of the light through).
enum class MaterialAlpha { kOpaque, kMask, kBlend };

// The glTF metallic-roughness material with its extensions (defaults: a
// matt light grey).
struct MaterialDesc {
  float base_color[3] = {0.8f, 0.8f, 0.8f};  // linear RGB reflectance, each in [0, 1]
  float roughness = 0.5f;                    // [0, 1]; GGX alpha = roughness^2
  float metallic = 0.0f;                     // [0, 1]
  float emission[3] = {0.0f, 0.0f, 0.0f};    // emitted radiance, W/(m^2 sr), linear RGB, >= 0
  float emission_strength = 1.0f;            // multiplies emission, >= 0; the product <= 1e30
  float transmission = 0.0f;                 // [0, 1]: 1 = clear glass-like dielectric
  float ior = 1.5f;                          // index of refraction, [1, 5]
  bool double_sided = false;                 // emission and shading on both faces
  float alpha = 1.0f;                        // [0, 1], used as alpha_mode says
  MaterialAlpha alpha_mode = MaterialAlpha::kOpaque;
  float alpha_cutoff = 0.5f;  // [0, 1]: kMask drops what is below
  // KHR_materials_specular: the dielectric reflection's strength and tint,
  // each in [0, 1].
  float specular = 1.0f;
  float specular_color[3] = {1.0f, 1.0f, 1.0f};
  // KHR_materials_clearcoat: a clear varnish layer over the base (0: none),
  // and its roughness; each in [0, 1].
  float clearcoat = 0.0f, clearcoat_roughness = 0.0f;
  // KHR_materials_sheen: a cloth-like rim (black: none) and its roughness;
  // each in [0, 1].
  float sheen_color[3] = {0.0f, 0.0f, 0.0f};
  float sheen_roughness = 0.0f;
  // Textures (add_texture) read at the mesh's uvs (uv (0, 0) is the
  // image's top-left corner, as in glTF), each multiplying its factor above:
  // base colour (RGB; A times alpha), metallic-roughness (G roughness, B
  // metallic), emission (RGB), transmission (R), clear coat (R), clear-coat
  // roughness (G), sheen colour (RGB), sheen roughness (A). The normal
  // texture is a tangent-space normal map (RGB = xyz * 0.5 + 0.5), its xy
  // scaled by normal_scale (finite, within [-100, 100]); the tangents follow
  // the uvs. A mesh without uvs reads texel (0, 0).
  TextureId base_color_texture, metallic_roughness_texture, emission_texture, transmission_texture;
  TextureId normal_texture, clearcoat_texture, clearcoat_roughness_texture, sheen_color_texture,
      sheen_roughness_texture;
  float normal_scale = 1.0f;
};

enum class LightKind { kPoint, kSpot, kDirectional };

// A punctual light in world space (KHR_lights_punctual, radiometric units).
struct LightDesc {
  LightKind kind = LightKind::kPoint;
  float position[3] = {0.0f, 0.0f, 0.0f};    // point and spot
  float direction[3] = {0.0f, -1.0f, 0.0f};  // where the light travels (spot, directional)
  float color[3] = {1.0f, 1.0f, 1.0f};       // linear RGB, >= 0
  // W/sr for point and spot lights, W/m^2 for directional lights; >= 0.
  float intensity = 1.0f;
  float inner_cone_angle = 0.0f;           // spot: radians, full intensity inside
  float outer_cone_angle = 0.7853981634f;  // spot: radians, in (inner, pi/2]
};

// A pinhole or thin-lens perspective camera looking from `position` at
// `target`, with `up` giving the roll (it need not be orthogonal).
struct CameraDesc {
  float position[3] = {0.0f, 0.0f, 5.0f};
  float target[3] = {0.0f, 0.0f, 0.0f};
  float up[3] = {0.0f, 1.0f, 0.0f};
  float vertical_fov = 0.6911112f;  // radians, in (0, pi); 39.6 degrees
  float aperture_radius = 0.0f;     // scene units; 0 = pinhole (everything sharp)
  float focus_distance = 1.0f;      // scene units along the view direction, > 0
};

enum class BackendChoice {
  kAuto,    // the GPU when one is usable, otherwise the CPU (with a warning)
  kCpu,     // Embree + TBB on the CPU
  kCuda,    // the GPU only; Error::kDevice when there is none
  kHetero,  // the GPU and the CPU together, each frame split between them
};

// How each bounce chooses the light it samples (`tandem render
// --light-sampler`).
enum class LightSampling {
  kTree,   // a light BVH: the lights near the point and facing it (many lights)
  kPower,  // by power alone (an alias table), blind to where the point is
};

struct RendererOptions {
  BackendChoice backend = BackendChoice::kAuto;
  uint32_t width = 1280, height = 720;  // pixels, each in [1, 16384]
  uint32_t samples_per_frame = 1;       // per pixel and frame, [1, 4096]
  uint32_t max_depth = 8;               // scattering events per path; 1 = direct light only
  uint32_t seed = 0;                    // same seed and scene: same image, bit for bit
  LightSampling light_sampling = LightSampling::kTree;
  // The CPU threads the renderer may use (BVH builds, the CPU backend's
  // tiles, texture decoding, the film): `threads` (0 = one per core) less
  // `reserve_cores` left to the host (its game loop), at least 1; each in
  // [0, 4096]. The budget is process-wide while the Renderer lives (TBB's
  // global limit: with several Renderers the smallest budget holds). The
  // image does not depend on it.
  uint32_t threads = 0;
  uint32_t reserve_cores = 0;
  // Whether load_gltf lights the file's scene with the built-in sky (an
  // HDR sky with a sun, the one `tandem render` uses), as the command line
  // does for every glTF scene no environment is given for. Without it a
  // file with no lights of its own renders black.
  bool default_sky = true;
  // Runs the viewer's denoiser (SVGF: a feature pass, then a temporal,
  // edge-aware filter of each frame's samples) after every frame, for
  // image_denoised(): about 100 ms a frame at 1280x720 on two cores.
  bool denoise = false;
  // With BackendChoice::kCuda: the GPU keeps its own copy of the
  // accumulated image (one small kernel per batch of tiles), for
  // cuda_image_linear() and cuda_image_srgb8().
  bool cuda_image = false;
};

// What the first hit of each pixel's centre saw (the denoiser's guides):
// row 0 at the top, width() * height() pixels.
struct FeatureBuffers {
  uint32_t width = 0, height = 0;
  std::vector<float> albedo;  // 3 per pixel: base colour at the hit (1 for the sky)
  std::vector<float> normal;  // 3 per pixel: shading normal facing the camera (0 for the sky)
  std::vector<float> depth;   // 1 per pixel: along the camera's view direction (0 for the sky)
  std::vector<float> motion;  // 2 per pixel: previous frame's position minus this one, pixels
};

// What one backend did in a frame.
struct BackendFrameStats {
  std::string name;      // "cpu", "cuda", "host"
  double share = 0.0;    // of the frame's samples, 0..1
  double seconds = 0.0;  // rendering
  uint64_t rays = 0;
  double mrays_per_second = 0.0;
  uint64_t upload_bytes = 0;  // scene and BVH changes sent to this backend
};

// What one frame did.
struct FrameInfo {
  uint64_t frame = 0;                       // counts every frame rendered by this renderer
  uint32_t accumulated_spp = 0;             // samples per pixel in the image now
  bool accumulation_reset = false;          // a scene or settings change restarted accumulation
  double seconds = 0.0;                     // wall time of the frame, begin to end
  uint64_t rays = 0;                        // rays traced by all backends
  uint32_t threads = 0;                     // CPU threads the frame could use (the budget)
  std::vector<BackendFrameStats> backends;  // each backend's part of the frame
  // The stages of the frame, in seconds: the scene edits compiled into the
  // renderers' arrays, Tandem's BVH updated (for the GPU; the CPU's Embree
  // BVH is built in the next stage), the changes sent to the backends
  // (each 0 when prepare_next_frame() did it during the previous frame),
  // the render (begin to end of the slowest backend) and the denoiser.
  double compile_seconds = 0.0, bvh_seconds = 0.0, upload_seconds = 0.0;
  double render_seconds = 0.0, denoise_seconds = 0.0;
  // The GPU failed during this frame (lost, out of memory, a kernel fault):
  // the CPU finished the frame and renders from now on, and
  // gpu_unused_reason() says what failed. Only under kAuto and kHetero;
  // under kCuda end_frame() throws Error::kDevice instead.
  bool gpu_failed = false;
};

enum class ToneCurve { kStandard, kAces, kReinhard };

// Which image the image calls give: the accumulated samples, or (with
// RendererOptions::denoise) the denoised frame image_denoised() describes.
enum class FrameImage { kAccumulated, kDenoised };

class Renderer {
 public:
  // Creates the backends (see BackendChoice) with an empty scene; until
  // set_camera() is called, the camera frames the whole scene. Throws Error::kInvalidArgument for
  // bad options and Error::kDevice when BackendChoice::kCuda has no GPU.
  explicit Renderer(const RendererOptions& options = {});
  ~Renderer();  // waits for a frame in flight
  // A moved-from Renderer may only be destroyed or assigned to.
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // --- scene ---------------------------------------------------------------
  // Every edit below may be made at any time, also between begin_frame()
  // and end_frame(): it reaches the next frame and restarts accumulation.

  // Adds a texture for materials to use. Errors: kInvalidArgument for no
  // pixels or both kinds, an empty or oversized image, a float texel
  // outside [0, 1e6] or NaN, an sRGB float texture, or an unknown enum.
  TextureId add_texture(const TextureDesc& texture);
  // Adds a material. Errors: kInvalidArgument for NaN or out-of-range
  // fields, or a texture that does not exist.
  MaterialId add_material(const MaterialDesc& material);
  // Changes a material. Errors: kInvalidArgument for an unknown id or bad fields.
  void set_material(MaterialId id, const MaterialDesc& material);

  // Copies a mesh whose triangles all use `material`. Errors:
  // kInvalidArgument for null arrays, no vertices or triangles, an index >=
  // vertex_count, non-finite values, or an unknown material.
  MeshId add_mesh(const MeshData& mesh, MaterialId material);
  // Replaces a mesh's vertex positions (and normals/uvs where given) with
  // the same vertex count; its triangles stay (indices are ignored here).
  // Made for meshes a game deforms every frame: the vertices are copied
  // once here and converted straight into the arrays the renderers read at
  // the next frame, and the mesh's BVH is refit, not rebuilt.
  // Errors: kInvalidArgument for an unknown id, another vertex count, null
  // positions, or non-finite values.
  void set_mesh_vertices(MeshId id, const MeshData& vertices);
  // Removes a mesh that no instance uses any more (its memory is freed; the
  // next frame recompiles the scene, as after add_mesh). Errors:
  // kInvalidArgument for an unknown or removed id, kInvalidState while
  // instances of it remain.
  void remove_mesh(MeshId id);

  // Places a mesh in the world. Errors: kInvalidArgument for an unknown
  // mesh, or a transform with NaN/infinite entries, not affine, or a
  // translation beyond 1e9. An instance whose mesh reaches beyond 1e9 of
  // the origin, or is scaled to (nearly) nothing, is not drawn (with a
  // warning, or for a scale of 0 one notice).
  InstanceId add_instance(MeshId mesh, const Transform& transform);
  // Moves an instance (the acceleration structure is refitted, not rebuilt).
  // Errors: as add_instance, and for an unknown instance.
  void set_instance_transform(InstanceId id, const Transform& transform);
  // Removes an instance: from the next frame it is not drawn, lit or
  // framed, at the cost of a move (a TLAS update). Its memory is kept for
  // the next add_instance of the same mesh, so a game that spawns and
  // despawns objects holds memory for the most alive at once. Errors:
  // kInvalidArgument for an unknown or removed id.
  void remove_instance(InstanceId id);

  // Adds or changes a light. Errors: kInvalidArgument for NaN, negative
  // intensity or colour, colour x intensity above 1e30, a position beyond
  // 1e9 of the origin, a zero direction, or bad cone angles.
  LightId add_light(const LightDesc& light);
  void set_light(LightId id, const LightDesc& light);
  // Removes a light (the light list is rebuilt, not the scene). Errors:
  // kInvalidArgument for an unknown or removed id.
  void remove_light(LightId id);

  // Sets the camera (until then, the first frame places one that frames the
  // whole scene). The image's aspect ratio is width/height of the options,
  // the field of view is vertical. Errors: kInvalidArgument for NaN, a
  // position beyond 1e9 of the origin, target == position, up parallel to
  // the view direction, or a field of view outside (0, pi).
  void set_camera(const CameraDesc& camera);

  // A constant sky: radiance (linear RGB, W/(m^2 sr), >= 0) arriving from
  // every direction that hits no surface; (0, 0, 0), the default, is black.
  void set_environment_color(float r, float g, float b);
  // An equirectangular environment map (its top row is straight up, +y)
  // lighting the scene, importance-sampled, scaled by `intensity` (>= 0)
  // and turned by `rotation` radians about +y. From a file (.hdr, .exr of
  // any compression, .pfm, .png, .jpg; read now, up to 8192x4096), from
  // the caller's pixels (width * height * 3 linear RGB floats, copied), or
  // the built-in sky. Errors: kFile naming the file (missing, malformed,
  // too large), kInvalidArgument for bad pixels, sizes, intensity or
  // rotation (NaN, infinite, negative, a radiance beyond float's range).
  void set_environment_map(const std::string& path, float intensity = 1.0f, float rotation = 0.0f);
  void set_environment_pixels(uint32_t width, uint32_t height, const float* rgb,
                              float intensity = 1.0f, float rotation = 0.0f);
  void use_default_sky(float intensity = 1.0f, float rotation = 0.0f);

  // Replaces the whole scene by the default scene of a .gltf/.glb file
  // (meshes, instances in glTF node order, materials, lights, camera when
  // the file has one, otherwise one that frames the scene), lit by the
  // built-in sky unless RendererOptions::default_sky is off. Previous ids
  // become invalid. Errors: kFile naming the file and the reason (missing,
  // malformed, over the loader's memory budgets); kInvalidState during a frame.
  void load_gltf(const std::string& path);
  // Empties the scene (ids become invalid). Errors: kInvalidState during a frame.
  void clear_scene();

  // What the scene holds now (removed objects not counted).
  uint32_t material_count() const;
  uint32_t mesh_count() const;
  uint32_t instance_count() const;
  uint32_t light_count() const;
  uint32_t texture_count() const;

  // --- settings ------------------------------------------------------------
  // Changes the options; a new resolution, depth or seed restarts
  // accumulation, a new backend recreates the backends (and recompiles the
  // scene on the next frame). Errors: as the constructor; kInvalidState for
  // a backend change during a frame.
  void set_options(const RendererOptions& options);
  const RendererOptions& options() const;
  // Names of the backends that rendered the last frame, e.g. "cpu" or
  // "cuda+cpu"; empty before the first frame (and after a backend change).
  std::string backend_names() const;
  // Why this renderer does not use a GPU that kAuto or kHetero would use
  // ("no NVIDIA driver is installed", "this build of tandem has no CUDA
  // backend", the failure of a GPU lost during a frame, ...); empty when it
  // uses one or BackendChoice::kCpu was asked.
  std::string gpu_unused_reason() const;
  // Drops the accumulated samples; the next frame starts over.
  void reset_accumulation();

  // --- frames (the Brigade loop of tandem-view) ----------------------------
  // begin_frame() applies the scene edits since the last frame (scene
  // compile, BVH update, upload to the GPU) and starts every backend
  // rendering on its own threads, then returns: the caller may edit the
  // scene for the next frame (simulation, animation, input) while this one
  // renders. Errors: kInvalidState when a frame is already in flight or the
  // scene has no instance; kDevice when the GPU fails (under kAuto/kHetero
  // the CPU takes over instead, with a warning).
  void begin_frame();
  // Optional, between begin_frame() and end_frame(): compiles the edits
  // made so far for the next frame and updates its BVH now, overlapped with
  // this frame's render, when only the GPU renders. Returns false (and does
  // nothing) when that cannot overlap; the next begin_frame() does it then.
  // Errors: kInvalidState outside a frame.
  bool prepare_next_frame();
  // Waits for the backends, adds the frame's samples to the image and
  // returns what the frame did. Errors: kInvalidState without begin_frame();
  // kDevice when the GPU failed (the frame's samples are dropped, the next
  // frame starts over).
  FrameInfo end_frame();
  // begin_frame() then end_frame().
  FrameInfo render_frame();
  // Whether a frame is between begin_frame() and end_frame().
  bool frame_in_flight() const;

  // --- image ---------------------------------------------------------------
  // The image of the frames since the last accumulation reset, row 0 at the
  // top, at the resolution of the last rendered frame (width() x height()).
  // Errors: kInvalidState before the first end_frame() or during a frame.
  uint32_t width() const;
  uint32_t height() const;
  // Linear RGB radiance, width() * height() * 3 floats.
  std::vector<float> image_linear() const;
  // The same into the caller's buffer of `count` floats (at least
  // width() * height() * 3), without an allocation: for a game that
  // uploads the frame into its own texture. Errors: kInvalidArgument for a
  // null or short buffer, kInvalidState as above (and as image_denoised()
  // for FrameImage::kDenoised).
  void copy_image_linear(float* out, size_t count,
                         FrameImage image = FrameImage::kAccumulated) const;
  // With RendererOptions::denoise: the denoised image, linear RGB like
  // image_linear(), blended into the accumulated image as samples add up
  // (all accumulated from 64 samples per pixel). Errors: kInvalidState
  // without the option, before the first frame or during one.
  std::vector<float> image_denoised() const;
  // The last frame's feature buffers (with the denoiser on, the ones it
  // used; otherwise traced now, motion measured since the previous call).
  // Errors: kInvalidState as image_linear(); kDevice when no backend can
  // trace them (a GPU-only renderer).
  FeatureBuffers features();
  // Exposure (stops), tone curve and sRGB encoding: width() * height() * 3 bytes.
  std::vector<uint8_t> image_srgb8(float exposure_stops = 0.0f,
                                   ToneCurve curve = ToneCurve::kStandard,
                                   FrameImage image = FrameImage::kAccumulated) const;
  // The same into the caller's buffer of `count` bytes (at least
  // width() * height() * 3), e.g. a streaming SDL or OpenGL texture. The
  // accumulated image is resolved on the way (one temporary of width() *
  // height() * 3 floats); the denoised one is read in place. Errors: as
  // copy_image_linear.
  void copy_image_srgb8(uint8_t* out, size_t count, float exposure_stops = 0.0f,
                        ToneCurve curve = ToneCurve::kStandard,
                        FrameImage image = FrameImage::kAccumulated) const;
  // Writes the image: .png (tone mapped as image_srgb8), .exr or .pfm
  // (linear), atomically (a failed write leaves no partial file). Errors:
  // kFile naming the path (unknown extension, missing directory, write
  // failure), kInvalidState as above.
  void write_image(const std::string& path, float exposure_stops = 0.0f,
                   ToneCurve curve = ToneCurve::kStandard,
                   FrameImage image = FrameImage::kAccumulated) const;
  // With RendererOptions::cuda_image (and so BackendChoice::kCuda): the
  // accumulated image in GPU memory, for a host that presents it through
  // its own CUDA graphics interop (a cudaMemcpy2DToArray into a registered
  // OpenGL or Vulkan image) without a trip through the CPU. A CUDA device
  // pointer (Tandem's device, the runtime's primary context) to width() *
  // height() * 3 floats (linear, as image_linear()) or bytes (as
  // image_srgb8()), rows top first; the GPU work is finished when the call
  // returns. Valid until the next call of either, the next frame or a
  // change of options. Errors: kInvalidState without the option, before
  // the first frame or during one; kDevice when the GPU fails.
  const void* cuda_image_linear();
  const void* cuda_image_srgb8(float exposure_stops = 0.0f, ToneCurve curve = ToneCurve::kStandard);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace embed_v0
}  // namespace tandem
