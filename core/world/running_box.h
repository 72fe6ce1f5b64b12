// A box grown one position at a time, for the loops that take it while
// they write the positions anyway: the compiler's copy of a mesh
// (compile_meshes.cpp) and the skinning's path without SSE
// (mesh_deformer.cpp). One definition, so the two agree bit for bit.
#pragma once

#include <cmath>
#include <limits>

#include "core/world/scene_bounds.h"

namespace tandem {

// The comparisons are glm::min(lo, p) = (p < lo ? p : lo) and
// glm::max(hi, p) = (hi < p ? p : hi), in vertex_bounds()'s order; plain
// floats so the loop keeps them in registers.
struct RunningBox {
  float lx = std::numeric_limits<float>::infinity(), ly = lx, lz = lx;
  float hx = -lx, hy = hx, hz = hx;
  bool finite = true;
  void add(float x, float y, float z) {
    lx = x < lx ? x : lx;
    ly = y < ly ? y : ly;
    lz = z < lz ? z : lz;
    hx = hx < x ? x : hx;
    hy = hy < y ? y : hy;
    hz = hz < z ? z : hz;
    finite &= std::isfinite(x) & std::isfinite(y) & std::isfinite(z);
  }
  // The SceneBounds of what was added (empty when `any` is false), with
  // positive_zeros() as vertex_bounds() returns it.
  SceneBounds bounds(bool any) const {
    SceneBounds b;
    if (!any) return b;
    b.lo = glm::vec3(lx, ly, lz) + glm::vec3(0.0f);
    b.hi = glm::vec3(hx, hy, hz) + glm::vec3(0.0f);
    b.empty = false;
    return b;
  }
};

}  // namespace tandem
