// Host-side storage of the kernel arrays, and the compiler that fills it
// from a Scene.
//
// KernelScene owns one std::vector per entry of TANDEM_KERNEL_ARRAYS; every
// backend reads the scene through KernelScene::view() (host pointers) or
// uploads the same vectors (CUDA). Each array has one writer
// (kernel_data.h): SceneCompiler fills TANDEM_SCENE_ARRAYS and `constants`
// from the Scene's dirty objects (scene_compiler.cpp gives the order, the
// compile_*.cpp files one kind of object each), AccelStructure
// (accstruc/) fills TANDEM_BVH_ARRAYS and `bvh`. Each reports exactly which
// element ranges it rewrote in a SceneDelta, and backends commit the union
// of the two, so they upload deltas instead of everything.
#pragma once

#include <cstddef>
#include <map>
#include <vector>

#include "core/kernel/kernel_data.h"
#include "core/world/light_tree_build.h"
#include "core/world/scene.h"
#include "core/world/scene_ranges.h"

namespace tandem {

class KernelScene {
 public:
#define TANDEM_DECLARE_VECTOR(T, name) std::vector<T> name;
  TANDEM_KERNEL_ARRAYS(TANDEM_DECLARE_VECTOR)
#undef TANDEM_DECLARE_VECTOR
  KernelConstants constants{};  // written by SceneCompiler
  KBvhConstants bvh{};          // written by AccelStructure

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

// Elements of one array were rewritten: up to kMaxRanges disjoint ascending
// ranges, and [begin, end) their bounding range (what a reader that wants
// one range uses: it re-sends unchanged elements in between, never misses
// one). Separate ranges keep, say, a deformed mesh's BLAS nodes and the
// TLAS at the end of the same array from being sent as everything between
// them. `reallocated` means the array changed size (or was rebuilt) and
// must be re-sent as a whole.
struct ArrayChange {
  static constexpr uint32_t kMaxRanges = 8;
  struct Range {
    uint32_t begin = 0, end = 0;
  };
  uint32_t begin = 0, end = 0;
  bool reallocated = false;
  uint32_t range_count = 0;  // 0 with end > begin: the bounding range is the one range
  Range ranges[kMaxRanges] = {};
  // Adds [b, e): merged with the ranges it overlaps or touches; past
  // kMaxRanges the two ranges with the smallest gap merge.
  void mark(uint32_t b, uint32_t e);
  bool any() const { return reallocated || end > begin; }
  // The changed ranges, ascending (the bounding range when none were kept).
  template <class F>
  void for_each_range(F&& f) const {
    if (end <= begin) return;
    if (range_count == 0) {
      f(begin, end);
      return;
    }
    for (uint32_t i = 0; i < range_count; ++i)
      f(ranges[i].begin, ranges[i].end);
  }
  // Elements in the ranges.
  size_t element_count() const;
};

struct SceneDelta {
#define TANDEM_DECLARE_CHANGE(T, name) ArrayChange name;
  TANDEM_KERNEL_ARRAYS(TANDEM_DECLARE_CHANGE)
#undef TANDEM_DECLARE_CHANGE
  bool full = false;                     // everything was rebuilt
  bool constants = false;                // camera / environment / integrator scalars
  bool bvh_constants = false;            // KernelScene::bvh (TLAS roots, layout)
  std::vector<uint32_t> meshes_rebuilt;  // BLAS to rebuild (new topology)
  std::vector<uint32_t> meshes_refit;    // BLAS to refit (vertices moved)
  // Ascending: the instances whose transform changed. When non-empty the
  // BVH updater refits only their TLAS paths, so it must list every moved
  // instance; a caller that leaves it empty gets a refit of all of them.
  std::vector<uint32_t> instances_moved;

