// Building the light BVH of core/kernel/light_tree.h on the host: the
// lights split by the surface area orientation heuristic (Conty & Kulla
// 2017): a split is good when each side's power, spread of directions and
// box are small.
#pragma once

#include <cstdint>
#include <functional>
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

// What refit_light_tree_paths needs of a tree besides its nodes, per node
// from `base`, its root (entries included, whose values mean nothing), and
// per light the leaf that holds it.
struct LightTreeShape {
  uint32_t base = 0;
  std::vector<glm::vec3> lo, hi;  // the box of each node's lights
  std::vector<uint32_t> parent;   // 0xffffffff: the root or an entry
  std::vector<uint32_t> leaf_of;  // by light index; 0xffffffff: not in the tree
  void resize(size_t node_count) {
    lo.resize(node_count - base, glm::vec3(0.0f));
    hi.resize(node_count - base, glm::vec3(0.0f));
    parent.resize(node_count - base, 0xffffffffu);
  }
};

// Appends the tree over `lights` to `nodes` (its child indices those of the
// whole array: several trees share one), writing each light's trail to
// trails[light] (the caller sizes `trails`); returns its root, or
// 0xffffffff when no light has power. With `shape`, its boxes and parents
// too (resized to the nodes).
uint32_t append_light_tree(std::vector<LightTreeInput> lights, std::vector<KLightTreeNode>& nodes,
                           std::vector<uint64_t>& trails, LightTreeShape* shape = nullptr);

// A light's current LightTreeInput, by its index.
using LightTreeInputOf = std::function<LightTreeInput(uint32_t light)>;

// The bounds, cones and powers of the tree at nodes[root] recomputed from
// its lights as they are now, its shape kept: what a deformed mesh's tree
// pays, O(its nodes), instead of a build.
void refit_light_tree(std::vector<KLightTreeNode>& nodes, uint32_t root,
                      const LightTreeInputOf& input);

// Only the leaves `leaves` (of a tree appended with `shape`) and the nodes
// above them recomputed, each from its children's boxes (kept in `shape`)
// and cones: O(leaves x depth), what a moved instance or light costs. The
// nodes rewritten go to *rewritten.
void refit_light_tree_paths(std::vector<KLightTreeNode>& nodes, LightTreeShape& shape,
                            const std::vector<uint32_t>& leaves, const LightTreeInputOf& input,
                            std::vector<uint32_t>* rewritten);

}  // namespace tandem
