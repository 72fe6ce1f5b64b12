// Host-side storage of the kernel arrays, and the compiler that fills it
// from a Scene.
//
// KernelScene owns one std::vector per entry of TANDEM_KERNEL_ARRAYS; every
// backend reads the scene through KernelScene::view() (host pointers) or
// uploads the same vectors (CUDA). SceneCompiler applies the Scene's dirty
// flags in a fixed order (textures -> materials -> meshes -> instances ->
// lights -> camera/environment) and reports exactly which element ranges it
// rewrote in a SceneDelta, so backends can commit deltas instead of
// re-uploading everything.
#pragma once

#include <cstddef>
#include <map>
#include <vector>

#include "core/kernel/kernel_data.h"
#include "core/scene/scene.h"

namespace tandem {

class KernelScene {
 public:
#define TANDEM_DECLARE_VECTOR(T, name) std::vector<T> name;
  TANDEM_KERNEL_ARRAYS(TANDEM_DECLARE_VECTOR)
#undef TANDEM_DECLARE_VECTOR
  KernelConstants constants{};

  // Pointers into the vectors above; valid until the next compile.
  KernelData view() const;
  // Number of vertices (positions carries one element of padding).
  uint32_t vertex_count() const;
  size_t byte_size() const;
};

// Backends that trace Tandem's BVH call this in sync(): the kernels treat a
// missing BVH as "nothing to hit" (an empty scene), so a caller that forgot
// AccelStructure would silently get a black image. Throws std::logic_error (a
// caller's bug, not bad input) naming `backend` when a mesh's BLAS root or
// the TLAS root is missing or out of range.
void check_bvh_present(const KernelScene& ks, const char* backend);

// Elements [begin, end) of one array were rewritten; `reallocated` means the
// array changed size (or was rebuilt) and must be re-sent as a whole.
struct ArrayChange {
  uint32_t begin = 0, end = 0;
  bool reallocated = false;
  void mark(uint32_t b, uint32_t e);
  bool any() const { return reallocated || end > begin; }
};

struct SceneDelta {
#define TANDEM_DECLARE_CHANGE(T, name) ArrayChange name;
  TANDEM_KERNEL_ARRAYS(TANDEM_DECLARE_CHANGE)
#undef TANDEM_DECLARE_CHANGE
  bool full = false;                     // everything was rebuilt
  bool constants = false;                // camera / environment / integrator scalars
  bool instances_changed = false;        // TLAS must be rebuilt
  std::vector<uint32_t> meshes_rebuilt;  // BLAS to rebuild (new topology)
  std::vector<uint32_t> meshes_refit;    // BLAS to refit (vertices moved)

  bool any() const;
  // What a backend that has seen nothing of the scene needs: every array
  // reallocated, the constants, the instances.
  static SceneDelta everything();
  // Adds `later`'s changes (what a second compile found) to this delta.
  void merge(const SceneDelta& later);
  // Bytes an upload of exactly the changed ranges moves (what the CUDA
  // backend reports as "commit bytes").
  size_t bytes(const KernelScene& ks) const;
};

// Per-frame render parameters that end up in KernelConstants.
struct RenderSettings {
  uint32_t width = 1280, height = 720;
  uint32_t max_depth = 8;       // scattering events; 1 = direct lighting only
  uint32_t rr_start_depth = 3;  // Russian roulette after this many bounces
  uint32_t seed = 0;
  float radiance_clamp = 0.0f;  // 0 = off
  // Every field: one comparison for "did the settings change", so that a
  // field added here is never forgotten by a hand-written one.
  bool operator==(const RenderSettings&) const = default;
};

class SceneCompiler {
 public:
  // Brings `out` up to date with `scene` and `settings`, then clears the
  // scene's dirty flags. The first call (or any added/removed object) does a
  // full build.
  SceneDelta compile(Scene& scene, const RenderSettings& settings, KernelScene& out);

 private:
  void compile_full(const Scene& scene, KernelScene& out, SceneDelta& delta);
  void compile_textures(const Scene& scene, KernelScene& out);
  KMaterial compile_material(const Scene& scene, const Material& m);
  void write_mesh_vertices(const Mesh& mesh, uint32_t mesh_index, KernelScene& out);
  KInstance compile_instance(const Instance& inst) const;
  void compile_lights(const Scene& scene, KernelScene& out, SceneDelta& delta);
  void compile_environment(const Scene& scene, KernelScene& out, SceneDelta& delta);
  void compile_constants(const Scene& scene, const RenderSettings& settings, KernelScene& out);
  uint32_t texture_index(uint32_t texture, bool srgb) const;

  bool compiled_once_ = false;
  size_t counts_[5] = {};  // textures, materials, meshes, instances, lights at last compile
  std::map<uint64_t, uint32_t> texture_slots_;  // (texture, srgb) -> KTexture index
  std::vector<uint32_t> texture_texel_offset_;
  std::vector<float> texture_mean_luminance_;  // sRGB-decoded, for emissive power
  std::vector<bool> mesh_emissive_;            // mesh uses an emissive material
  float lights_radius_ = -1.0f;                // scene radius the light powers were computed with
  RenderSettings last_settings_{};
};

}  // namespace tandem
