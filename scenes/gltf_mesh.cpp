// glTF meshes -> tandem Meshes: every triangle primitive of a glTF mesh is
// merged into one Mesh (vertex arrays concatenated, one material per
// triangle), strips and fans become triangle lists.
#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/glm.hpp>

#include "scenes/gltf_internal.h"
#include "scenes/gltf_validate.h"

namespace tandem::gltf {

namespace {

// Which vertex range and triangle range of the merged mesh one primitive
// filled, and which optional attributes it brought.
struct Part {
  size_t first_vertex = 0, vertex_count = 0;
  size_t first_triangle = 0, triangle_count = 0;
  bool normals = false;
};

int attribute(const tinygltf::Primitive& p, const char* name) {
  const auto it = p.attributes.find(name);
  return it == p.attributes.end() ? -1 : it->second;
}

// Appends `count` elements of an optional attribute. The array stays empty
// until some primitive has the attribute; from then on, primitives without
// it get `fill`, so the array is always empty or one entry per vertex.
template <class T>
void append_attribute(std::vector<T>& array, bool& active, size_t vertices_before,
                      const std::vector<float>* source, size_t count, const T& fill) {
  if (source != nullptr) {
    if (!active) {
      array.assign(vertices_before, fill);
      active = true;
    }
    const size_t at = array.size();
    array.resize(at + count);
    static_assert(sizeof(T) % sizeof(float) == 0);
    std::memcpy(&array[at], source->data(), count * sizeof(T));
  } else if (active) {
    array.resize(vertices_before + count, fill);
  }
}

// Area-weighted vertex normals for a primitive that has none while others
// in the same mesh do.
void fill_face_normals(Mesh& mesh, const Part& part) {
  for (size_t t = part.first_triangle; t < part.first_triangle + part.triangle_count; ++t) {
    const glm::uvec3 tri = mesh.triangles[t];
    const glm::vec3 n = glm::cross(mesh.positions[tri.y] - mesh.positions[tri.x],
                                   mesh.positions[tri.z] - mesh.positions[tri.x]);
    for (int k = 0; k < 3; ++k)
      mesh.normals[tri[k]] += n;
  }
  for (size_t v = part.first_vertex; v < part.first_vertex + part.vertex_count; ++v) {
    const float len = glm::length(mesh.normals[v]);
    mesh.normals[v] = len > 0.0f && std::isfinite(len) ? mesh.normals[v] / len : glm::vec3(0, 0, 1);
  }
}

// Triangle count a primitive will produce (before dropping degenerates).
size_t triangle_count(int mode, size_t index_count) {
  if (mode == TINYGLTF_MODE_TRIANGLES) return index_count / 3;
  return index_count >= 3 ? index_count - 2 : 0;  // strip or fan
}

}  // namespace

DecodedMeshes decode_meshes(Context& ctx, AccessorCache& cache, uint32_t default_material) {
  const tinygltf::Model& m = ctx.model;
  DecodedMeshes out;
  out.meshes.resize(m.meshes.size());
  out.keys.resize(m.meshes.size());
  out.uses_default_material.assign(m.meshes.size(), false);

  for (size_t mi = 0; mi < m.meshes.size(); ++mi) {
    const tinygltf::Mesh& gm = m.meshes[mi];
    Mesh& mesh = out.meshes[mi];
    mesh.name = gm.name.empty() ? "mesh " + std::to_string(mi) : gm.name;
    std::string& key = out.keys[mi];
    std::vector<Part> parts;
    bool has_normals = false, has_tangents = false, has_uv0 = false, has_uv1 = false;
    out.primitives += gm.primitives.size();

    for (size_t pi = 0; pi < gm.primitives.size(); ++pi) {
      const tinygltf::Primitive& p = gm.primitives[pi];
      const std::string who = "mesh " + std::to_string(mi) + " primitive " + std::to_string(pi);
      const int pos = attribute(p, "POSITION"), nrm = attribute(p, "NORMAL"),
                tan = attribute(p, "TANGENT"), uv0 = attribute(p, "TEXCOORD_0"),
                uv1 = attribute(p, "TEXCOORD_1");
      const uint32_t material = p.material >= 0 ? uint32_t(p.material) : default_material;
      key += std::to_string(p.mode) + "," + std::to_string(pos) + "," + std::to_string(nrm) + "," +
             std::to_string(tan) + "," + std::to_string(uv0) + "," + std::to_string(uv1) + "," +
             std::to_string(p.indices) + "," + std::to_string(material) + ";";

      const size_t vertex_count = m.accessors[size_t(pos)].count;
      // Points and lines are not rendered: nothing of them is decoded (the
      // validator has checked their accessors' formats and ranges).
      if (p.mode < TINYGLTF_MODE_TRIANGLES) {
        ctx.warn_once("mode" + std::to_string(p.mode),
                      who + " (and any others like it) draws points or lines, which are skipped");
        continue;
      }
      // Index values are checked while decoding: an index out of range is a
      // broken file.
      const std::vector<uint32_t>* indices = nullptr;
      size_t index_count = vertex_count;
      if (p.indices >= 0) {
        indices = &cache.uints(p.indices, who + " indices");
        index_count = indices->size();
        const auto bad = std::find_if(indices->begin(), indices->end(),
                                      [&](uint32_t i) { return i >= vertex_count; });
        if (bad != indices->end()) {
          ctx.fail(who + ": index " + std::to_string(*bad) + " at position " +
                   std::to_string(bad - indices->begin()) + " is out of range (" +
                   std::to_string(vertex_count) + " vertices)");
        }
      }
      if (p.mode == TINYGLTF_MODE_TRIANGLES && index_count % 3 != 0) {
        ctx.warn(who + " has " + std::to_string(index_count) +
                 " indices, not a multiple of 3; the last ones are ignored");
      }

      const size_t tris = triangle_count(p.mode, index_count);
      out.file_triangles += tris;
      if (mesh.positions.size() + vertex_count > kMaxMeshVertices ||
          mesh.triangles.size() + tris > kMaxMeshTriangles) {
        ctx.fail("mesh " + std::to_string(mi) + " has more than 2^31 vertices or triangles");
      }
      // The merged mesh copies every vertex (all attributes a mesh can have,
      // counted for every vertex because one primitive with an attribute
      // gives it to all) and triangle: one accessor shared by many
      // primitives must not multiply into unbounded memory.
      constexpr uint64_t kVertexBytes =
          sizeof(glm::vec3) * 2 + sizeof(glm::vec4) + sizeof(glm::vec2) * 2;
      constexpr uint64_t kTriangleBytes = sizeof(glm::uvec3) + sizeof(uint32_t);
      ctx.charge(Budget::kGeometryBytes,
                 uint64_t(vertex_count) * kVertexBytes + uint64_t(tris) * kTriangleBytes,
                 who + " (" + std::to_string(vertex_count) + " vertices, " + std::to_string(tris) +
                     " triangles)");
      const std::vector<float>& positions = cache.floats(pos, who + " POSITION");

      Part part;
      part.first_vertex = mesh.positions.size();
      part.vertex_count = vertex_count;
      part.first_triangle = mesh.triangles.size();
      part.normals = nrm >= 0;
      const size_t before = part.first_vertex;
      mesh.positions.resize(before + vertex_count);
      std::memcpy(&mesh.positions[before], positions.data(), vertex_count * sizeof(glm::vec3));
      append_attribute(mesh.normals, has_normals, before,
                       nrm >= 0 ? &cache.floats(nrm, who + " NORMAL") : nullptr, vertex_count,
                       glm::vec3(0.0f));
      // Zero xyz marks "no tangent here" for primitives that lack them.
      append_attribute(mesh.tangents, has_tangents, before,
                       tan >= 0 ? &cache.floats(tan, who + " TANGENT") : nullptr, vertex_count,
                       glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
      append_attribute(mesh.uv0, has_uv0, before,
                       uv0 >= 0 ? &cache.floats(uv0, who + " TEXCOORD_0") : nullptr, vertex_count,
                       glm::vec2(0.0f));
      append_attribute(mesh.uv1, has_uv1, before,
                       uv1 >= 0 ? &cache.floats(uv1, who + " TEXCOORD_1") : nullptr, vertex_count,
                       glm::vec2(0.0f));

      auto index = [&](size_t i) {
        return uint32_t(before) + (indices ? (*indices)[i] : uint32_t(i));
      };
      mesh.triangles.reserve(mesh.triangles.size() + tris);
      for (size_t t = 0; t < tris; ++t) {
        glm::uvec3 tri;
        if (p.mode == TINYGLTF_MODE_TRIANGLES) {
          tri = {index(3 * t), index(3 * t + 1), index(3 * t + 2)};
        } else if (p.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
          // Every other strip triangle is flipped to keep a consistent winding.
          tri = t % 2 == 0 ? glm::uvec3(index(t), index(t + 1), index(t + 2))
                           : glm::uvec3(index(t), index(t + 2), index(t + 1));
        } else {
          tri = {index(t + 1), index(t + 2), index(0)};  // fan, as the spec orders it
        }
        // Repeated vertices (common in strips used as restarts) add nothing.
        if (tri.x == tri.y || tri.y == tri.z || tri.x == tri.z) {
          ++out.dropped_degenerate;
          continue;
        }
        mesh.triangles.push_back(tri);
        mesh.triangle_materials.push_back(material);
      }
      part.triangle_count = mesh.triangles.size() - part.first_triangle;
      if (p.material < 0) out.uses_default_material[mi] = true;
      parts.push_back(part);
    }
    if (has_normals) {
      for (const Part& part : parts) {
        if (!part.normals) fill_face_normals(mesh, part);
      }
    }
  }
  return out;
}

}  // namespace tandem::gltf
