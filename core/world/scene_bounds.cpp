#include "core/world/scene_bounds.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/world/scene.h"
#include "core/world/scene_ranges.h"

namespace tandem {

void SceneBounds::extend(const glm::vec3& p) {
  finite = finite && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
  if (empty) {
    lo = hi = p;
    empty = false;
  } else {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
}

void SceneBounds::extend(const SceneBounds& b) {
  if (b.empty) return;
  finite = finite && b.finite;
  if (empty) {
    *this = b;
  } else {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
}

float SceneBounds::radius() const {
  return empty ? 0.0f : 0.5f * glm::length(hi - lo);
}

namespace {

// -0 and +0 compare equal, so which of them a min or max keeps depends on
// the order the points came in; every way of computing a box ends with
// this, so they all agree to the bit.
SceneBounds positive_zeros(SceneBounds b) {
  b.lo += glm::vec3(0.0f);
  b.hi += glm::vec3(0.0f);
  return b;
}

bool finite(const glm::vec3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

}  // namespace

SceneBounds mesh_object_bounds(const Mesh& mesh) {
  SceneBounds b;
  for (const glm::uvec3& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k)
      b.extend(mesh.positions[t[k]]);
  }
  return positive_zeros(b);
}

SceneBounds vertex_bounds(const glm::vec3* positions, size_t count, bool* all_finite) {
  // Branch-free min/max over a straight array (the compiler vectorises it),
  // instead of SceneBounds::extend per triangle corner.
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo);
  bool ok = true;
  for (size_t v = 0; v < count; ++v) {
    const glm::vec3 p = positions[v];
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
    ok &= finite(p);
  }
  *all_finite = ok;
  SceneBounds b;
  if (count == 0) return b;
  b.lo = lo;
  b.hi = hi;
  b.empty = false;
  b.finite = ok;
  return positive_zeros(b);
}

SceneBounds instance_world_bounds(const Instance& inst, const SceneBounds& mb) {
  SceneBounds b;
  if (inst.hidden || mb.empty || classify_instance(inst.transform, mb) != InstanceState::kVisible)
    return b;
  for (int c = 0; c < 8; ++c) {
    const glm::vec3 corner((c & 1) ? mb.hi.x : mb.lo.x, (c & 2) ? mb.hi.y : mb.lo.y,
                           (c & 4) ? mb.hi.z : mb.lo.z);
    b.extend(glm::vec3(inst.transform * glm::vec4(corner, 1.0f)));
  }
  return b;
}

SceneBounds compute_scene_bounds(const std::vector<Mesh>& meshes,
                                 const std::vector<Instance>& instances) {
  std::vector<SceneBounds> mesh_bounds(meshes.size());
  for (size_t i = 0; i < meshes.size(); ++i)
    mesh_bounds[i] = mesh_object_bounds(meshes[i]);
  SceneBounds b;
  for (const Instance& inst : instances)
    b.extend(instance_world_bounds(inst, mesh_bounds[inst.mesh]));
  return b;
}

void SceneBoundsCache::mesh_added() {
  const uint32_t m = uint32_t(mesh_bounds_.size());
  mesh_bounds_.emplace_back();
  given_bounds_.emplace_back();
  given_.push_back(0);
  vertex_use_.push_back(kUnknown);
  mesh_instances_.emplace_back();
  mesh_stale_.push_back(0);
  mesh_changed(m);
}

void SceneBoundsCache::instance_added(uint32_t mesh) {
  const uint32_t i = uint32_t(instance_mesh_.size());
  instance_mesh_.push_back(mesh);
  instance_stale_.push_back(0);
  // A bad mesh index is the loader's to report; it just has no box here.
  if (mesh < mesh_instances_.size()) mesh_instances_[mesh].push_back(i);
  mark_instance(i);
}

void SceneBoundsCache::mesh_changed(uint32_t mesh) {
  if (mesh >= mesh_stale_.size()) return;
  given_[mesh] = 0;  // describes the mesh before this change
  if (mesh_stale_[mesh]) return;
  mesh_stale_[mesh] = 1;
  stale_meshes_.push_back(mesh);
}

void SceneBoundsCache::mesh_vertex_bounds(uint32_t mesh, const SceneBounds& all_vertices) {
  if (mesh >= mesh_stale_.size() || !mesh_stale_[mesh]) return;
  given_bounds_[mesh] = positive_zeros(all_vertices);
  given_[mesh] = 1;
}

SceneBounds SceneBoundsCache::refresh_mesh(uint32_t mesh, const MeshLookup& lookup) {
  if (vertex_use_[mesh] == kAllUsed && given_[mesh]) return given_bounds_[mesh];
  const Mesh& m = lookup(mesh);
  if (vertex_use_[mesh] == kUnknown) {
    // Once per mesh: are all vertices used? Then a straight pass over the
    // positions (or the compiler's box) gives the triangles' box.
    std::vector<uint8_t> used(m.positions.size(), 0);
    for (const glm::uvec3& t : m.triangles) {
      for (int k = 0; k < 3; ++k) {
        if (t[k] < used.size()) used[t[k]] = 1;
      }
    }
    vertex_use_[mesh] =
        std::find(used.begin(), used.end(), 0) == used.end() ? kAllUsed : kSomeUnused;
  }
  if (vertex_use_[mesh] == kAllUsed && !m.triangles.empty()) {
    if (given_[mesh]) return given_bounds_[mesh];
    bool all_finite = false;
    const SceneBounds b = vertex_bounds(m.positions.data(), m.positions.size(), &all_finite);
    // Non-finite points: SceneBounds::extend's order decides, so walk.
    if (all_finite) return b;
  }
  return mesh_object_bounds(m);
}

void SceneBoundsCache::instance_changed(uint32_t instance) {
  mark_instance(instance);
}

void SceneBoundsCache::mark_instance(uint32_t instance) {
  if (instance >= instance_stale_.size() || instance_stale_[instance]) return;
  instance_stale_[instance] = 1;
  stale_instances_.push_back(instance);
}

// Room for every instance: leaves_ doubles, so a scene that keeps adding
// instances pays for a rebuild O(log n) times in all.
void SceneBoundsCache::regrow_tree(size_t mesh_count, const std::vector<Instance>& instances) {
  const uint32_t n = uint32_t(instances.size());
  uint32_t leaves = std::max(1u, leaves_);
  while (leaves < n)
    leaves *= 2;
  std::vector<SceneBounds> old = std::move(tree_);
  const uint32_t old_leaves = leaves_;
  tree_.assign(2 * size_t(leaves), SceneBounds{});
  leaves_ = leaves;
  for (uint32_t i = 0; i < n; ++i) {
    if (i < old_leaves && !instance_stale_[i]) {
      tree_[leaves + i] = old[old_leaves + i];
    } else {
      const uint32_t m = instances[i].mesh;
      tree_[leaves + i] =
          m < mesh_count ? instance_world_bounds(instances[i], mesh_bounds_[m]) : SceneBounds{};
    }
  }
  for (uint32_t p = leaves - 1; p >= 1; --p) {
    tree_[p] = tree_[2 * p];
    tree_[p].extend(tree_[2 * p + 1]);
  }
}

SceneBounds SceneBoundsCache::bounds(const std::vector<Mesh>& meshes,
                                     const std::vector<Instance>& instances) {
  return bounds(
      meshes.size(), [&](uint32_t m) -> const Mesh& { return meshes[m]; }, instances);
}

SceneBounds SceneBoundsCache::bounds(size_t mesh_count, const MeshLookup& mesh,
                                     const std::vector<Instance>& instances) {
  for (uint32_t m : stale_meshes_) {
    mesh_bounds_[m] = refresh_mesh(m, mesh);
    mesh_stale_[m] = 0;
    given_[m] = 0;
    for (uint32_t i : mesh_instances_[m])
      mark_instance(i);
  }
  stale_meshes_.clear();
  if (instances.size() > leaves_) {
    regrow_tree(mesh_count, instances);
  } else {
    for (uint32_t i : stale_instances_) {
      const uint32_t m = instances[i].mesh;
      tree_[leaves_ + i] =
          m < mesh_count ? instance_world_bounds(instances[i], mesh_bounds_[m]) : SceneBounds{};
    }
    // Parents of the changed leaves, level by level (each parent once).
    std::vector<uint32_t> level;
    level.reserve(stale_instances_.size());
    for (uint32_t i : stale_instances_)
      level.push_back((leaves_ + i) / 2);
    while (!level.empty() && level.front() >= 1) {
      std::sort(level.begin(), level.end());
      level.erase(std::unique(level.begin(), level.end()), level.end());
      for (uint32_t p : level) {
        tree_[p] = tree_[2 * p];
        tree_[p].extend(tree_[2 * p + 1]);
      }
      if (level.front() == 1) break;
      for (uint32_t& p : level)
        p /= 2;
    }
  }
  for (uint32_t i : stale_instances_)
    instance_stale_[i] = 0;
  stale_instances_.clear();
  return leaves_ == 0 ? SceneBounds{} : tree_[1];
}

}  // namespace tandem
