// Instances: transforms (and their inverses) to KInstance; an instance the
// tracers cannot take (scene_ranges.h) is compiled hidden.
#include <algorithm>
#include <cstring>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "core/util/log.h"
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

namespace tandem {

KInstance SceneCompiler::compile_instance(const Scene& scene, uint32_t index) {
  const Instance& inst = scene.instances()[index];
  KInstance k{};
  k.mesh = inst.mesh;
  k.handedness = 1.0f;
  if (inst.hidden) {
    k.flags = kInstanceHidden;  // as below, but asked for: nothing to say
    return k;
  }
  const InstanceState state = inst.mesh < scene.mesh_count()
                                  ? classify_instance(inst.transform, mesh_box(scene, inst.mesh))
                                  : InstanceState::kVisible;
  if (state != InstanceState::kVisible) {
    // Not drawn: out of the TLAS, disabled in Embree, and its zero
    // transforms give its triangle lights no area.
    k.flags = kInstanceHidden;
    note_hidden(scene, index, state);
    return k;
  }
  k.object_to_world = to_mat34(inst.transform);
  k.world_to_object = to_mat34(glm::inverse(inst.transform));
  k.handedness = glm::determinant(glm::mat3(inst.transform)) < 0.0f ? -1.0f : 1.0f;
  if (inst.transform == glm::mat4(1.0f)) k.flags |= kInstanceIdentity;
  return k;
}

void SceneCompiler::note_hidden(const Scene& scene, uint32_t index, InstanceState state) {
  if (hidden_noted_.size() <= index) hidden_noted_.resize(index + 1, InstanceState::kVisible);
  if (hidden_noted_[index] == state) return;
  hidden_noted_[index] = state;
  const Instance& inst = scene.instances()[index];
  const std::string mesh_name =
      inst.mesh < scene.mesh_count() ? scene.mesh_name(inst.mesh).substr(0, 80) : "";
  const std::string what = "instance " + std::to_string(index) +
                           (inst.name.empty() ? "" : " ('" + inst.name.substr(0, 80) + "')") +
                           " of mesh " + std::to_string(inst.mesh) +
                           (mesh_name.empty() ? "" : " ('" + mesh_name + "')") + " " +
                           instance_state_text(state) + ": not drawn";
  // The usual way to hide an object (a scale of 0) is said once for all.
  if (state == InstanceState::kSingular) {
    if (!singular_noted_) log_info(what + " (said once for all such instances)");
    singular_noted_ = true;
    return;
  }
  log_warning((scene.source.empty() ? std::string() : scene.source + ": ") + what);
}

void SceneCompiler::compile_instances(const Scene& scene, KernelScene& out) {
  out.instances.clear();
  mesh_instances_.assign(scene.mesh_count(), {});
  const uint32_t n = uint32_t(scene.instances().size());
  for (uint32_t i = 0; i < n; ++i) {
    out.instances.push_back(compile_instance(scene, i));
    const uint32_t m = scene.instances()[i].mesh;
    if (m < mesh_instances_.size()) mesh_instances_[m].push_back(i);
  }
}

void SceneCompiler::update_instances(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                     Needs& needs) {
  std::vector<uint32_t> dirty = scene.dirty_instances();
  for (uint32_t i : dirty)
    bounds_.instance_changed(i);
  // Instances of meshes whose vertices changed: recompiled, and counted as
  // changed only if they did (a mesh that starts or stops being drawable).
  std::vector<uint32_t> recheck;
  for (uint32_t m : scene.dirty_meshes()) {
    if (m >= mesh_instances_.size() || !(scene.mesh_dirty()[m] & kDirtyVertices)) continue;
    recheck.insert(recheck.end(), mesh_instances_[m].begin(), mesh_instances_[m].end());
  }
  std::sort(dirty.begin(), dirty.end());
  std::sort(recheck.begin(), recheck.end());
  for (uint32_t i : recheck) {
    if (std::binary_search(dirty.begin(), dirty.end(), i)) continue;
    const KInstance k = compile_instance(scene, i);
    if (std::memcmp(&k, &out.instances[i], sizeof k) != 0) dirty.push_back(i);
  }
  std::sort(dirty.begin(), dirty.end());
  dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
  for (uint32_t i : dirty) {
    const KInstance before = out.instances[i];
    out.instances[i] = compile_instance(scene, i);
    delta.instances.mark(i, i + 1);
    delta.instances_moved.push_back(i);
    // An instance's light follows it (its power, and the tree's bounds):
    // O(the instance) plus the light tables; one that changes mesh changes
    // the light list.
    const KInstance& after = out.instances[i];
    const bool emissive = mesh_emissive_[before.mesh] || mesh_emissive_[after.mesh];
    if (emissive) needs.emissive_moved.push_back(i);
    needs.light_list |= emissive && before.mesh != after.mesh;
  }
}

}  // namespace tandem
