// The order in which SceneCompiler brings the kernel arrays up to date.
// Each step names what it must come after; the per-kind work is in the
// compile_*.cpp files.
#include <algorithm>
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

namespace tandem {

bool SceneCompiler::needs_full_build(const Scene& scene) const {
  // Not the light count: lights added or removed rebuild the light list
  // only (compile()).
  const size_t counts[4] = {scene.textures().size(), scene.materials().size(), scene.mesh_count(),
                            scene.instances().size()};
  if (!compiled_once_ || !std::equal(counts, counts + 4, counts_)) return true;
  // New texels move every later texture's offset.
  if (!scene.dirty_textures().empty()) return true;
  // New topology moves every later mesh's vertex and triangle offsets.
  for (uint32_t m : scene.dirty_meshes()) {
    if (scene.mesh_dirty()[m] & (kDirtyTopology | kDirtyCreated)) return true;
  }
  return false;
}

void SceneCompiler::compile_full(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  // Texture slots first: materials refer to them.
  compile_textures(scene, out);
  // Materials before meshes: mesh flags (alpha test, emission) read them.
  compile_materials(scene, out);
  compile_meshes(scene, out, delta);
  // The instances into the bounds before any is classified by its box.
  for (const Instance& inst : scene.instances())
    bounds_.instance_added(inst.mesh);
  compile_instances(scene, out);
  // The environment before the lights: its luminance is the environment
  // light's power.
  compile_environment(scene, out, delta);
  // Lights last: triangle lights read materials, meshes and instances.
  compile_lights(scene, out, delta);

  delta.full = true;
#define TANDEM_MARK_ALL(T, name) delta.name.reallocated = true;
  TANDEM_SCENE_ARRAYS(TANDEM_MARK_ALL)
#undef TANDEM_MARK_ALL
}

SceneDelta SceneCompiler::compile(const Scene& scene, const RenderSettings& settings,
                                  KernelScene& out) {
  SceneDelta delta;
  light_sampler_ = settings.light_sampler;
  if (needs_full_build(scene)) {
    compile_full(scene, out, delta);
  } else {
    Needs needs;
    // Materials first: their emission decides whether lights follow.
    update_materials(scene, out, delta, needs);
    // Vertices: BLAS refits for the BVH updater, and emissive areas.
    update_meshes(scene, out, delta, needs);
    // Instances: the TLAS, and emissive areas of non-rigid moves.
    update_instances(scene, out, delta, needs);
    // The environment before the lights (its power is a light's).
    if (scene.environment_dirty()) {
      compile_environment(scene, out, delta);
      needs.light_list = true;
    }
    // Lights added or removed: their records and every light index after them.
    if (scene.lights().size() != counts_[4]) needs.light_list = true;
    // The other sampler: its tables.
    if (compiled_once_ && settings.light_sampler != last_settings_.light_sampler) {
      needs.light_list = true;
    }
    // Punctual lights, and the scene's size that directional powers scale with.
    needs.light_powers =
        !scene.dirty_lights().empty() || (delta.instances_changed() && scene_size_changed(scene));
    // Lights last: every step above may change a light's power.
    if (needs.full) {
      delta = SceneDelta{};
      compile_full(scene, out, delta);
    } else if (needs.light_list) {
      compile_lights(scene, out, delta);
    } else if (!needs.emissive_deformed.empty() || !needs.emissive_moved.empty() ||
               needs.light_powers) {
      // What changed, in place: deformed meshes' triangles, then the lights
      // of their instances and of moved ones, then punctual lights; the
      // light list keeps its order, or is built anew.
      std::vector<uint32_t> instances = needs.emissive_moved, changed;
      bool in_place = update_mesh_lights(out, delta, needs.emissive_deformed, instances);
      std::sort(instances.begin(), instances.end());
      instances.erase(std::unique(instances.begin(), instances.end()), instances.end());
      in_place = in_place && update_instance_lights(out, delta, instances, changed);
      if (in_place) {
        // The powers that follow the scene's size with the rest: the tables
        // are rebuilt anyway, and then are a fresh compile's.
        update_light_powers(scene, out, delta, changed);
        refresh_light_tables(out, delta, std::move(changed));
      } else {
        compile_lights(scene, out, delta);
      }
    }
  }
  // Constants after everything: any change above may move the bounds.
  if (delta.any() || scene.camera_dirty() || settings != last_settings_ || !compiled_once_) {
    compile_constants(scene, settings, out);
    delta.constants = true;
  }
  last_settings_ = settings;
  compiled_once_ = true;
  const size_t counts[5] = {scene.textures().size(), scene.materials().size(), scene.mesh_count(),
                            scene.instances().size(), scene.lights().size()};
  std::copy(counts, counts + 5, counts_);
  return delta;
}

SceneBounds SceneCompiler::scene_bounds(const Scene& scene) {
  return bounds_.bounds(
      scene.mesh_count(), [&](uint32_t m) -> const Mesh& { return scene.mesh(m); },
      scene.instances());
}

const SceneBounds& SceneCompiler::mesh_box(const Scene& scene, uint32_t mesh) {
  scene_bounds(scene);
  return bounds_.mesh_box(mesh);
}

}  // namespace tandem
