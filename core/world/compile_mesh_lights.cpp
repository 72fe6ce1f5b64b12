// The triangle lights of emissive meshes, once per mesh however many times
// it is instanced: each emissive triangle's object-space constants
// (cache_triangle_light), and what chooses among a mesh's triangles once an
// instance of it is chosen: its alias table by power (the power sampler) or
// its light tree in object space (the tree sampler), which every instance
// walks with the shading point moved into its object space. A deformed
// mesh recomputes its own triangles and refits its tree in place.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

#include "core/kernel/lights.h"
#include "core/world/kernel_scene.h"
#include "core/world/light_tables.h"
#include "core/world/light_tree_build.h"

namespace tandem {

namespace {

// Triangle light `index` as the mesh's tree knows it, in object space.
LightTreeInput triangle_light_input(const KernelData& kd, uint32_t index) {
  const KTriangleLight& tl = kd.triangle_lights[index];
  const glm::vec3 p[3] = {
      {tl.p0.x, tl.p0.y, tl.p0.z}, {tl.p1.x, tl.p1.y, tl.p1.z}, {tl.p2.x, tl.p2.y, tl.p2.z}};
  LightTreeInput in;
  in.light = index;
  in.power = tl.power;
  in.lo = glm::min(p[0], glm::min(p[1], p[2]));
  in.hi = glm::max(p[0], glm::max(p[1], p[2]));
  in.axis = glm::vec3(tl.normal.x, tl.normal.y, tl.normal.z);  // the side it emits to
  in.cos_theta_o = 1.0f;
  in.cos_theta_e = 0.0f;
  in.two_sided = (kd.materials[tl.material].flags & kMaterialDoubleSided) != 0;
  return in;
}

// The lights of mesh `mesh` as its vertices are now: its triangles of
// non-black emission and positive power, in order.
std::vector<KTriangleLight> mesh_triangle_lights(const KernelData& kd, uint32_t mesh) {
  const KMesh& km = kd.meshes[mesh];
  std::vector<KTriangleLight> all(km.triangle_count);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, km.triangle_count, 16384), [&](auto r) {
    for (uint32_t p = r.begin(); p < r.end(); ++p) {
      const KMaterial& m = kd.materials[kd.triangles[km.triangle_offset + p].material];
      all[p] = is_black(m.emission) ? KTriangleLight{} : cache_triangle_light(kd, mesh, p);
    }
  });
  all.erase(std::remove_if(all.begin(), all.end(),
                           [](const KTriangleLight& t) { return !(t.power > 0.0f); }),
            all.end());
  return all;
}

}  // namespace

void SceneCompiler::mesh_light_tables(KernelScene& out, uint32_t mesh) {
  const KMeshLights& ml = out.mesh_lights[mesh];
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (uint32_t t = ml.first; t < ml.first + ml.count; ++t) {
    const KTriangleLight& tl = out.triangle_lights[t];
    for (const Vec3& v : {tl.p0, tl.p1, tl.p2}) {
      lo = glm::min(lo, glm::vec3(v.x, v.y, v.z));
      hi = glm::max(hi, glm::vec3(v.x, v.y, v.z));
    }
  }
  mesh_light_lo_[mesh] = lo;
  mesh_light_hi_[mesh] = hi;
  if (!tree_sampler()) {
    std::vector<double> power(ml.count);
    for (uint32_t k = 0; k < ml.count; ++k)
      power[k] = out.triangle_lights[ml.first + k].power;
    const std::vector<KAliasEntry> table = build_alias_table(power);
    std::copy(table.begin(), table.end(), out.triangle_light_alias.begin() + ml.first);
  }
}