  bool any() const;
  // The TLAS must follow: instance records changed, or BLAS whose bounds
  // the instances see were refit (everything, after a full build).
  bool instances_changed() const {
    return full || instances.any() || !meshes_refit.empty();
  }
  // What a backend that has seen nothing of the scene needs: every array
  // reallocated, the constants, the instances.
  static SceneDelta everything();
  // Adds `later`'s changes (what a second compile found, or the BVH
  // updater's changes) to this delta.
  void merge(const SceneDelta& later);
  // Bytes an upload of exactly the changed ranges moves (what the CUDA
  // backend reports as "commit bytes").
  size_t bytes(const KernelScene& ks) const;
};

// Per-frame render parameters that end up in KernelConstants.
// How next-event estimation chooses a light (core/kernel/lights.h).
enum class LightSampler : uint8_t {
  kPower,  // an alias table by power
  kTree,   // the light tree for finite lights, by power for infinite ones
};

struct RenderSettings {
  uint32_t width = 1280, height = 720;
  uint32_t max_depth = 8;       // scattering events; 1 = direct lighting only
  uint32_t rr_start_depth = 3;  // Russian roulette after this many bounces
  uint32_t seed = 0;
  float radiance_clamp = 0.0f;  // 0 = off
  // The tree: 2x faster to equal noise on the many-light scene, within 5%
  // on the Cornell box and ToyCar (docs/performance/log/light_sampling.md).
  LightSampler light_sampler = LightSampler::kTree;
  // Every field: one comparison for "did the settings change", so that a
  // field added here is never forgotten by a hand-written one.
  bool operator==(const RenderSettings&) const = default;
};

class SceneCompiler {
 public:
  // Brings `out`'s scene arrays and constants up to date with `scene` and
  // `settings`. The first call (or any added/removed object) does a full
  // build. Costs O(what changed): the dirty lists are walked, never the
  // whole scene (light tables excepted, whose alias table is rebuilt,
  // O(lights), when a light's power changes). The scene is only read: its
  // owner (SceneSync) clears its dirty flags once the changes are taken.
  // A posed mesh (Scene::pose_mesh) is written from its pose straight into
  // `out`, without writing the Scene's copy.
  SceneDelta compile(const Scene& scene, const RenderSettings& settings, KernelScene& out);

 private:
  // What the edits of one incremental compile require downstream.
  struct Needs {
    bool full = false;          // an edit only a full build handles (alpha mode)
    bool light_list = false;    // triangle lights or the environment light changed
    bool light_powers = false;  // punctual light parameters or the scene size changed
    // Emissive meshes whose vertices moved: their triangle lights' powers
    // (areas) change, the light list does not (unless an area reaches 0).
    std::vector<uint32_t> emissive_deformed;
    // Moved instances of emissive meshes: their lights' powers and bounds.
    std::vector<uint32_t> emissive_moved;
  };
  bool needs_full_build(const Scene& scene) const;
  void compile_full(const Scene& scene, KernelScene& out, SceneDelta& delta);

