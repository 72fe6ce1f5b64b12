// Instances: transforms (and their inverses) to KInstance.
#include <algorithm>
#include <vector>
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

#include <glm/glm.hpp>

namespace tandem {

namespace {

// Whether two affine maps scale every area alike: their linear parts have the
// same Gram matrix (A^T A), up to float rounding (rotations, translations).
bool same_areas(const Mat34& a, const Mat34& b) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double ga = 0.0, gb = 0.0, scale = 0.0;
      for (int r = 0; r < 3; ++r) {
        const float* ra = &a.rows[r].x;
        const float* rb = &b.rows[r].x;
        ga += double(ra[i]) * ra[j];
        gb += double(rb[i]) * rb[j];
        scale += double(ra[i]) * ra[i] + double(ra[j]) * ra[j];
      }
      if (std::fabs(ga - gb) > 1e-5 * std::max(scale, 1e-30)) return false;
    }
  }
  return true;
}

}  // namespace

KInstance SceneCompiler::compile_instance(const Instance& inst) const {
  KInstance k{};
  k.object_to_world = to_mat34(inst.transform);
  k.world_to_object = to_mat34(glm::inverse(inst.transform));
  k.mesh = inst.mesh;
  k.handedness = glm::determinant(glm::mat3(inst.transform)) < 0.0f ? -1.0f : 1.0f;
  if (inst.transform == glm::mat4(1.0f)) k.flags |= kInstanceIdentity;
  return k;
}

void SceneCompiler::compile_instances(const Scene& scene, KernelScene& out) {
  out.instances.clear();
  for (const Instance& inst : scene.instances())
    out.instances.push_back(compile_instance(inst));
}

void SceneCompiler::update_instances(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                     Needs& needs) {
  std::vector<uint32_t> dirty = scene.dirty_instances();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    const KInstance before = out.instances[i];
    out.instances[i] = compile_instance(scene.instances()[i]);
    delta.instances.mark(i, i + 1);
    delta.instances_changed = true;
    delta.instances_moved.push_back(i);
    // Triangle lights are stored as (instance, prim): moving an emissive
    // instance rigidly changes neither the light list nor any light's
    // power, so the (large) light arrays stay as they are.
    const KInstance& after = out.instances[i];
    triangle_powers_stale_ |= mesh_emissive_[before.mesh] || mesh_emissive_[after.mesh];
    needs.light_list |=
        (mesh_emissive_[before.mesh] || mesh_emissive_[after.mesh]) &&
        (before.mesh != after.mesh || !same_areas(before.object_to_world, after.object_to_world));
  }
}

}  // namespace tandem
