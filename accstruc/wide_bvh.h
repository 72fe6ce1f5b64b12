// Internal to accstruc/: the wide layout's refit, used by refit_layouts()
// and BlasRefit.
#pragma once

#include <span>

#include "accstruc/bvh_layouts.h"

namespace tandem {

// Re-quantises every wide node bottom-up from the primitives' current boxes,
// keeping the topology and slot assignment. Returns the root's box.
Aabb refit_wide(BvhLayouts& layouts, std::span<const Aabb> prim_boxes, uint32_t parallel_depth);

// Sets a node's origin, exponents and quantised slot boxes from the exact
// boxes of the slots in `used` (bit per slot), as the build does.
void quantize_wide_node(KWideBvhNode& node, const Aabb boxes[kWideBvhWidth], uint32_t used);

}  // namespace tandem
