#include "core/world/light_tree_build.h"

#include <algorithm>
#include <cmath>

namespace tandem {

namespace {

constexpr float kPiF = 3.14159265358979f;

// A cone of directions: `axis` within theta_o, plus theta_e beyond.
struct Cone {
  glm::vec3 axis{0.0f, 0.0f, 1.0f};
  float theta_o = 0.0f, theta_e = 0.0f;
  bool empty = true;
};

Cone cone_of(const LightTreeInput& l) {
  return {l.axis, std::acos(std::clamp(l.cos_theta_o, -1.0f, 1.0f)),
          std::acos(std::clamp(l.cos_theta_e, -1.0f, 1.0f)), false};
}

// The smallest cone (of this construction) holding both.
Cone cone_union(const Cone& a, const Cone& b) {
  if (a.empty) return b;
  if (b.empty) return a;
  const float theta_e = std::max(a.theta_e, b.theta_e);
  const float theta_d = std::acos(std::clamp(glm::dot(a.axis, b.axis), -1.0f, 1.0f));
  if (std::min(theta_d + b.theta_o, kPiF) <= a.theta_o) return {a.axis, a.theta_o, theta_e, false};
  if (std::min(theta_d + a.theta_o, kPiF) <= b.theta_o) return {b.axis, b.theta_o, theta_e, false};
  const float theta_o = 0.5f * (a.theta_o + theta_d + b.theta_o);
  const glm::vec3 w = glm::cross(a.axis, b.axis);
  if (theta_o >= kPiF || glm::dot(w, w) < 1e-12f) return {a.axis, kPiF, theta_e, false};
  // a's axis turned towards b's by theta_o - theta_a (Rodrigues, about w).
  const float r = theta_o - a.theta_o;
  const glm::vec3 k = glm::normalize(w);
  const glm::vec3 axis = a.axis * std::cos(r) + glm::cross(k, a.axis) * std::sin(r) +
                         k * glm::dot(k, a.axis) * (1.0f - std::cos(r));
  return {glm::normalize(axis), theta_o, theta_e, false};
}

// The orientation measure of a cone: the solid angle it emits into,
// weighted by the cosine falloff beyond theta_o.
float orientation_measure(const Cone& c) {
  const float theta_w = std::min(c.theta_o + c.theta_e, kPiF);
  const float so = std::sin(c.theta_o), co = std::cos(c.theta_o);
  return 2.0f * kPiF * (1.0f - co) +
         0.5f * kPiF *
             (2.0f * theta_w * so - std::cos(c.theta_o - 2.0f * theta_w) - 2.0f * c.theta_o * so +
              co);
}

struct Group {
  glm::vec3 lo{INFINITY}, hi{-INFINITY};
  Cone cone;
  float power = 0.0f;
  bool two_sided = false;
  void add(const LightTreeInput& l) {
    lo = glm::min(lo, l.lo);
    hi = glm::max(hi, l.hi);
    cone = cone_union(cone, cone_of(l));
    power += l.power;
    two_sided |= l.two_sided;
  }
  void add(const Group& g) {
    if (g.cone.empty) return;
    lo = glm::min(lo, g.lo);
    hi = glm::max(hi, g.hi);
    cone = cone_union(cone, g.cone);
    power += g.power;
    two_sided |= g.two_sided;
  }
  float area() const {
    const glm::vec3 d = glm::max(hi - lo, glm::vec3(0.0f));
    return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
  // The SAOH cost of a side, without the node's own normalisation.
  float cost(float epsilon_area) const {
    return cone.empty ? 0.0f : power * orientation_measure(cone) * (area() + epsilon_area);
  }
};

glm::vec3 centre(const LightTreeInput& l) {
  return 0.5f * (l.lo + l.hi);
}

// A node's cone as the builder has it.
Cone cone_of(const KLightTreeNode& n) {
  return {glm::vec3(n.axis.x, n.axis.y, n.axis.z),
          std::acos(std::clamp(n.cos_theta_o, -1.0f, 1.0f)),
          std::acos(std::clamp(n.cos_theta_e, -1.0f, 1.0f)), false};
}

KLightTreeNode node_of(const Group& g) {
  KLightTreeNode n{};
  const glm::vec3 c = 0.5f * (g.lo + g.hi);
  n.center = make_vec3(c.x, c.y, c.z);
  n.radius = 0.5f * glm::length(g.hi - g.lo);
  n.power = g.power;
  n.axis = make_vec3(g.cone.axis.x, g.cone.axis.y, g.cone.axis.z);
  n.cos_theta_o = std::cos(g.cone.theta_o);
  n.sin_theta_o = std::sin(g.cone.theta_o);
  n.cos_theta_e = std::cos(std::min(g.cone.theta_e, kPiF));
  n.flags = g.two_sided ? kLightTreeTwoSided : 0u;
  return n;
}

// Node `index` rewritten from its group, keeping what places it in the tree.
void rewrite_node(KLightTreeNode& node, const Group& g) {
  KLightTreeNode n = node_of(g);
  n.flags |= node.flags & kLightTreeLeaf;
  n.index = node.index;
  n.count = node.count;
  node = n;
}

// A leaf's group from its lights as they are now (each asked once), its
// entries' shares rewritten.
Group refit_leaf(std::vector<KLightTreeNode>& nodes, uint32_t leaf, const LightTreeInputOf& input) {
  Group g;
  const uint32_t count = nodes[leaf].count;
  if (count <= 1) {
    g.add(input(nodes[leaf].index));
  } else {
    float power[kLightTreeMaxLeafLights];
    for (uint32_t k = 1; k <= count; ++k) {
      const LightTreeInput light = input(nodes[leaf + k].index);
      power[k - 1] = light.power;
      g.add(light);
    }
    for (uint32_t k = 1; k <= count; ++k)
      nodes[leaf + k].power = g.power > 0.0f ? power[k - 1] / g.power : 1.0f / float(count);
  }
  rewrite_node(nodes[leaf], g);
  return g;
}

Group refit_subtree(std::vector<KLightTreeNode>& nodes, uint32_t node,
                    const LightTreeInputOf& input) {
  if (nodes[node].flags & kLightTreeLeaf) return refit_leaf(nodes, node, input);
  Group g = refit_subtree(nodes, node + 1, input);
  g.add(refit_subtree(nodes, nodes[node].index, input));
  rewrite_node(nodes[node], g);
  return g;
}

class Builder {
 public:
  Builder(std::vector<LightTreeInput>& lights, std::vector<KLightTreeNode>& nodes,
          std::vector<uint64_t>& trails, LightTreeShape* shape)
      : lights_(lights), nodes_(nodes), trails_(trails), shape_(shape) {}

