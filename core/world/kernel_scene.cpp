#include "core/world/kernel_scene.h"

#include <algorithm>
#include <iterator>

namespace tandem {

// ---------------------------------------------------------------------------
// KernelScene / deltas

KernelData KernelScene::view() const {
  KernelData kd{};
#define TANDEM_FILL_VIEW(T, name) \
  kd.name = name.data();          \
  kd.name##_count = uint32_t(name.size());
  TANDEM_KERNEL_ARRAYS(TANDEM_FILL_VIEW)
#undef TANDEM_FILL_VIEW
  kd.constants = constants;
  kd.bvh = bvh;
  return kd;
}

uint32_t KernelScene::vertex_count() const {
  return positions.empty() ? 0u : uint32_t(positions.size() - 1);
}

size_t KernelScene::byte_size() const {
  size_t bytes = sizeof(constants) + sizeof(bvh);
#define TANDEM_ADD_BYTES(T, name) bytes += name.size() * sizeof(T);
  TANDEM_KERNEL_ARRAYS(TANDEM_ADD_BYTES)
#undef TANDEM_ADD_BYTES
  return bytes;
}

SceneDelta SceneDelta::everything() {
  SceneDelta all;
  all.full = all.constants = all.bvh_constants = true;
#define TANDEM_MARK_REALLOCATED(T, name) all.name.reallocated = true;
  TANDEM_KERNEL_ARRAYS(TANDEM_MARK_REALLOCATED)
#undef TANDEM_MARK_REALLOCATED
  return all;
}

void SceneDelta::merge(const SceneDelta& later) {
#define TANDEM_MERGE_CHANGE(T, name)                             \
  name.reallocated = name.reallocated || later.name.reallocated; \
  later.name.for_each_range([&](uint32_t b, uint32_t e) { name.mark(b, e); });
  TANDEM_KERNEL_ARRAYS(TANDEM_MERGE_CHANGE)
#undef TANDEM_MERGE_CHANGE
  full = full || later.full;
  constants = constants || later.constants;
  bvh_constants = bvh_constants || later.bvh_constants;
  auto add_unique = [](std::vector<uint32_t>& to, const std::vector<uint32_t>& from) {
    for (uint32_t m : from) {
      if (std::find(to.begin(), to.end(), m) == to.end()) to.push_back(m);
    }
  };
  add_unique(meshes_rebuilt, later.meshes_rebuilt);
  add_unique(meshes_refit, later.meshes_refit);
  // Possibly long (every moving body): a sorted merge, not add_unique.
  std::vector<uint32_t> moved;
  std::set_union(instances_moved.begin(), instances_moved.end(), later.instances_moved.begin(),
                 later.instances_moved.end(), std::back_inserter(moved));
  instances_moved = std::move(moved);
}

void ArrayChange::mark(uint32_t b, uint32_t e) {
  if (e <= b) return;
  if (end <= begin) {
    begin = b;
    end = e;
    range_count = 1;
    ranges[0] = {b, e};
    return;
  }
  if (range_count == 0) {  // only a bounding range was set: it is the one range
    range_count = 1;
    ranges[0] = {begin, end};
  }
  begin = std::min(begin, b);
  end = std::max(end, e);
  // Insert in order, absorbing every range that overlaps or touches [b, e).
  Range merged[kMaxRanges + 1];
  uint32_t n = 0;
  bool placed = false;
  for (uint32_t i = 0; i < range_count; ++i) {
    const Range r = ranges[i];
    if (r.end < b) {
      merged[n++] = r;
    } else if (r.begin > e) {
      if (!placed) merged[n++] = {b, e}, placed = true;
      merged[n++] = r;
    } else {
      b = std::min(b, r.begin);
      e = std::max(e, r.end);
    }
  }
  if (!placed) merged[n++] = {b, e};
  if (n > kMaxRanges) {
    uint32_t best = 0;
    for (uint32_t i = 1; i + 1 < n; ++i) {
      if (merged[i + 1].begin - merged[i].end < merged[best + 1].begin - merged[best].end) best = i;
    }
    merged[best].end = merged[best + 1].end;
    for (uint32_t i = best + 1; i + 1 < n; ++i)
      merged[i] = merged[i + 1];
    --n;
  }
  range_count = n;
  std::copy(merged, merged + n, ranges);
}

size_t ArrayChange::element_count() const {
  size_t n = 0;
  for_each_range([&](uint32_t b, uint32_t e) { n += e - b; });
  return n;
}

bool SceneDelta::any() const {
  bool any_array = false;
#define TANDEM_ANY_CHANGE(T, name) any_array = any_array || name.any();
  TANDEM_KERNEL_ARRAYS(TANDEM_ANY_CHANGE)
#undef TANDEM_ANY_CHANGE
  return any_array || full || constants || bvh_constants || !meshes_refit.empty();
}

size_t SceneDelta::bytes(const KernelScene& ks) const {
  size_t total =
      (constants ? sizeof(KernelConstants) : 0) + (bvh_constants ? sizeof(KBvhConstants) : 0);
#define TANDEM_CHANGE_BYTES(T, name)     \
  if (name.reallocated)                  \
    total += ks.name.size() * sizeof(T); \
  else                                   \
    total += name.element_count() * sizeof(T);
  TANDEM_KERNEL_ARRAYS(TANDEM_CHANGE_BYTES)
#undef TANDEM_CHANGE_BYTES
  return total;
}

}  // namespace tandem
