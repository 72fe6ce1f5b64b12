// Binary layout (flatten, refit, validation) and the layout-independent
// parts of bvh_layouts.h. The wide layout lives in wide_bvh.cpp.
#include "accstruc/bvh_layouts.h"

#include "accstruc/wide_bvh.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cstring>
#include <functional>

namespace tandem {

namespace {

// Subtrees at least this large are flattened / refit as separate tasks.
constexpr uint32_t kParallelSubtree = 4096;

class BinaryFlattener {
 public:
  BinaryFlattener(const BuildTree& tree, std::vector<KBvhNode>& out) : tree_(tree), out_(out) {
    // Interior nodes per subtree, to place right subtrees without a
    // sequential pass. Children always have larger indices than parents.
    interior_.assign(tree.nodes.size(), 0);
    for (size_t i = tree.nodes.size(); i-- > 0;) {
      const BuildNode& n = tree.nodes[i];
      if (!n.is_leaf()) interior_[i] = 1 + interior_[n.child[0]] + interior_[n.child[1]];
    }
  }

  void run() {
    const BuildNode& root = tree_.nodes[tree_.root];
    if (root.is_leaf()) {
      // A single leaf still needs a node to hold its box; the second child
      // is empty.
      out_.assign(1, KBvhNode{});
      KBvhNode& n = out_[0];
      set_binary_child_box(n, 0, root.box);
      set_binary_child_box(n, 1, Aabb{});
      n.child[0] = kBvhLeafFlag | root.first;
      n.count[0] = root.count;
      n.child[1] = kBvhLeafFlag;
      n.count[1] = 0;
      return;
    }
    out_.assign(interior_[tree_.root], KBvhNode{});
    flatten(tree_.root, 0);
  }

 private:
  // Depth-first preorder: the left subtree follows its parent directly.
  void flatten(uint32_t build_index, uint32_t out_index) {
    const BuildNode& b = tree_.nodes[build_index];
    KBvhNode& n = out_[out_index];
    uint32_t next = out_index + 1;
    uint32_t child_out[2] = {kInvalidIndex, kInvalidIndex};
    for (uint32_t c = 0; c < 2; ++c) {
      const BuildNode& child = tree_.nodes[b.child[c]];
      set_binary_child_box(n, c, child.box);
      if (child.is_leaf()) {
        n.child[c] = kBvhLeafFlag | child.first;
        n.count[c] = child.count;
      } else {
        child_out[c] = next;
        n.child[c] = next;
        n.count[c] = 0;
        next += interior_[b.child[c]];
      }
    }
    auto go = [&](uint32_t c) {
      if (child_out[c] != kInvalidIndex) flatten(b.child[c], child_out[c]);
    };
    if (b.count >= kParallelSubtree) {
      tbb::parallel_invoke([&] { go(0); }, [&] { go(1); });
    } else {
      go(0);
      go(1);
    }
  }