void SceneCompiler::compile_mesh_lights(KernelScene& out, SceneDelta& delta) {
  out.triangle_lights.clear();
  out.mesh_lights.assign(out.meshes.size(), KMeshLights{0, 0, kInvalidIndex, 0.0f});
  mesh_light_lo_.assign(out.meshes.size(), glm::vec3(0.0f));
  mesh_light_hi_.assign(out.meshes.size(), glm::vec3(0.0f));
  for (uint32_t m = 0; m < out.meshes.size(); ++m) {
    KMeshLights& ml = out.mesh_lights[m];
    ml.first = uint32_t(out.triangle_lights.size());
    if (!mesh_emissive_[m]) continue;
    const std::vector<KTriangleLight> lights = mesh_triangle_lights(out.view(), m);
    ml.count = uint32_t(lights.size());
    for (const KTriangleLight& tl : lights)
      ml.power += tl.power;
    out.triangle_lights.insert(out.triangle_lights.end(), lights.begin(), lights.end());
  }
  out.triangle_light_trails.assign(out.triangle_lights.size(), 0);
  out.triangle_light_alias.assign(tree_sampler() ? 0 : out.triangle_lights.size(), KAliasEntry{});
  out.light_tree_nodes.clear();
  const KernelData kd = out.view();
  for (uint32_t m = 0; m < out.meshes.size(); ++m) {
    KMeshLights& ml = out.mesh_lights[m];
    if (ml.count == 0) continue;
    mesh_light_tables(out, m);
    if (tree_sampler()) {
      std::vector<LightTreeInput> inputs;
      inputs.reserve(ml.count);
      for (uint32_t t = ml.first; t < ml.first + ml.count; ++t)
        inputs.push_back(triangle_light_input(kd, t));
      ml.tree_root =
          append_light_tree(std::move(inputs), out.light_tree_nodes, out.triangle_light_trails);
    }
  }
  mesh_light_tree_nodes_ = uint32_t(out.light_tree_nodes.size());
  delta.triangle_lights.reallocated = true;
  delta.triangle_light_alias.reallocated = true;
  delta.triangle_light_trails.reallocated = true;
  delta.mesh_lights.reallocated = true;
  delta.light_tree_nodes.reallocated = true;
}

bool SceneCompiler::update_mesh_lights(KernelScene& out, SceneDelta& delta,
                                       const std::vector<uint32_t>& meshes,
                                       std::vector<uint32_t>& instances) {
  if (out.mesh_lights.size() != out.meshes.size() ||
      emissive_mesh_instances_.size() != out.meshes.size()) {
    return false;
  }
  for (uint32_t m : meshes) {
    KMeshLights& ml = out.mesh_lights[m];
    const std::vector<KTriangleLight> lights = mesh_triangle_lights(out.view(), m);
    // A triangle that gained or lost all its area changes the list.
    if (lights.size() != ml.count) return false;
    for (uint32_t k = 0; k < ml.count; ++k) {
      if (lights[k].prim != out.triangle_lights[ml.first + k].prim) return false;
    }
    if (ml.count == 0) continue;
    // The same sums as compile_mesh_lights(), so the powers (and the tables
    // built from them) are bit for bit a fresh compile's.
    ml.power = 0.0f;
    for (const KTriangleLight& tl : lights)
      ml.power += tl.power;
    std::copy(lights.begin(), lights.end(), out.triangle_lights.begin() + ml.first);
    delta.triangle_lights.mark(ml.first, ml.first + ml.count);
    delta.mesh_lights.mark(m, m + 1);
    mesh_light_tables(out, m);
    if (tree_sampler()) {
      const KernelData kd = out.view();
      refit_light_tree(out.light_tree_nodes, ml.tree_root,
                       [&](uint32_t light) { return triangle_light_input(kd, light); });
      // A mesh's tree is every node from its root to the next mesh's.
      uint32_t end = mesh_light_tree_nodes_;
      for (uint32_t next = m + 1; next < out.meshes.size(); ++next) {
        if (out.mesh_lights[next].count > 0) {
          end = out.mesh_lights[next].tree_root;
          break;
        }
      }
      delta.light_tree_nodes.mark(ml.tree_root, end);
    } else {
      delta.triangle_light_alias.mark(ml.first, ml.first + ml.count);
    }
    instances.insert(instances.end(), emissive_mesh_instances_[m].begin(),
                     emissive_mesh_instances_[m].end());
  }
  return true;
}

}  // namespace tandem
