// BlasRefit's index of a BLAS, made once after its build (blas_refit.h):
// the leaf entries' vertex indices, the tasks, the wide slots' sources and
// each leaf's distinct vertices. The per-frame refit is blas_refit.cpp.
#include "accstruc/blas_refit.h"

#include <algorithm>
#include <functional>
#include <utility>

#include "accstruc/blas_refit_entries.h"
#include "accstruc/wide_bvh.h"

namespace tandem {

using namespace blas_refit_entries;

namespace {

// Binary nodes per task at most: a task's nodes (64 bytes each), leaf
// triangles and vertices stay within a core's L2 while it sweeps them, and a
// million-triangle mesh is a few hundred tasks for two cores to share.
constexpr uint32_t kTaskNodes = 4096;

}  // namespace

void BlasRefit::clear() {
  indexed_ = false;
  vertex_count_ = triangle_count_ = 0;
  leaf_tris_.clear();
  leaf_verts_.clear();
  leaf_sizes_.clear();
  vertex_lists_ = false;
  non_members_.clear();
  tasks_.clear();
  top_.clear();
  anchored_.clear();
  wide_deferred_.clear();
  wide_src_.clear();
}

bool BlasRefit::index(const BvhLayouts& l, const MeshGeometry& g) {
  clear();
  const uint32_t n = uint32_t(l.nodes.size()), prims = uint32_t(l.prims.size());
  const uint32_t wn = uint32_t(l.wide_nodes.size());
  if (n == 0 || wn == 0 || l.wide_prims.size() != prims || n >= (1u << 29) || prims >= (1u << 30) ||
      g.triangle_count >= kLastOfLeaf) {
    return false;
  }
  // Leaf entries: each triangle once, with vertices in range.
  std::vector<uint32_t> pos(g.triangle_count, kNone);  // triangle -> leaf entry
  leaf_tris_.resize(size_t(kEntryWords) * prims);
  for (uint32_t e = 0; e < prims; ++e) {
    const uint32_t t = l.prims[e];
    if (t >= g.triangle_count || pos[t] != kNone) return false;
    pos[t] = e;
    const KTriangle& tri = g.triangles[t];
    if (tri.v0 >= g.vertex_count || tri.v1 >= g.vertex_count || tri.v2 >= g.vertex_count)
      return false;
    leaf_tris_[kEntryWords * size_t(e)] = tri.v0;
    leaf_tris_[kEntryWords * size_t(e) + 1] = tri.v1;
    leaf_tris_[kEntryWords * size_t(e) + 2] = tri.v2;
    leaf_tris_[kEntryWords * size_t(e) + 3] = t;  // the record's p0.w
  }
  for (uint32_t t = 0; t < g.triangle_count; ++t) {
    if (pos[t] == kNone) non_members_.push_back(t);
  }

  // Binary node children (x = 2 * node + c): their leaf-entry ranges, which
  // must be contiguous for a subtree, parents, sizes (preorder: a subtree is
  // the node range [i, i + size)).
  std::vector<uint32_t> rbeg(2 * size_t(n)), rend(2 * size_t(n)), parent(n, kNone), size(n, 1);
  std::vector<uint32_t> leaf_at(prims, kNone);
  for (uint32_t i = n; i-- > 0;) {
    const KBvhNode& node = l.nodes[i];
    uint32_t next = i + 1;
    for (uint32_t c = 0; c < 2; ++c) {
      const uint32_t x = 2 * i + c, ref = node.child[c];
      if (ref & kBvhLeafFlag) {
        const uint32_t first = ref & ~kBvhLeafFlag, count = node.count[c];
        if (uint64_t(first) + count > prims) return false;
        rbeg[x] = first;
        rend[x] = first + count;
        if (count > 0) leaf_tris_[kEntryWords * size_t(first + count - 1) + 3] |= kLastOfLeaf;
        for (uint32_t e = first; e < first + count; ++e) {
          if (leaf_at[e] != kNone) return false;
          leaf_at[e] = x;
        }
      } else {
        if (ref != next || ref >= n || parent[ref] != kNone) return false;
        parent[ref] = x;
        if (rend[2 * ref] != rbeg[2 * ref + 1]) return false;
        rbeg[x] = rbeg[2 * ref];
        rend[x] = rend[2 * ref + 1];
        size[i] += size[ref];
        next += size[ref];
      }
    }
  }
  for (uint32_t i = 1; i < n; ++i) {
    if (parent[i] == kNone) return false;
  }
  for (uint32_t e = 0; e < prims; ++e) {
    if (leaf_at[e] == kNone) return false;
  }

  // Tasks: the largest subtrees of at most kTaskNodes nodes; the nodes above
  // them are refit afterwards, children (larger indices) first.
  std::vector<uint32_t> task_of(n, kNone);
  {
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
      const uint32_t i = stack.back();
      stack.pop_back();
      if (size[i] <= kTaskNodes) {
        tasks_.push_back({i, i + size[i], 0, 0});
        continue;
      }
      top_.push_back(i);
      for (uint32_t c = 0; c < 2; ++c) {
        if (!(l.nodes[i].child[c] & kBvhLeafFlag)) stack.push_back(l.nodes[i].child[c]);
      }
    }
    std::sort(tasks_.begin(), tasks_.end(),
              [](const Task& a, const Task& b) { return a.lo < b.lo; });
    // A subtree's leaf entries are one contiguous range (checked above for
    // every node but the root; an empty child, as a one-triangle tree's
    // root has, holds none): the task's leaf pass walks it front to back.
    for (Task& t : tasks_) {
      uint32_t lo = kNone, hi = 0, total = 0;
      for (uint32_t c = 0; c < 2; ++c) {
        const size_t x = 2 * size_t(t.lo) + c;
        if (rend[x] <= rbeg[x]) continue;
        lo = std::min(lo, rbeg[x]);
        hi = std::max(hi, rend[x]);
        total += rend[x] - rbeg[x];
      }
      if (lo == kNone) lo = hi = 0;
      if (hi - lo != total) return false;
      t.leaf_lo = lo;
      t.leaf_hi = hi;
    }
    std::sort(top_.begin(), top_.end(), std::greater<uint32_t>());
    index_leaf_vertices(l);
    for (uint32_t t = 0; t < tasks_.size(); ++t) {
      for (uint32_t i = tasks_[t].lo; i < tasks_[t].hi; ++i)
        task_of[i] = t;
    }
  }