  const BuildTree& tree_;
  std::vector<KBvhNode>& out_;
  std::vector<uint32_t> interior_;
};

Aabb leaf_box(std::span<const uint32_t> prims, uint32_t first, uint32_t count,
              std::span<const Aabb> prim_boxes) {
  Aabb b;
  for (uint32_t i = first; i < first + count; ++i) {
    const Aabb& pb = prim_boxes[prims[i]];
    if (aabb_valid(pb)) b.grow(pb);
  }
  return b;
}

// The box of a refit subtree and the sum of its nodes' child-box half areas
// (refit_quality()'s numerator), summed in tree order so the result does not
// depend on how the tasks ran.
struct RefitResult {
  Aabb box;
  double child_area_sum = 0.0;
};

// `parallel_depth` levels below spawn tasks.
RefitResult refit_binary(BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes,
                         uint32_t parallel_depth) {
  KBvhNode& n = l.nodes[index];
  RefitResult r[2];
  auto child = [&](uint32_t c) {
    if (n.child[c] & kBvhLeafFlag) {
      r[c].box = leaf_box(l.prims, n.child[c] & ~kBvhLeafFlag, n.count[c], prim_boxes);
    } else {
      r[c] = refit_binary(l, n.child[c], prim_boxes, parallel_depth ? parallel_depth - 1 : 0);
    }
  };
  if (parallel_depth > 0) {
    tbb::parallel_invoke([&] { child(0); }, [&] { child(1); });
  } else {
    child(0);
    child(1);
  }
  set_binary_child_box(n, 0, r[0].box);
  set_binary_child_box(n, 1, r[1].box);
  RefitResult all;
  all.box = r[0].box;
  all.box.grow(r[1].box);
  all.child_area_sum = double(r[0].box.half_area()) + double(r[1].box.half_area()) +
                       r[0].child_area_sum + r[1].child_area_sum;
  return all;
}

bool validate_binary(const BvhLayouts& l, uint32_t prim_count) {
  const uint32_t n = uint32_t(l.nodes.size());
  if (n == 0) return l.prims.empty();
  for (uint32_t p : l.prims) {
    if (p >= prim_count) return false;
  }
  // Depth of each node; children must come after their parent, so one
  // forward pass sees every parent before its children.
  std::vector<uint8_t> depth(n, 0);
  depth[0] = 1;
  for (uint32_t i = 0; i < n; ++i) {
    const KBvhNode& node = l.nodes[i];
    if (depth[i] == 0) return false;  // unreachable from the root
    for (uint32_t c = 0; c < 2; ++c) {
      if (node.child[c] & kBvhLeafFlag) {
        const uint64_t first = node.child[c] & ~kBvhLeafFlag;
        if (first + node.count[c] > l.prims.size()) return false;
      } else {
        const uint32_t ch = node.child[c];
        if (node.count[c] != 0 || ch <= i || ch >= n || depth[ch] != 0) return false;
        if (depth[i] + 1u >= kBvhStackSize) return false;
        depth[ch] = uint8_t(depth[i] + 1);
      }
    }
  }
  return true;
}

bool validate_wide(const BvhLayouts& l, uint32_t prim_count) {
  const uint32_t n = uint32_t(l.wide_nodes.size());
  if (n == 0) return l.wide_prims.empty();
  for (uint32_t p : l.wide_prims) {
    if (p >= prim_count) return false;
  }
  std::vector<uint8_t> depth(n, 0);
  depth[0] = 1;
  for (uint32_t i = 0; i < n; ++i) {
    const KWideBvhNode& node = l.wide_nodes[i];
    if (depth[i] == 0) return false;
    for (int a = 0; a < 3; ++a) {
      if (node.exponent[a] == 0 || node.exponent[a] == 255) return false;
    }
    uint32_t rank = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t meta = node.meta[s];
      const bool interior = (node.imask >> s) & 1u;
      if (interior) {
        const uint64_t ch = uint64_t(node.child_base) + rank++;
        if (meta != (kWideMetaInterior | (24u + s)) || ch <= i || ch >= n || depth[ch] != 0) {
          return false;
        }
        if (depth[i] + 1u >= kBvhStackSize) return false;
        depth[ch] = uint8_t(depth[i] + 1);
      } else if (meta != 0) {
        const uint32_t unary = meta >> 5, offset = meta & 31u;
        if (unary != 1 && unary != 3 && unary != 7) return false;
        const uint32_t count = unary == 1 ? 1 : (unary == 3 ? 2 : 3);
        if (offset + count > 24 ||
            uint64_t(node.prim_base) + offset + count > l.wide_prims.size()) {
          return false;
        }
      }
    }
  }
  return true;
}

}  // namespace

void flatten_binary(const BuildTree& tree, BvhLayouts& out) {
  out.nodes.clear();
  out.prims.clear();
  if (tree.empty()) return;
  BinaryFlattener(tree, out.nodes).run();
  out.prims = tree.prims;
  out.depth = tree.depth;
  out.bounds = tree.nodes[tree.root].box;
}