  // compile_textures.cpp
  void compile_textures(const Scene& scene, KernelScene& out);
  // The key of texture_slots_ for `texture` read by a slot that decodes
  // sRGB when `slot_srgb` (Texture::decodes_srgb decides for the texture).
  static uint64_t texture_key(const Scene& scene, int32_t texture, bool slot_srgb);
  // The mean luminance of texture `texture` as the emission slot reads it, computed at its
  // first use as an emissive texture after compile_textures() (only those
  // need it; every texel of every texture was a quarter of a second of a
  // textured model's compile).
  float texture_mean_luminance(const Scene& scene, uint32_t texture);
  // compile_materials.cpp
  void compile_materials(const Scene& scene, KernelScene& out);
  KMaterial compile_material(const Scene& scene, const Material& m);
  void update_materials(const Scene& scene, KernelScene& out, SceneDelta& delta, Needs& needs);
  // compile_meshes.cpp
  void compile_meshes(const Scene& scene, KernelScene& out, SceneDelta& delta);
  // Converts vertices [begin, end) of one mesh into the kernel arrays; with
  // `box`, also the box of those positions (false when one is not finite).
  bool write_mesh_vertices(const Mesh& mesh, uint32_t mesh_index, KernelScene& out, uint32_t begin,
                           uint32_t end, SceneBounds* box = nullptr);
  // A mesh's new vertices: its pose written into `out` when the Scene
  // holds one (Scene::compiled_pose), else the Scene's copy converted. The
  // box of each whole mesh written goes to bounds_.
  void update_meshes(const Scene& scene, KernelScene& out, SceneDelta& delta, Needs& needs);
  // The scene's bounds and a mesh's object-space box as compiled: from the
  // boxes taken while the vertices were written (a posed mesh's are never
  // in the Scene), O(edits) like the Scene's own cache.
  SceneBounds scene_bounds(const Scene& scene);
  const SceneBounds& mesh_box(const Scene& scene, uint32_t mesh);
  // compile_instances.cpp
  // An instance the tracers cannot take (scene_ranges.h) is compiled hidden:
  // zero transforms, kInstanceHidden, with one notice.
  void compile_instances(const Scene& scene, KernelScene& out);
  KInstance compile_instance(const Scene& scene, uint32_t instance);
  // Moved instances, and the instances of meshes whose vertices changed
  // (their world box, and whether they can be drawn, changed with them).
  void update_instances(const Scene& scene, KernelScene& out, SceneDelta& delta, Needs& needs);
  void note_hidden(const Scene& scene, uint32_t instance, InstanceState state);
  // compile_environment.cpp
  void compile_environment(const Scene& scene, KernelScene& out, SceneDelta& delta);
  // compile_lights.cpp
  // The light list anew: punctual lights, the environment, the meshes'
  // triangle lights and one light per instance of an emissive mesh.
  void compile_lights(const Scene& scene, KernelScene& out, SceneDelta& delta);
  // The alias table, total power and (with the tree sampler) the tree over
  // the light list's finite lights, built anew from light_power_.
  void finish_light_tables(KernelScene& out, SceneDelta& delta);
  void compile_light_alias(KernelScene& out, bool with_tree);
  // The same after the lights `changed` (indices of out.lights) changed
  // within a list that kept its order: the alias table anew, the tree refit
  // along their paths (built anew when a light entered or left it).
  void refresh_light_tables(KernelScene& out, SceneDelta& delta, std::vector<uint32_t> changed);
  // Dirty punctual lights and the powers that follow the scene's size; the
  // lights whose records changed go to `changed`.
  void update_light_powers(const Scene& scene, KernelScene& out, SceneDelta& delta,
                           std::vector<uint32_t>& changed);
  // The lights of `instances` (moved, or of deformed meshes): their world
  // powers; false (for compile_lights) when one would enter or leave the list.
  bool update_instance_lights(KernelScene& out, SceneDelta& delta,
                              const std::vector<uint32_t>& instances,
                              std::vector<uint32_t>& changed);
  LightTreeInput light_tree_input(const KernelData& kd, uint32_t light, float power) const;
  bool tree_sampler() const;
  // compile_mesh_lights.cpp
  // Every emissive mesh's triangle lights, its table or tree.
  void compile_mesh_lights(KernelScene& out, SceneDelta& delta);
  // Mesh `mesh`'s box of lights and (the power sampler) its alias table.
  void mesh_light_tables(KernelScene& out, uint32_t mesh);
  // Deformed emissive meshes: their triangle lights recomputed, tables
  // rebuilt or trees refit, O(their triangles); their instances go to
  // `instances`. False (nothing is left half done that compile_lights
  // would not redo) when a triangle enters or leaves the list.
  bool update_mesh_lights(KernelScene& out, SceneDelta& delta, const std::vector<uint32_t>& meshes,
                          std::vector<uint32_t>& instances);
  bool scene_size_changed(const Scene& scene);
  // compile_constants.cpp
  void compile_constants(const Scene& scene, const RenderSettings& settings, KernelScene& out);

  bool compiled_once_ = false;
  SceneBoundsCache bounds_;  // scene_bounds()
  size_t counts_[5] = {};    // textures, materials, meshes, instances, lights at last compile
  std::map<uint64_t, uint32_t> texture_slots_;  // (texture, srgb) -> KTexture index
  std::vector<uint32_t> texture_texel_offset_;
  std::vector<float> texture_mean_luminance_;  // texture_mean_luminance(); < 0: not yet
  std::vector<bool> mesh_emissive_;            // mesh uses an emissive material
  float lights_radius_ = -1.0f;                // scene radius the light powers were computed with
  // Every light's power as in light_alias, in the order of out.lights
  // (punctual lights, the environment, instances of emissive meshes): a
  // light's change rebuilds the alias table from these.
  std::vector<double> light_power_;
  // The instances of each mesh that has triangle lights, so a deformed mesh
  // finds its instances' lights.
  std::vector<std::vector<uint32_t>> emissive_mesh_instances_;
  // The tree sampler: the object-space box of each mesh's triangle lights,
  // the end of the meshes' trees in out.light_tree_nodes (the lights' tree
  // follows), that tree's boxes and parents, and the leaf of each light.
  std::vector<glm::vec3> mesh_light_lo_, mesh_light_hi_;
  uint32_t mesh_light_tree_nodes_ = 0;
  LightTreeShape top_shape_;
  // The instances of each mesh, for update_instances; and per instance the
  // state it was last noted hidden in (kVisible: never), so that each is
  // said once, and singular ones once for all.
  std::vector<std::vector<uint32_t>> mesh_instances_;
  std::vector<InstanceState> hidden_noted_;
  bool singular_noted_ = false;
  // compile_lights.cpp: a punctual light the tracers cannot take is off;
  // said once while it stays so.
  void note_light(const Scene& scene, uint32_t light);
  std::vector<uint8_t> lights_noted_;
  RenderSettings last_settings_{};
  // The sampler of the compile under way (the light tables follow it).
  LightSampler light_sampler_ = LightSampler::kPower;
};

}  // namespace tandem