  // The binary node child whose range is exactly [b, e), or for a leaf
  // slot the leaf entries [b, e) inside one binary leaf.
  const auto source = [&](uint32_t b, uint32_t e, bool leaf_slot) -> uint32_t {
    if (b >= e || e > prims) return kNone;
    uint32_t x = leaf_at[b];
    if (rbeg[x] == b && rend[x] == e) return kSlotNode | x;
    if (rbeg[x] <= b && e <= rend[x])
      return leaf_slot && e - b <= kWideMaxLeafPrims ? kSlotTris | b : kNone;
    for (;;) {
      x = parent[x >> 1];
      if (x == kNone || rbeg[x] > b || rend[x] - rbeg[x] > e - b) return kNone;
      if (rbeg[x] == b && rend[x] == e) return kSlotNode | x;
    }
  };

  // Wide nodes, children (larger indices) first: each slot's source, the
  // node's leaf-entry range, and the task whose sweep computes its sources.
  wide_src_.assign(size_t(kWideBvhWidth) * wn, kSlotEmpty);
  std::vector<uint32_t> wbeg(wn), wend(wn);
  std::vector<std::vector<Anchored>> per_task(tasks_.size());
  for (uint32_t w = wn; w-- > 0;) {
    const KWideBvhNode& node = l.wide_nodes[w];
    uint32_t lo = kNone, hi = 0, total = 0, rank = 0, anchor = kNone, task = kNone;
    bool one_task = true;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t meta = node.meta[s];
      const bool interior = (node.imask >> s) & 1u;
      if (meta == 0) {
        if (interior) return false;
        continue;
      }
      uint32_t b, e;
      if (interior) {
        const uint64_t cw = uint64_t(node.child_base) + rank++;
        if (cw <= w || cw >= wn) return false;
        b = wbeg[cw];
        e = wend[cw];
      } else {
        const uint64_t first = uint64_t(node.prim_base) + (meta & 31u);
        const uint32_t count = wide_leaf_count(meta);
        if (first + count > prims) return false;
        b = pos[l.wide_prims[first]];
        if (b == kNone) return false;
        for (uint32_t j = 1; j < count; ++j) {
          if (pos[l.wide_prims[first + j]] != b + j) return false;
        }
        e = b + count;
      }
      const uint32_t src = source(b, e, !interior);
      if (src == kNone) return false;
      wide_src_[size_t(kWideBvhWidth) * w + s] = src;
      lo = std::min(lo, b);
      hi = std::max(hi, e);
      total += e - b;
      const uint32_t at =
          (src & kSlotKind) == kSlotNode ? (src & kSlotIndex) >> 1 : leaf_at[b] >> 1;
      anchor = std::min(anchor, at);
      if (task == kNone) task = task_of[at];
      one_task = one_task && task_of[at] == task && task != kNone;
    }
    if (lo == kNone || hi - lo != total) return false;
    wbeg[w] = lo;
    wend[w] = hi;
    if (one_task) {
      per_task[task].push_back({anchor, w});
    } else {
      wide_deferred_.push_back(w);
    }
  }
  for (uint32_t t = 0; t < tasks_.size(); ++t) {
    std::vector<Anchored>& a = per_task[t];
    std::sort(a.begin(), a.end(),
              [](const Anchored& x, const Anchored& y) { return x.anchor > y.anchor; });
    tasks_[t].wide_lo = uint32_t(anchored_.size());
    anchored_.insert(anchored_.end(), a.begin(), a.end());
    tasks_[t].wide_hi = uint32_t(anchored_.size());
  }
  vertex_count_ = g.vertex_count;
  triangle_count_ = g.triangle_count;
  indexed_ = true;
  return true;
}