BvhLayouts make_layouts(const BuildTree& tree, std::span<const Aabb> prim_boxes,
                        uint32_t max_wide_leaf_prims, float traversal_cost,
                        float intersection_cost) {
  BvhLayouts l;
  if (tree.empty()) return l;
  tbb::parallel_invoke([&] { flatten_binary(tree, l); },
                       [&] {
                         collapse_wide(tree, prim_boxes, max_wide_leaf_prims, traversal_cost,
                                       intersection_cost, l);
                       });
  l.sah_cost = sah_cost(tree, traversal_cost, intersection_cost);
  return l;
}

Aabb refit_binary_node(BvhLayouts& l, uint32_t index, std::span<const Aabb> prim_boxes) {
  KBvhNode& n = l.nodes[index];
  Aabb boxes[2];
  for (uint32_t c = 0; c < 2; ++c) {
    if (n.child[c] & kBvhLeafFlag) {
      boxes[c] = leaf_box(l.prims, n.child[c] & ~kBvhLeafFlag, n.count[c], prim_boxes);
    } else {
      // The child's boxes are stored exactly: their union is what a full
      // refit would return for it.
      const KBvhNode& ch = l.nodes[n.child[c]];
      boxes[c] = binary_child_box(ch, 0);
      boxes[c].grow(binary_child_box(ch, 1));
    }
  }
  set_binary_child_box(n, 0, boxes[0]);
  set_binary_child_box(n, 1, boxes[1]);
  Aabb all = boxes[0];
  all.grow(boxes[1]);
  return all;
}

Aabb binary_child_box(const KBvhNode& n, uint32_t c) {
  const Vec4& xy = c == 0 ? n.c0_xy : n.c1_xy;
  const float zlo = c == 0 ? n.c01_z.x : n.c01_z.z, zhi = c == 0 ? n.c01_z.y : n.c01_z.w;
  return Aabb{{xy.x, xy.z, zlo}, {xy.y, xy.w, zhi}};
}

void emit_layout_nodes(const BvhLayouts& l, const LayoutBases& base,
                       std::span<const uint32_t> node_list,
                       std::span<const uint32_t> wide_node_list, KBvhNode* nodes,
                       KWideBvhNode* wide_nodes) {
  for (uint32_t i : node_list) {
    KBvhNode n = l.nodes[i];
    for (uint32_t c = 0; c < 2; ++c) {
      n.child[c] =
          (n.child[c] & kBvhLeafFlag) ? (n.child[c] + base.prim) : (n.child[c] + base.node);
    }
    nodes[i] = n;
  }
  for (uint32_t i : wide_node_list) {
    KWideBvhNode n = l.wide_nodes[i];
    n.child_base += base.wide_node;
    n.prim_base += base.wide_prim;
    wide_nodes[i] = n;
  }
}

double refit_layouts(BvhLayouts& l, std::span<const Aabb> prim_boxes) {
  if (l.empty()) return 0.0;
  // Task-parallel over the top levels of large hierarchies only.
  const uint32_t parallel_depth = l.prims.size() >= 4 * kParallelSubtree ? 6 : 0;
  RefitResult r;
  tbb::parallel_invoke([&] { r = refit_binary(l, 0, prim_boxes, parallel_depth); },
                       [&] { refit_wide(l, prim_boxes, parallel_depth); });
  l.bounds = r.box;
  const double root = r.box.half_area();
  return root > 0.0 ? r.child_area_sum / root : 0.0;
}

double refit_quality(const BvhLayouts& l) {
  const double root = l.bounds.half_area();
  if (l.empty() || !(root > 0.0)) return 0.0;
  const size_t grain = 16384;
  const double sum = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, l.nodes.size(), grain), 0.0,
      [&](const tbb::blocked_range<size_t>& r, double acc) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
          acc += double(binary_child_box(l.nodes[i], 0).half_area()) +
                 double(binary_child_box(l.nodes[i], 1).half_area());
        }
        return acc;
      },
      std::plus<double>());
  return sum / root;
}

bool refit_too_poor(double quality, double built_quality) {
  return quality > kRefitQualityLimit * built_quality;
}

