// A synthetic deforming mesh for tests and benchmarks of the per-frame
// deformation path (Scene::edit_mesh_vertices -> vertex-range deltas ->
// BLAS refit): a square grid in the xz plane carrying a travelling sine
// wave, whose vertices move every frame while its topology stays.
#pragma once

#include <cstdint>

#include "core/world/scene.h"

namespace tandem {

struct WaveGrid {
  uint32_t cells = 64;      // grid cells per side: (cells + 1)^2 vertices, 2 cells^2 triangles
  float size = 4.0f;        // side length, centred on the origin
  float amplitude = 0.05f;  // wave height, world units
  float wavelength = 1.0f;  // world units, along x + z/2
  uint32_t vertex_count() const { return (cells + 1) * (cells + 1); }
};

// The grid at time 0, with normals and uv0, one material (index `material`).
Mesh make_wave_grid(const WaveGrid& g, uint32_t material = 0);

// Sets positions and normals of vertices [first, first + count) of a mesh
// made by make_wave_grid(g) to the wave at `time` (in wavelengths travelled),
// in parallel. Only y and the normals change; x and z stay on the grid.
void deform_wave_grid(Mesh& m, const WaveGrid& g, float time, uint32_t first, uint32_t count);
inline void deform_wave_grid(Mesh& m, const WaveGrid& g, float time) {
  deform_wave_grid(m, g, time, 0, g.vertex_count());
}

}  // namespace tandem