  // Lights [begin, end), at `depth` with path `trail`, below `parent`;
  // returns the node.
  uint32_t build(size_t begin, size_t end, uint32_t depth, uint64_t trail, uint32_t parent) {
    Group all;
    for (size_t i = begin; i < end; ++i)
      all.add(lights_[i]);
    const uint32_t index = uint32_t(nodes_.size());
    nodes_.push_back(node_of(all));
    if (shape_) {
      shape_->resize(nodes_.size());
      shape_->lo[index - shape_->base] = all.lo;
      shape_->hi[index - shape_->base] = all.hi;
      shape_->parent[index - shape_->base] = parent;
    }
    if (end - begin == 1) {
      nodes_[index].flags |= kLightTreeLeaf;
      nodes_[index].index = lights_[begin].light;
      nodes_[index].count = 1;
      trails_[lights_[begin].light] = trail;
      if (shape_) shape_->leaf_of[lights_[begin].light] = index;
      return index;
    }
    float split_cost = INFINITY;
    const size_t mid = split(begin, end, all, depth, &split_cost);
    // A few lights that no split tells apart (the SAOH of the two sides is
    // within 1% of the whole's: the triangles of one quad) stay together.
    if (end - begin <= kLightTreeMaxLeafLights &&
        !(split_cost < 0.99f * all.cost(1e-6f * std::max(all.area(), 1e-12f)))) {
      make_leaf(index, begin, end, all, trail);
      return index;
    }
    build(begin, mid, depth + 1, trail, index);
    const uint32_t second = build(mid, end, depth + 1, trail | (uint64_t(1) << depth), index);
    nodes_[index].index = second;
    return index;
  }

