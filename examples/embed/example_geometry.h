// Meshes for the examples, as a game would hand its own arrays to
// Tandem: quads and cubes with normals and uvs.
#pragma once

#include <tandem/tandem.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace embed_example {

// The arrays of one mesh (positions, normals, uvs), alive while add_mesh copies them.
struct Geometry {
  std::vector<float> positions, normals, uvs;
  std::vector<uint32_t> indices;

  // The quad c, c+u, c+u+v, c+v facing along u x v, its uvs 0..uv_scale.
  void add_quad(const float c[3], const float u[3], const float v[3], float uv_scale = 1.0f) {
    const float n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0]};
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const uint32_t base = uint32_t(positions.size() / 3);
    const float cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
    for (int k = 0; k < 4; ++k) {
      for (int i = 0; i < 3; ++i) {
        positions.push_back(c[i] + cu[k] * u[i] + cv[k] * v[i]);
        normals.push_back(len > 0.0f ? n[i] / len : 0.0f);
      }
      uvs.push_back(cu[k] * uv_scale);
      uvs.push_back(cv[k] * uv_scale);
    }
    for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u})
      indices.push_back(base + i);
  }

  tandem::MeshData data() const {
    tandem::MeshData d;
    d.positions = positions.data();
    d.normals = normals.data();
    d.uvs = uvs.data();
    d.vertex_count = positions.size() / 3;
    d.indices = indices.data();
    d.triangle_count = indices.size() / 3;
    return d;
  }
};

inline Geometry cube(float h) {
  Geometry g;
  const float w = 2.0f * h;
  const float faces[6][3][3] = {
      {{-h, -h, h}, {w, 0, 0}, {0, w, 0}}, {{h, -h, -h}, {-w, 0, 0}, {0, w, 0}},
      {{h, -h, h}, {0, 0, -w}, {0, w, 0}}, {{-h, -h, -h}, {0, 0, w}, {0, w, 0}},
      {{-h, h, h}, {w, 0, 0}, {0, 0, -w}}, {{-h, -h, -h}, {w, 0, 0}, {0, 0, w}},
  };
  for (const auto& f : faces)
    g.add_quad(f[0], f[1], f[2]);
  return g;
}

}  // namespace embed_example
