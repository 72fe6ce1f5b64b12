#include "scenes/deforming_grid.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace tandem {

namespace {

constexpr float kTwoPi = 6.28318530718f;

glm::vec3 grid_point(const WaveGrid& g, uint32_t v) {
  const uint32_t row = v / (g.cells + 1), col = v % (g.cells + 1);
  const float step = g.size / float(g.cells);
  return {-0.5f * g.size + step * float(col), 0.0f, -0.5f * g.size + step * float(row)};
}

}  // namespace

Mesh make_wave_grid(const WaveGrid& g, uint32_t material) {
  Mesh m;
  m.name = "wave grid";
  const uint32_t n = g.vertex_count();
  m.positions.resize(n);
  m.normals.resize(n);
  m.uv0.resize(n);
  for (uint32_t v = 0; v < n; ++v) {
    const glm::vec3 p = grid_point(g, v);
    m.uv0[v] = {p.x / g.size + 0.5f, p.z / g.size + 0.5f};
  }
  m.triangles.reserve(size_t(2) * g.cells * g.cells);
  for (uint32_t r = 0; r < g.cells; ++r) {
    for (uint32_t c = 0; c < g.cells; ++c) {
      const uint32_t a = r * (g.cells + 1) + c, b = a + 1, d = a + g.cells + 1, e = d + 1;
      // Counter-clockwise seen from +y, so normals point up.
      m.triangles.push_back({a, d, b});
      m.triangles.push_back({b, d, e});
    }
  }
  m.triangle_materials.assign(m.triangles.size(), material);
  deform_wave_grid(m, g, 0.0f);
  return m;
}

void deform_wave_grid(Mesh& m, const WaveGrid& g, float time, uint32_t first, uint32_t count) {
  const float k = kTwoPi / g.wavelength;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(first, first + count, 16384), [&](auto r) {
    for (uint32_t v = r.begin(); v < r.end(); ++v) {
      glm::vec3 p = grid_point(g, v);
      // Phase along the direction (1, 0.5): the wave crosses the grid's
      // diagonal cells, so boxes change shape, not just height.
      const float phase = k * (p.x + 0.5f * p.z) - kTwoPi * time;
      p.y = g.amplitude * std::sin(phase);
      const float slope = g.amplitude * k * std::cos(phase);  // dy/d(phase direction)
      m.positions[v] = p;
      m.normals[v] = glm::normalize(glm::vec3(-slope, 1.0f, -0.5f * slope));
    }
  });
}

}  // namespace tandem