 private:
  // Node `index` as a leaf of lights [begin, end), its entries after it,
  // each light's probability within it its share of the power.
  void make_leaf(uint32_t index, size_t begin, size_t end, const Group& all, uint64_t trail) {
    KLightTreeNode& leaf = nodes_[index];
    leaf.flags |= kLightTreeLeaf;
    leaf.count = uint32_t(end - begin);
    leaf.index = lights_[begin].light;
    for (size_t i = begin; i < end; ++i) {
      KLightTreeNode entry{};
      entry.index = lights_[i].light;
      entry.power = lights_[i].power / all.power;
      nodes_.push_back(entry);
      trails_[lights_[i].light] = trail;
      if (shape_) shape_->leaf_of[lights_[i].light] = index;
    }
    if (shape_) shape_->resize(nodes_.size());
  }

  // Where [begin, end) splits: the cheapest of 12 buckets on each axis by
  // the SAOH (its cost in *best), or (deep in the tree, or when every
  // light sits at one centre: *best left infinite) the median of the widest
  // axis, which keeps every trail within 64 levels.
  size_t split(size_t begin, size_t end, const Group& all, uint32_t depth, float* best) {
    glm::vec3 clo(INFINITY), chi(-INFINITY);
    for (size_t i = begin; i < end; ++i) {
      clo = glm::min(clo, centre(lights_[i]));
      chi = glm::max(chi, centre(lights_[i]));
    }
    const glm::vec3 extent = chi - clo;
    const int widest =
        extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const auto by_axis = [&](int axis) {
      return [axis](const LightTreeInput& a, const LightTreeInput& b) {
        return centre(a)[axis] < centre(b)[axis];
      };
    };
    const auto median_split = [&] {
      const size_t median = begin + (end - begin) / 2;
      std::nth_element(lights_.begin() + long(begin), lights_.begin() + long(median),
                       lights_.begin() + long(end), by_axis(widest));
      return median;
    };
    if (depth >= 40 || !(extent[widest] > 0.0f)) return median_split();
    constexpr int kBuckets = 12;
    const float epsilon_area = 1e-6f * std::max(all.area(), 1e-12f);
    float best_cost = INFINITY;
    int best_axis = -1, best_bucket = 0;
    for (int axis = 0; axis < 3; ++axis) {
      if (!(extent[axis] > 0.0f)) continue;
      Group buckets[kBuckets];
      for (size_t i = begin; i < end; ++i)
        buckets[bucket_of(lights_[i], axis, clo, extent, kBuckets)].add(lights_[i]);
      // Long thin boxes split across their length: the regularisation of
      // Conty & Kulla (the widest extent over this axis's).
      const float kr = extent[widest] / extent[axis];
      // Each side's group by one sweep from each end (22 unions, not 132):
      // the build is what a moving emissive instance pays every frame.
      Group right_of[kBuckets];  // right_of[b]: buckets b..11
      right_of[kBuckets - 1] = buckets[kBuckets - 1];
      for (int b = kBuckets - 2; b >= 0; --b) {
        right_of[b] = buckets[b];
        right_of[b].add(right_of[b + 1]);
      }
      Group left;
      for (int b = 0; b + 1 < kBuckets; ++b) {
        left.add(buckets[b]);
        const Group& right = right_of[b + 1];
        if (left.cone.empty || right.cone.empty) continue;
        const float cost = kr * (left.cost(epsilon_area) + right.cost(epsilon_area));
        if (cost < best_cost) best_cost = cost, best_axis = axis, best_bucket = b;
      }
    }
    if (best_axis < 0) return median_split();
    *best = best_cost;
    const auto mid = std::partition(
        lights_.begin() + long(begin), lights_.begin() + long(end), [&](const LightTreeInput& l) {
          return bucket_of(l, best_axis, clo, extent, kBuckets) <= best_bucket;
        });
    const size_t m = size_t(mid - lights_.begin());
    return m == begin || m == end ? median_split() : m;
  }