void BlasRefit::index_leaf_vertices(const BvhLayouts& l) {
  // The binary leaves holding triangles, by first entry.
  std::vector<std::pair<uint32_t, uint32_t>> leaves;  // first entry, count
  for (const KBvhNode& node : l.nodes) {
    for (uint32_t c = 0; c < 2; ++c) {
      if ((node.child[c] & kBvhLeafFlag) && node.count[c] > 0) {
        if (node.count[c] > 255) return;
        leaves.push_back({node.child[c] & ~kBvhLeafFlag, node.count[c]});
      }
    }
  }
  std::sort(leaves.begin(), leaves.end());
  leaf_verts_.reserve(2 * leaves.size());
  leaf_sizes_.reserve(leaves.size());
  std::vector<uint32_t> last_use;  // a leaf's vertices, the last used first
  for (Task& t : tasks_) {
    t.leaves_lo = uint32_t(leaf_sizes_.size());
    t.verts_lo = uint32_t(leaf_verts_.size());
    auto k = std::lower_bound(leaves.begin(), leaves.end(), std::make_pair(t.leaf_lo, 0u));
    uint32_t covered = t.leaf_lo;
    for (; k != leaves.end() && k->first < t.leaf_hi; ++k) {
      if (k->first != covered) break;
      covered += k->second;
      last_use.clear();
      for (uint32_t e = k->first + k->second; e-- > k->first;) {
        for (uint32_t j = 3; j-- > 0;) {
          const uint32_t v = leaf_tris_[kEntryWords * size_t(e) + j];
          if (std::find(last_use.begin(), last_use.end(), v) == last_use.end())
            last_use.push_back(v);
        }
      }
      for (size_t j = last_use.size(); j-- > 0;)
        leaf_verts_.push_back(last_use[j]);
      // Repeating the last vertex changes no bit of the box (an equal input
      // met again), and whole groups of four take no branch a vertex.
      const size_t groups = (last_use.size() + 3) / 4;
      leaf_verts_.resize(leaf_verts_.size() + (4 * groups - last_use.size()), last_use[0]);
      leaf_sizes_.push_back({uint8_t(k->second), uint8_t(groups)});
    }
    t.leaves_hi = uint32_t(leaf_sizes_.size());
    if (covered != t.leaf_hi) {  // not the task's leaves end to end
      leaf_verts_.clear();
      leaf_sizes_.clear();
      return;
    }
  }
  vertex_lists_ = true;
}

}  // namespace tandem
