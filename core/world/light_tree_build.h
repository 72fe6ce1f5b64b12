// Building the light BVH of core/kernel/light_tree.h on the host: the
// lights split by the surface area orientation heuristic (Conty & Kulla
// 2017): a split is good when each side's power, spread of directions and
// box are small.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/kernel/light_tree.h"

namespace tandem {

// What the tree knows of one light.
struct LightTreeInput {
  glm::vec3 lo{0.0f}, hi{0.0f};      // where it is (a point light: lo == hi)
  glm::vec3 axis{0.0f, 0.0f, 1.0f};  // unit: the middle of the directions it emits into
  float cos_theta_o = -1.0f;         // their spread around `axis` (-1: every direction)
  float cos_theta_e = 0.0f;          // how far beyond that it still emits (0: pi/2, a surface)
  bool two_sided = false;            // also along -axis
  float power = 0.0f;                // lights of no power are left out of the tree
  uint32_t light = 0;                // its index in the light list
};

struct LightTree {
  std::vector<KLightTreeNode> nodes;  // depth first, the root first; empty: no light
  // Per light index: its path from the root (bit k set: the second child at
  // depth k); 0 for a light not in the tree (and for the only one).
  std::vector<uint64_t> trails;
};

// `light_count`: the size of the light list the inputs index into.
LightTree build_light_tree(std::vector<LightTreeInput> lights, uint32_t light_count);

}  // namespace tandem
