// Large procedural scenes for stress tests and benchmarks of acceleration
// structures: the same seed always gives the same scene, on every platform.
#pragma once

#include <cstdint>

#include "core/world/scene.h"

namespace tandem {

// A landscape with `approx_triangles` unique triangles (a little more for
// tiny budgets) of very varied
// shape and size: a heightfield terrain, a huge two-triangle ground plane, a
// dense torus, a soup of random triangles (from slivers to large, a few of
// them degenerate), a dozen rock meshes of different resolutions instanced
// hundreds of times with rotations, non-uniform scales and mirroring,
// tufts of long thin "grass" triangles, instanced boxes stretched into
// towers, and alpha-blended foliage cards. Lit by a uniform sky.
Scene make_procedural_scene(uint32_t approx_triangles, uint32_t seed);

}  // namespace tandem
