// A light BVH (Conty & Kulla 2017; Estevez & Kulla 2018): lights grouped by
// position and orientation, each node bounding its lights' positions (a
// box), their emission directions (a cone: axis, spread theta_o, and the
// angle theta_e beyond it that they still emit into) and their power. A
// shading point descends from the root choosing a child with probability
// proportional to a conservative estimate of the light it receives from
// it (power over distance squared, zero when every light faces away), so a
// far, dim or turned-away light is seldom chosen; the probability of any
// given light is the product of the choices along its path (its trail),
// which light_tree_pmf recomputes for multiple importance sampling.
//
// Written once for every backend: the choices are the same bits on the
// CPU and the GPU for the same point and random number.
#pragma once

#include "core/kernel/math.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

enum KLightTreeFlags : uint32_t {
  kLightTreeLeaf = 1u << 0,      // `index` is a light, not a child
  kLightTreeTwoSided = 1u << 1,  // emits on both sides of the cone's axis
};

// A leaf of several lights (`count` > 1: lights that sit and face together,
// the two triangles of a quad, where a split would not tell them apart)
// is followed by `count` entries, each a node whose `index` is a light and
// `power` its probability within the leaf (by power): the walk ends a
// level or more earlier, and the light is chosen by a scan.
constexpr uint32_t kLightTreeMaxLeafLights = 4;

// A node in depth-first order: an inner node's first child follows it,
// its second child is at `index` (of the whole array: several trees share
// one). Where its lights are is kept as the
// sphere around their box, and the cone's sine beside its cosine: what
// light_tree_importance reads, with no square root for either.
struct KLightTreeNode {
  Vec3 center;        // of the lights' box
  float power;        // summed over the node's lights (> 0: zero-power lights are left out)
  Vec3 axis;          // unit
  float cos_theta_o;  // cone spread around `axis`
  float sin_theta_o;
  float cos_theta_e;  // emission beyond the spread (pi/2 for a surface)
  float radius;       // half the box's diagonal
  uint32_t index;     // second child, or the light (a leaf of one)
  uint32_t flags;
  uint32_t count;  // a leaf's lights (its entries follow it when more than one)
  uint32_t pad[2];
};
static_assert(sizeof(KLightTreeNode) == 64, "GPU layout");

// cos(max(0, a - b)) from the cosines and sines of a and b (in [0, pi]).
TANDEM_HD_INLINE float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  if (cos_a > cos_b) return 1.0f;  // a < b
  return cos_a * cos_b + sin_a * sin_b;
}
// sin(max(0, a - b)), as above.
TANDEM_HD_INLINE float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  if (cos_a > cos_b) return 0.0f;
  return sin_a * cos_b - cos_a * sin_b;
}

// How much light a node may send to point p (with `n` the unit normal of
// the side of the surface there that scatters light, or zero for a surface
// that receives from every side: glass, a volume): power / d^2 times the
// cosine of the smallest angle between the node's emission cone and the
// direction to p, and times the cosine at the receiver, each widened by the
// angle the node's bounding sphere covers seen from p; zero when no light of
// the node can reach p's front.
TANDEM_HD float light_tree_importance(const KLightTreeNode& node, Vec3 p, Vec3 n) {
  const Vec3 to_p = p - node.center;
  const float dist2 = length_sq(to_p);
  // The distance clamped by the sphere's radius: inside or next to the
  // node the bound must not explode.
  const float d2 = max_f(dist2, node.radius);
  const float inv_len = dist2 > 0.0f ? 1.0f / sqrtf(dist2) : 0.0f;
  const Vec3 wi = dist2 > 0.0f ? to_p * inv_len : make_vec3(0.0f, 0.0f, 1.0f);
  float cos_w = dot(node.axis, wi);
  if (node.flags & kLightTreeTwoSided) cos_w = fabsf(cos_w);
  const float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
  // The angle the sphere covers from p (everything when p is inside it).
  float cos_b = -1.0f, sin_b = 0.0f;
  if (dist2 > node.radius * node.radius) {
    sin_b = node.radius * inv_len;
    cos_b = safe_sqrt(1.0f - sin_b * sin_b);
  }
  // theta_w - theta_o, then less theta_b, each clamped at 0.
  const float cos_x = cos_sub_clamped(sin_w, cos_w, node.sin_theta_o, node.cos_theta_o);
  const float sin_x = sin_sub_clamped(sin_w, cos_w, node.sin_theta_o, node.cos_theta_o);
  const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  // Strictly outside: a spot's cone has theta_e 0, and a point inside it
  // (cos_p 1) is lit.
  if (cos_p < node.cos_theta_e) return 0.0f;
  float importance = node.power * cos_p / d2;
  if (length_sq(n) > 0.0f) {
    // The receiver's cosine towards the node, cos(max(0, theta_i -
    // theta_b)): below zero (no light) when the whole sphere is behind it.
    const float cos_i = -dot(wi, n);
    const float sin_i = safe_sqrt(1.0f - cos_i * cos_i);
    importance *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
  }
  return max_f(importance, 0.0f);
}

