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
  all.full = all.constants = all.bvh_constants = all.instances_changed = true;
#define TANDEM_MARK_REALLOCATED(T, name) all.name.reallocated = true;
  TANDEM_KERNEL_ARRAYS(TANDEM_MARK_REALLOCATED)
#undef TANDEM_MARK_REALLOCATED
  return all;
}

void SceneDelta::merge(const SceneDelta& later) {
#define TANDEM_MERGE_CHANGE(T, name)                             \
  name.reallocated = name.reallocated || later.name.reallocated; \
  name.mark(later.name.begin, later.name.end);
  TANDEM_KERNEL_ARRAYS(TANDEM_MERGE_CHANGE)
#undef TANDEM_MERGE_CHANGE
  full = full || later.full;
  constants = constants || later.constants;
  bvh_constants = bvh_constants || later.bvh_constants;
  instances_changed = instances_changed || later.instances_changed;
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

SceneDelta operator|(SceneDelta scene, const SceneDelta& bvh) {
  scene.merge(bvh);
  return scene;
}

void ArrayChange::mark(uint32_t b, uint32_t e) {
  if (e <= b) return;
  if (end <= begin) {
    begin = b;
    end = e;
  } else {
    begin = std::min(begin, b);
    end = std::max(end, e);
  }
}

bool SceneDelta::any() const {
  bool any_array = false;
#define TANDEM_ANY_CHANGE(T, name) any_array = any_array || name.any();
  TANDEM_KERNEL_ARRAYS(TANDEM_ANY_CHANGE)
#undef TANDEM_ANY_CHANGE
  return any_array || full || constants || bvh_constants || instances_changed;
}

size_t SceneDelta::bytes(const KernelScene& ks) const {
  size_t total =
      (constants ? sizeof(KernelConstants) : 0) + (bvh_constants ? sizeof(KBvhConstants) : 0);
#define TANDEM_CHANGE_BYTES(T, name)     \
  if (name.reallocated)                  \
    total += ks.name.size() * sizeof(T); \
  else if (name.end > name.begin)        \
    total += size_t(name.end - name.begin) * sizeof(T);
  TANDEM_KERNEL_ARRAYS(TANDEM_CHANGE_BYTES)
#undef TANDEM_CHANGE_BYTES
  return total;
}

}  // namespace tandem
