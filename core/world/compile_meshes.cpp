// Meshes: the mesh table (offsets, flags), the per-vertex arrays and the
// triangles. Flags read the materials, so materials compile first.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"
#include "core/world/mesh_pose.h"
#include "core/world/running_box.h"

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
               (m.uv1.empty() ? 0u : kMeshHasUv1) |
               (scene.mesh_deforms(uint32_t(i)) ? kMeshDeforms : 0u);
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
  // The bounds anew, each mesh's box taken as its vertices are copied.
  bounds_ = SceneBoundsCache{};
  for (size_t i = 0; i < scene.meshes().size(); ++i) {
    const Mesh& m = scene.meshes()[i];
    bounds_.mesh_added();
    SceneBounds box;
    if (write_mesh_vertices(m, uint32_t(i), out, 0, out.meshes[i].vertex_count, &box))
      bounds_.mesh_vertex_bounds(uint32_t(i), box);
    const uint32_t toff = out.meshes[i].triangle_offset;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
      const uint32_t mat = t < m.triangle_materials.size() ? m.triangle_materials[t] : 0u;
      out.triangles[toff + t] = {m.triangles[t].x, m.triangles[t].y, m.triangles[t].z,
                                 std::min<uint32_t>(mat, uint32_t(out.materials.size() - 1))};
    }
    delta.meshes_rebuilt.push_back(uint32_t(i));
  }
}

namespace {

// Vertices converted per task: large enough that a deformed mesh of a
// million vertices is a few dozen tasks, small enough to spread over cores.
constexpr uint32_t kVertexGrain = 32768;

// out[base + v] = convert(in[v]) for v in [begin, end); a missing attribute
// (empty `in`) is written as zeros, as the kernels expect of a mesh without it.
template <class Out, class In, class Convert>
void convert_range(std::vector<Out>& out, const std::vector<In>& in, uint32_t base, uint32_t begin,
                   uint32_t end, Convert convert) {
  if (out.empty()) return;
  Out* dst = out.data() + base;
  if (in.empty()) {
    std::fill(dst + begin, dst + end, Out{});
    return;
  }
  for (uint32_t v = begin; v < end; ++v)
    dst[v] = convert(in[v]);
}

// convert_range() of the positions fused with vertex_bounds() over them:
// one pass, the box in registers (a second pass over a block the copy had
// just read cost as much as the copy). The same comparisons in the same
// order as vertex_bounds(), so the same box.
SceneBounds copy_positions_with_bounds(Vec3* dst, const glm::vec3* in, uint32_t begin, uint32_t end,
                                       bool* all_finite) {
  RunningBox box;
  for (uint32_t v = begin; v < end; ++v) {
    const float x = in[v].x, y = in[v].y, z = in[v].z;
    dst[v] = {x, y, z};
    box.add(x, y, z);
  }
  *all_finite = box.finite;
  return box.bounds(end > begin);
}

}  // namespace

bool SceneCompiler::write_mesh_vertices(const Mesh& mesh, uint32_t mesh_index, KernelScene& out,
                                        uint32_t begin, uint32_t end, SceneBounds* box) {
  const uint32_t base = out.meshes[mesh_index].vertex_offset;
  // One attribute at a time over a block: straight copies the compiler can
  // vectorise, instead of a branch per attribute per vertex.
  auto block = [&](uint32_t b, uint32_t e, bool positions = true) {
    if (positions) convert_range(out.positions, mesh.positions, base, b, e, to_vec3);
    convert_range(out.normals, mesh.normals, base, b, e, to_vec3);
    convert_range(out.tangents, mesh.tangents, base, b, e, [](const glm::vec4& t) {
      return Vec4{t.x, t.y, t.z, t.w};
    });
    const auto uv = [](const glm::vec2& t) { return Vec2{t.x, t.y}; };
    convert_range(out.uv0, mesh.uv0, base, b, e, uv);
    convert_range(out.uv1, mesh.uv1, base, b, e, uv);
  };
  // The box while the block's positions are still in the cache: the bounds
  // cache needs no pass of its own over a deformed mesh.
  struct Box {
    SceneBounds b;
    bool finite = true;
  };
  auto block_box = [&](uint32_t b, uint32_t e) {
    Box r;
    if (box != nullptr && e > b && e <= mesh.positions.size() && !out.positions.empty()) {
      r.b = copy_positions_with_bounds(out.positions.data() + base, mesh.positions.data(), b, e,
                                       &r.finite);
      block(b, e, /*positions=*/false);
      return r;
    }
    block(b, e);
    if (box != nullptr && e > b && e <= mesh.positions.size())
      r.b = vertex_bounds(mesh.positions.data() + b, e - b, &r.finite);
    return r;
  };
  if (end <= begin) return false;
  Box all;
  if (end - begin <= kVertexGrain) {
    all = block_box(begin, end);
  } else {
    all = tbb::parallel_reduce(
        tbb::blocked_range<uint32_t>(begin, end, kVertexGrain), Box{},
        [&](const tbb::blocked_range<uint32_t>& r, Box acc) {
          const Box here = block_box(r.begin(), r.end());
          acc.b.extend(here.b);
          acc.finite = acc.finite && here.finite;
          return acc;
        },
        [](Box a, const Box& b) {
          a.b.extend(b.b);
          a.finite = a.finite && b.finite;
          return a;
        });
  }
  if (box != nullptr) *box = all.b;
  return box != nullptr && all.finite;
}