// The probability of the second child of inner node `node` at p, from the
// importances of both; -1 when neither child can light p.
TANDEM_HD float light_tree_second_child_probability(const KLightTreeNode* nodes, uint32_t node,
                                                    Vec3 p, Vec3 n) {
  const float first = light_tree_importance(nodes[node + 1], p, n);
  const float second = light_tree_importance(nodes[nodes[node].index], p, n);
  const float sum = first + second;
  if (!(sum > 0.0f)) return -1.0f;
  return second / sum;
}

// Chooses a light of the tree at nodes[root] for point p (normal n, or
// zero) with one uniform number u in [0, 1): its index, in *pmf the
// probability of that choice, and in *u_rest what is left of u, uniform in
// [0, 1) again for whatever chooses next (an instance's triangle). Returns
// 0xffffffff (with *pmf 0) when a branch it took holds no light that can
// reach p.
TANDEM_HD uint32_t light_tree_sample_at(const KLightTreeNode* nodes, uint32_t root, Vec3 p, Vec3 n,
                                        float u, float* pmf, float* u_rest) {
  *pmf = 0.0f;
  // The root's own importance is not asked: where it is zero so are its
  // children's (no light then), and a lone light that cannot reach p gives
  // a sample of no light, as its own test finds.
  float prob = 1.0f;
  uint32_t node = root;
  while (!(nodes[node].flags & kLightTreeLeaf)) {
    const float second = light_tree_second_child_probability(nodes, node, p, n);
    if (second < 0.0f) return 0xffffffffu;
    if (u < 1.0f - second) {
      u = min_f(u / (1.0f - second), 0x1.fffffep-1f);
      prob *= 1.0f - second;
      node = node + 1;
    } else {
      u = min_f((u - (1.0f - second)) / second, 0x1.fffffep-1f);
      prob *= second;
      node = nodes[node].index;
    }
  }
  const KLightTreeNode& leaf = nodes[node];
  if (leaf.count <= 1) {
    *pmf = prob;
    *u_rest = u;
    return leaf.index;
  }
  // By power among the leaf's lights; the last takes what rounding left.
  uint32_t entry = node + 1;
  for (uint32_t k = 1; k < leaf.count; ++k, ++entry) {
    if (u < nodes[entry].power) break;
    u -= nodes[entry].power;
  }
  *pmf = prob * nodes[entry].power;
  *u_rest = min_f(u / nodes[entry].power, 0x1.fffffep-1f);
  return nodes[entry].index;
}

// light_tree_sample_at for a tree of `node_count` nodes rooted at 0 (none:
// no light).
TANDEM_HD uint32_t light_tree_sample(const KLightTreeNode* nodes, uint32_t node_count, Vec3 p,
                                     Vec3 n, float u, float* pmf) {
  *pmf = 0.0f;
  float u_rest;
  return node_count == 0 ? 0xffffffffu : light_tree_sample_at(nodes, 0, p, n, u, pmf, &u_rest);
}

// The probability light_tree_sample_at from `root` chooses light `light`,
// whose trail is `trail` (bit k: the second child at depth k), at p: the
// same products.
TANDEM_HD float light_tree_pmf_at(const KLightTreeNode* nodes, uint32_t root, uint64_t trail,
                                  uint32_t light, Vec3 p, Vec3 n) {
  float prob = 1.0f;
  uint32_t node = root;
  while (!(nodes[node].flags & kLightTreeLeaf)) {
    const float second = light_tree_second_child_probability(nodes, node, p, n);
    if (second < 0.0f) return 0.0f;
    if (trail & 1u) {
      prob *= second;
      node = nodes[node].index;
    } else {
      prob *= 1.0f - second;
      node = node + 1;
    }
    trail >>= 1;
  }
  const KLightTreeNode& leaf = nodes[node];
  if (leaf.count <= 1) return leaf.index == light ? prob : 0.0f;
  for (uint32_t k = 0; k < leaf.count; ++k) {
    if (nodes[node + 1 + k].index == light) return prob * nodes[node + 1 + k].power;
  }
  return 0.0f;
}

TANDEM_HD float light_tree_pmf(const KLightTreeNode* nodes, uint32_t node_count, uint64_t trail,
                               uint32_t light, Vec3 p, Vec3 n) {
  return node_count == 0 ? 0.0f : light_tree_pmf_at(nodes, 0, trail, light, p, n);
}

TANDEM_KERNEL_END
}  // namespace tandem