NodeSpans emit_refit_nodes(const BvhLayouts& l, const LayoutBases& base, KBvhNode* nodes,
                           KWideBvhNode* wide_nodes) {
  // Each block writes its nodes and reports the span of those that differ
  // from what the kernel array held; spans join by min/max.
  struct Span {
    uint32_t begin = kInvalidIndex, end = 0;
    void join(const Span& o) {
      begin = std::min(begin, o.begin);
      end = std::max(end, o.end);
    }
  };
  auto emit = [](auto* dst, const auto& src, auto convert) {
    return tbb::parallel_reduce(
        tbb::blocked_range<uint32_t>(0, uint32_t(src.size()), 8192), Span{},
        [&](const tbb::blocked_range<uint32_t>& r, Span s) {
          for (uint32_t i = r.begin(); i < r.end(); ++i) {
            const auto n = convert(src[i]);
            if (std::memcmp(&n, dst + i, sizeof(n)) != 0) {
              dst[i] = n;
              s.begin = std::min(s.begin, i);
              s.end = i + 1;
            }
          }
          return s;
        },
        [](Span a, const Span& b) {
          a.join(b);
          return a;
        });
  };
  const Span bin = emit(nodes, l.nodes, [&](KBvhNode n) {
    for (uint32_t c = 0; c < 2; ++c)
      n.child[c] =
          (n.child[c] & kBvhLeafFlag) ? (n.child[c] + base.prim) : (n.child[c] + base.node);
    return n;
  });
  const Span wide = emit(wide_nodes, l.wide_nodes, [&](KWideBvhNode n) {
    n.child_base += base.wide_node;
    n.prim_base += base.wide_prim;
    return n;
  });
  NodeSpans out;
  if (bin.end > 0) out.nodes = {bin.begin, bin.end};
  if (wide.end > 0) out.wide_nodes = {wide.begin, wide.end};
  return out;
}

bool validate_layouts(const BvhLayouts& l, uint32_t prim_count) {
  if (l.nodes.empty() != l.wide_nodes.empty()) return false;
  if (l.nodes.size() >= kBvhLeafFlag || l.prims.size() >= kBvhLeafFlag) return false;
  return validate_binary(l, prim_count) && validate_wide(l, prim_count);
}

void emit_layouts(const BvhLayouts& l, const LayoutBases& base, KBvhNode* nodes, uint32_t* prims,
                  KWideBvhNode* wide_nodes, uint32_t* wide_prims) {
  const size_t grain = 8192;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, l.nodes.size(), grain), [&](auto r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      KBvhNode n = l.nodes[i];
      for (uint32_t c = 0; c < 2; ++c) {
        n.child[c] =
            (n.child[c] & kBvhLeafFlag) ? (n.child[c] + base.prim) : (n.child[c] + base.node);
      }
      nodes[i] = n;
    }
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, l.wide_nodes.size(), grain), [&](auto r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      KWideBvhNode n = l.wide_nodes[i];
      n.child_base += base.wide_node;
      n.prim_base += base.wide_prim;
      wide_nodes[i] = n;
    }
  });
  std::copy(l.prims.begin(), l.prims.end(), prims);
  std::copy(l.wide_prims.begin(), l.wide_prims.end(), wide_prims);
}

void emit_blas_wide_entries(const BvhLayouts& l, const LayoutBases& base, uint32_t* wide_prims) {
  uint32_t ids = 0;
  for (uint32_t p : l.prims)
    ids = std::max(ids, p + 1);
  std::vector<uint32_t> entry_of(ids, kInvalidIndex);
  for (size_t i = 0; i < l.prims.size(); ++i)
    entry_of[l.prims[i]] = base.prim + uint32_t(i);
  for (size_t j = 0; j < l.wide_prims.size(); ++j) {
    const uint32_t p = l.wide_prims[j];
    // Both layouts list the same triangles; a foreign id (which
    // validate_layouts() does not rule out) gets entry 0's record rather than
    // an index out of range.
    wide_prims[j] = p < ids && entry_of[p] != kInvalidIndex ? entry_of[p] : base.prim;
  }
}

}  // namespace tandem
