// Meshes: the mesh table (offsets, flags), the per-vertex arrays and the
// triangles. Flags read the materials, so materials compile first.
#include <algorithm>
#include <vector>
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

namespace tandem {

void SceneCompiler::compile_meshes(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  // Meshes: per-vertex arrays are only allocated when some mesh has them.
  bool any_normals = false, any_tangents = false, any_uv0 = false, any_uv1 = false;
  uint32_t vertex_total = 0, triangle_total = 0;
  out.meshes.clear();
  mesh_emissive_.assign(scene.meshes().size(), false);
  for (size_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& m = scene.meshes()[i];
    KMesh km{};
    km.vertex_offset = vertex_total;
    km.vertex_count = uint32_t(m.positions.size());
    km.triangle_offset = triangle_total;
    km.triangle_count = uint32_t(m.triangles.size());
    km.flags = (m.normals.empty() ? 0u : kMeshHasNormals) |
               (m.tangents.empty() ? 0u : kMeshHasTangents) | (m.uv0.empty() ? 0u : kMeshHasUv0) |
               (m.uv1.empty() ? 0u : kMeshHasUv1);
    for (uint32_t mat : m.triangle_materials) {
      const KMaterial& k = out.materials[std::min<size_t>(mat, out.materials.size() - 1)];
      if (k.alpha_mode != kAlphaOpaque) km.flags |= kMeshHasAlphaTest;
      if (!is_black(k.emission)) km.flags |= kMeshHasEmission;
    }
    mesh_emissive_[i] = (km.flags & kMeshHasEmission) != 0;
    any_normals |= !m.normals.empty();
    any_tangents |= !m.tangents.empty();
    any_uv0 |= !m.uv0.empty();
    any_uv1 |= !m.uv1.empty();
    vertex_total += km.vertex_count;
    triangle_total += km.triangle_count;
    out.meshes.push_back(km);
  }
  // One extra position so 16-byte SIMD loads of the last vertex stay in bounds.
  out.positions.assign(vertex_total + 1, Vec3{0, 0, 0});
  out.normals.assign(any_normals ? vertex_total : 0, Vec3{0, 0, 0});
  out.tangents.assign(any_tangents ? vertex_total : 0, Vec4{0, 0, 0, 0});
  out.uv0.assign(any_uv0 ? vertex_total : 0, Vec2{0, 0});
  out.uv1.assign(any_uv1 ? vertex_total : 0, Vec2{0, 0});
  out.triangles.resize(triangle_total);
  for (size_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& m = scene.meshes()[i];
    write_mesh_vertices(m, uint32_t(i), out);
    const uint32_t toff = out.meshes[i].triangle_offset;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
      const uint32_t mat = t < m.triangle_materials.size() ? m.triangle_materials[t] : 0u;
      out.triangles[toff + t] = {m.triangles[t].x, m.triangles[t].y, m.triangles[t].z,
                                 std::min<uint32_t>(mat, uint32_t(out.materials.size() - 1))};
    }
    delta.meshes_rebuilt.push_back(uint32_t(i));
  }
}

void SceneCompiler::write_mesh_vertices(const Mesh& mesh, uint32_t mesh_index, KernelScene& out) {
  const KMesh& km = out.meshes[mesh_index];
  const uint32_t base = km.vertex_offset;
  for (uint32_t v = 0; v < km.vertex_count; ++v) {
    out.positions[base + v] = to_vec3(mesh.positions[v]);
    if (!out.normals.empty())
      out.normals[base + v] = mesh.normals.empty() ? Vec3{0, 0, 0} : to_vec3(mesh.normals[v]);
    if (!out.tangents.empty()) {
      const glm::vec4 t = mesh.tangents.empty() ? glm::vec4(0.0f) : mesh.tangents[v];
      out.tangents[base + v] = {t.x, t.y, t.z, t.w};
    }
    if (!out.uv0.empty())
      out.uv0[base + v] = mesh.uv0.empty() ? Vec2{0, 0} : Vec2{mesh.uv0[v].x, mesh.uv0[v].y};
    if (!out.uv1.empty())
      out.uv1[base + v] = mesh.uv1.empty() ? Vec2{0, 0} : Vec2{mesh.uv1[v].x, mesh.uv1[v].y};
  }
}

void SceneCompiler::update_meshes(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                  Needs& needs) {
  std::vector<uint32_t> dirty = scene.dirty_meshes();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    if (!(scene.mesh_dirty()[i] & kDirtyVertices)) continue;
    write_mesh_vertices(scene.meshes()[i], i, out);
    const KMesh& km = out.meshes[i];
    delta.positions.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
    if (!out.normals.empty())
      delta.normals.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
    if (!out.tangents.empty())
      delta.tangents.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
    if (!out.uv0.empty()) delta.uv0.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
    if (!out.uv1.empty()) delta.uv1.mark(km.vertex_offset, km.vertex_offset + km.vertex_count);
    delta.meshes_refit.push_back(i);
    delta.instances_changed = true;  // TLAS bounds change with the BLAS
    needs.light_list |= mesh_emissive_[i];
  }
}

}  // namespace tandem