  static int bucket_of(const LightTreeInput& l, int axis, glm::vec3 clo, glm::vec3 extent,
                       int buckets) {
    const int b = int(float(buckets) * (centre(l)[axis] - clo[axis]) / extent[axis]);
    return std::clamp(b, 0, buckets - 1);
  }

  std::vector<LightTreeInput>& lights_;
  std::vector<KLightTreeNode>& nodes_;
  std::vector<uint64_t>& trails_;
  LightTreeShape* shape_;
};

}  // namespace

uint32_t append_light_tree(std::vector<LightTreeInput> lights, std::vector<KLightTreeNode>& nodes,
                           std::vector<uint64_t>& trails, LightTreeShape* shape) {
  lights.erase(std::remove_if(lights.begin(), lights.end(),
                              [&](const LightTreeInput& l) {
                                return !(l.power > 0.0f) || !std::isfinite(l.power) ||
                                       l.light >= trails.size();
                              }),
               lights.end());
  if (shape) {
    *shape = LightTreeShape{};
    shape->base = uint32_t(nodes.size());
    shape->leaf_of.assign(trails.size(), 0xffffffffu);
  }
  if (lights.empty()) return 0xffffffffu;
  nodes.reserve(nodes.size() + 2 * lights.size());
  return Builder(lights, nodes, trails, shape).build(0, lights.size(), 0, 0, 0xffffffffu);
}

LightTree build_light_tree(std::vector<LightTreeInput> lights, uint32_t light_count) {
  LightTree tree;
  tree.trails.assign(light_count, 0);
  append_light_tree(std::move(lights), tree.nodes, tree.trails);
  return tree;
}

void refit_light_tree(std::vector<KLightTreeNode>& nodes, uint32_t root,
                      const LightTreeInputOf& input) {
  refit_subtree(nodes, root, input);
}

void refit_light_tree_paths(std::vector<KLightTreeNode>& nodes, LightTreeShape& shape,
                            const std::vector<uint32_t>& leaves, const LightTreeInputOf& input,
                            std::vector<uint32_t>* rewritten) {
  std::vector<uint32_t> above;
  for (uint32_t leaf : leaves) {
    const Group g = refit_leaf(nodes, leaf, input);
    shape.lo[leaf - shape.base] = g.lo;
    shape.hi[leaf - shape.base] = g.hi;
    rewritten->push_back(leaf);
    if (shape.parent[leaf - shape.base] != 0xffffffffu)
      above.push_back(shape.parent[leaf - shape.base]);
  }
  // Level by level from the deepest: a parent's index is below its
  // children's (depth first), so the largest pending index has none of its
  // descendants pending; each node is rewritten once.
  std::sort(above.begin(), above.end());
  above.erase(std::unique(above.begin(), above.end()), above.end());
  while (!above.empty()) {
    const uint32_t node = above.back();
    above.pop_back();
    Group g;
    for (const uint32_t child : {node + 1, nodes[node].index}) {
      Group c;
      c.lo = shape.lo[child - shape.base];
      c.hi = shape.hi[child - shape.base];
      c.cone = cone_of(nodes[child]);
      c.power = nodes[child].power;
      c.two_sided = (nodes[child].flags & kLightTreeTwoSided) != 0;
      g.add(c);
    }
    rewrite_node(nodes[node], g);
    shape.lo[node - shape.base] = g.lo;
    shape.hi[node - shape.base] = g.hi;
    rewritten->push_back(node);
    const uint32_t parent = shape.parent[node - shape.base];
    if (parent != 0xffffffffu) {
      // Keep `above` sorted and unique.
      const auto at = std::lower_bound(above.begin(), above.end(), parent);
      if (at == above.end() || *at != parent) above.insert(at, parent);
    }
  }
}

}  // namespace tandem
