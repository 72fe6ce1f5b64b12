#include "scenes/mesh_deformer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace tandem {

JointMatrix joint_matrix(const glm::mat4& a) {
  JointMatrix j;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      j.m[4 * r + c] = a[c][r];  // glm is column-major
  }
  return j;
}

glm::mat4 to_mat4(const JointMatrix& j) {
  glm::mat4 a(1.0f);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      a[c][r] = j.m[4 * r + c];
  }
  return a;
}

namespace {

// Vertices per task: large enough that a task is a few microseconds of
// work, small enough that two cores balance on a 10 k vertex mesh.
constexpr size_t kBlock = 2048;

// Unit `v`, or `v` unchanged when it is (nearly) zero: a zero tangent marks
// "no tangent here" and must stay zero; a collapsed normal keeps its input.
inline glm::vec3 normalised_or_kept(const glm::vec3& v, const glm::vec3& fallback) {
  const float len2 = glm::dot(v, v);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return fallback;
  return v * (1.0f / std::sqrt(len2));
}

struct ActiveTarget {
  uint32_t index;
  float weight;
};

}  // namespace

void deform_mesh(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh& out) {
  const size_t vertices = d.vertex_count();
  if (out.positions.size() != vertices) return;  // not the mesh it was made for
  const bool normals = !d.base_normals.empty() && out.normals.size() == vertices;
  const bool tangents = !d.base_tangents.empty() && out.tangents.size() == vertices;
  // Only targets with a non-zero weight cost anything per vertex.
  std::vector<ActiveTarget> active;
  if (morph_weights != nullptr) {
    for (uint32_t k = 0; k < d.targets; ++k) {
      if (morph_weights[k] != 0.0f && std::isfinite(morph_weights[k]))
        active.push_back({k, morph_weights[k]});
    }
  }
  const bool morph_p = !d.position_deltas.empty(), morph_n = normals && !d.normal_deltas.empty(),
             morph_t = tangents && !d.tangent_deltas.empty();
  const bool skinned = d.skinned() && palette != nullptr;
  const uint32_t influences = d.influences;

  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, vertices, kBlock),
      [&](const tbb::blocked_range<size_t>& range) {
        for (size_t v = range.begin(); v != range.end(); ++v) {
          glm::vec3 p = d.base_positions[v];
          glm::vec3 n = normals ? d.base_normals[v] : glm::vec3(0.0f);
          glm::vec4 t = tangents ? d.base_tangents[v] : glm::vec4(0.0f);
          for (const ActiveTarget& a : active) {
            const size_t at = size_t(a.index) * vertices + v;
            if (morph_p) p += a.weight * d.position_deltas[at];
            if (morph_n) n += a.weight * d.normal_deltas[at];
            if (morph_t) t += glm::vec4(a.weight * d.tangent_deltas[at], 0.0f);
          }
          if (!skinned) {
            out.positions[v] = p;
            if (normals) out.normals[v] = active.empty() ? n : normalised_or_kept(n, n);
            if (tangents) {
              const glm::vec3 tx(t);
              out.tangents[v] = glm::vec4(active.empty() ? tx : normalised_or_kept(tx, tx), t.w);
            }
            continue;
          }
          // The blended 3x4 matrix: a weighted sum of the palette entries.
          float m[12] = {};
          const uint16_t* joint = &d.joints[v * influences];
          const float* weight = &d.weights[v * influences];
          for (uint32_t i = 0; i < influences; ++i) {
            const float w = weight[i];
            if (w == 0.0f) continue;
            const float* pm = palette[joint[i]].m;
            for (int c = 0; c < 12; ++c)
              m[c] += w * pm[c];
          }
          out.positions[v] = {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3],
                              m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                              m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
          const glm::vec3 c0(m[0], m[4], m[8]), c1(m[1], m[5], m[9]), c2(m[2], m[6], m[10]);
          if (normals) {
            // Cofactor matrix (columns c1 x c2, c2 x c0, c0 x c1) = det * A^-T.
            const glm::vec3 k0 = glm::cross(c1, c2), k1 = glm::cross(c2, c0),
                            k2 = glm::cross(c0, c1);
            const float det = glm::dot(c0, k0);
            const glm::vec3 sn = (det < 0.0f ? -1.0f : 1.0f) * (n.x * k0 + n.y * k1 + n.z * k2);
            out.normals[v] = normalised_or_kept(sn, normalised_or_kept(n, n));
          }
          if (tangents) {
            const glm::vec3 st = t.x * c0 + t.y * c1 + t.z * c2;
            const glm::vec3 tx(t);
            out.tangents[v] = glm::vec4(normalised_or_kept(st, tx), t.w);
          }
        }
      });
}

void deform_scene_mesh(const MeshDeformation& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene) {
  if (d.mesh >= scene.meshes().size()) return;
  deform_mesh(d, palette, morph_weights, scene.edit_mesh_vertices(d.mesh));
}

}  // namespace tandem