namespace {

// Where a posed mesh's vertices go in `out`, when it is compiled with the
// pose's vertex count.
bool pose_target(KernelScene& out, uint32_t mesh, const MeshPose& pose, MeshVertexTarget* target) {
  const KMesh& km = out.meshes[mesh];
  const size_t n = km.vertex_count, first = km.vertex_offset;
  if (pose.vertex_count() != n || first + n > out.positions.size()) return false;
  target->positions = out.positions.data() + first;
  target->normals = (km.flags & kMeshHasNormals) && first + n <= out.normals.size()
                        ? out.normals.data() + first
                        : nullptr;
  target->tangents = (km.flags & kMeshHasTangents) && first + n <= out.tangents.size()
                         ? out.tangents.data() + first
                         : nullptr;
  target->uv0 =
      (km.flags & kMeshHasUv0) && first + n <= out.uv0.size() ? out.uv0.data() + first : nullptr;
  target->vertex_count = n;
  return true;
}

}  // namespace

void SceneCompiler::update_meshes(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                  Needs& needs) {
  std::vector<uint32_t> dirty = scene.dirty_meshes();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    if (!(scene.mesh_dirty()[i] & kDirtyVertices)) continue;
    const KMesh& km = out.meshes[i];
    // Only the edited vertices (Scene::edit_mesh_vertices with a range),
    // never past what the mesh was compiled with.
    const Scene::VertexRange r = scene.mesh_dirty_vertices(i);
    const size_t count = scene.mesh_vertex_count(i);
    const uint32_t end = std::min({r.end, km.vertex_count, uint32_t(count)});
    if (end <= r.begin) continue;
    const bool whole = r.begin == 0 && end == count;
    // A mesh only posed since the last compile: the pose goes straight
    // into `out` (the attributes it does not write are as compiled), and
    // the Scene's copy is neither written nor read. Otherwise (or where a
    // posed position is not finite) the copy is converted.
    const MeshPose* pose = whole ? scene.compiled_pose(i) : nullptr;
    MeshVertexTarget target;
    SceneBounds box;
    const bool boxed =
        pose != nullptr && pose_target(out, i, *pose, &target) && pose->write(target, &box)
            ? true
            : write_mesh_vertices(scene.mesh(i), i, out, r.begin, end, whole ? &box : nullptr);
    bounds_.mesh_changed(i);
    if (boxed) bounds_.mesh_vertex_bounds(i, box);
    const uint32_t b = km.vertex_offset + r.begin, e = km.vertex_offset + end;
    delta.positions.mark(b, e);
    if (!out.normals.empty()) delta.normals.mark(b, e);
    if (!out.tangents.empty()) delta.tangents.mark(b, e);
    if (!out.uv0.empty()) delta.uv0.mark(b, e);
    if (!out.uv1.empty()) delta.uv1.mark(b, e);
    delta.meshes_refit.push_back(i);  // the TLAS follows (instances_changed())
    if (mesh_emissive_[i]) needs.emissive_deformed.push_back(i);
  }
}

}  // namespace tandem
