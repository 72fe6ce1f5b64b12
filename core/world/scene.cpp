#include "core/world/scene.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace tandem {

namespace {

uint64_t next_vertex_version() {
  static std::atomic<uint64_t> counter{0};
  return counter.fetch_add(1, std::memory_order_relaxed) + 1;
}

}  // namespace

uint32_t Scene::DirtySet::add(uint32_t bits) {
  const uint32_t id = uint32_t(mask.size());
  mask.push_back(0);
  mark(id, bits);
  return id;
}

void Scene::DirtySet::mark(uint32_t index, uint32_t bits) {
  uint32_t& m = mask.at(index);
  if (m == 0 && bits != 0) list.push_back(index);
  m |= bits;
}

void Scene::DirtySet::erase(const std::vector<uint8_t>& removed) {
  std::vector<uint32_t> new_index(mask.size(), kRemovedIndex);
  uint32_t kept = 0;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (removed[i]) continue;
    new_index[i] = kept;
    mask[kept++] = mask[i];
  }
  mask.resize(kept);
  std::vector<uint32_t> kept_list;
  for (uint32_t i : list) {
    if (new_index[i] != kRemovedIndex) kept_list.push_back(new_index[i]);
  }
  list = std::move(kept_list);
}

void Scene::DirtySet::clear() {
  for (uint32_t i : list)
    mask[i] = 0;
  list.clear();
}

uint32_t Scene::add_texture(Texture t) {
  textures_.push_back(std::move(t));
  return textures_dirty_.add(kDirtyCreated | kDirtyParams);
}
uint32_t Scene::add_material(Material m) {
  materials_.push_back(std::move(m));
  return materials_dirty_.add(kDirtyCreated | kDirtyParams);
}
uint32_t Scene::add_mesh(Mesh m) {
  meshes_.push_back(std::move(m));
  bounds_cache_.mesh_added();
  mesh_vertex_ranges_.push_back({0, uint32_t(meshes_.back().positions.size())});
  mesh_vertex_versions_.push_back(next_vertex_version());
  mesh_deforms_.push_back(0);
  unwritten_poses_.emplace_back();
  poses_since_clear_.emplace_back();
  return meshes_dirty_.add(kDirtyCreated | kDirtyParams | kDirtyTopology | kDirtyVertices);
}
uint32_t Scene::add_instance(Instance i) {
  bounds_cache_.instance_added(i.mesh);
  instances_.push_back(std::move(i));
  return instances_dirty_.add(kDirtyCreated | kDirtyParams | kDirtyTransform);
}
uint32_t Scene::add_light(Light l) {
  lights_.push_back(std::move(l));
  return lights_dirty_.add(kDirtyCreated | kDirtyParams);
}

void Scene::set_camera(const Camera& c) {
  camera_ = c;
  has_camera_ = true;
  camera_dirty_ = true;
}

void Scene::set_environment(Environment e) {
  environment_ = std::move(e);
  environment_dirty_ = true;
}

void Scene::set_instance_transform(uint32_t instance, const glm::mat4& transform) {
  instances_.at(instance).transform = transform;
  instances_dirty_.mark(instance, kDirtyTransform);
  bounds_cache_.instance_changed(instance);
}

void Scene::set_instance_hidden(uint32_t instance, bool hidden) {
  Instance& inst = instances_.at(instance);
  if (inst.hidden == hidden) return;
  inst.hidden = hidden;
  // The TLAS drops or takes it as for a move.
  instances_dirty_.mark(instance, kDirtyTransform);
  bounds_cache_.instance_changed(instance);
}

void Scene::remove_light(uint32_t light) {
  if (light >= lights_.size())
    throw std::out_of_range("remove_light: light " + std::to_string(light) + " does not exist");
  std::vector<uint8_t> removed(lights_.size(), 0);
  removed[light] = 1;
  lights_.erase(lights_.begin() + light);
  lights_dirty_.erase(removed);
}

namespace {

// Keeps the elements of `v` whose `removed` flag is 0, in order.
template <class T>
void erase_flagged(std::vector<T>& v, const std::vector<uint8_t>& removed) {
  size_t kept = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (removed[i]) continue;
    if (kept != i) v[kept] = std::move(v[i]);  // not onto itself: that may empty it
    ++kept;
  }
  v.resize(kept);
}

}  // namespace

std::vector<uint32_t> Scene::remove_mesh(uint32_t mesh) {
  if (mesh >= meshes_.size())
    throw std::out_of_range("remove_mesh: mesh " + std::to_string(mesh) + " does not exist");
  std::vector<uint8_t> mesh_removed(meshes_.size(), 0), instance_removed(instances_.size(), 0);
  mesh_removed[mesh] = 1;
  std::vector<uint32_t> remap(instances_.size(), kRemovedIndex);
  uint32_t kept = 0;
  for (size_t i = 0; i < instances_.size(); ++i) {
    instance_removed[i] = instances_[i].mesh == mesh;
    if (!instance_removed[i]) remap[i] = kept++;
  }
  erase_flagged(instances_, instance_removed);
  for (Instance& inst : instances_) {
    if (inst.mesh > mesh) --inst.mesh;
  }
  instances_dirty_.erase(instance_removed);
  if (unwritten_poses_[mesh] != nullptr) --unwritten_count_;
  erase_flagged(meshes_, mesh_removed);
  erase_flagged(mesh_vertex_ranges_, mesh_removed);
  erase_flagged(mesh_vertex_versions_, mesh_removed);
  erase_flagged(mesh_deforms_, mesh_removed);
  erase_flagged(unwritten_poses_, mesh_removed);
  erase_flagged(poses_since_clear_, mesh_removed);
  meshes_dirty_.erase(mesh_removed);
  // Every index the cache keeps moved: it starts over (the next bounds()
  // walks the scene once, as after loading).
  bounds_cache_ = SceneBoundsCache{};
  for (size_t m = 0; m < meshes_.size(); ++m)
    bounds_cache_.mesh_added();
  for (const Instance& inst : instances_)
    bounds_cache_.instance_added(inst.mesh);
  return remap;
}

void Scene::set_mesh_deforms(uint32_t mesh, bool deforms) {
  uint8_t& d = mesh_deforms_.at(mesh);
  if (d == uint8_t(deforms)) return;
  d = uint8_t(deforms);
  meshes_dirty_.mark(mesh, kDirtyTopology);
}

Material& Scene::edit_material(uint32_t material) {
  materials_dirty_.mark(material, kDirtyParams);
  return materials_[material];
}

Light& Scene::edit_light(uint32_t light) {
  lights_dirty_.mark(light, kDirtyParams);
  return lights_[light];
}

void Scene::mark_vertices(uint32_t mesh, uint32_t begin, uint32_t end) {
  mesh_vertex_versions_[mesh] = next_vertex_version();
  VertexRange& r = mesh_vertex_ranges_[mesh];
  if (!(meshes_dirty_.mask[mesh] & kDirtyVertices) || r.empty()) {
    r = {begin, end};
  } else {
    r = {std::min(r.begin, begin), std::max(r.end, end)};
  }
  meshes_dirty_.mark(mesh, kDirtyVertices);
  bounds_cache_.mesh_changed(mesh);
}

Mesh& Scene::edit_mesh_vertices(uint32_t mesh) {
  Mesh& m = meshes_.at(mesh);
  write_unwritten_pose(mesh);  // the caller may read what it does not write
  mark_vertices(mesh, 0, uint32_t(m.positions.size()));
  poses_since_clear_[mesh] = nullptr;
  return m;
}

Mesh& Scene::edit_mesh_vertices(uint32_t mesh, uint32_t first_vertex, uint32_t count) {
  Mesh& m = meshes_.at(mesh);
  if (uint64_t(first_vertex) + count > m.positions.size()) {
    throw std::out_of_range("edit_mesh_vertices: vertices [" + std::to_string(first_vertex) + ", " +
                            std::to_string(uint64_t(first_vertex) + count) + ") of mesh " +
                            std::to_string(mesh) + " (\"" + m.name + "\"), which has " +
                            std::to_string(m.positions.size()));
  }
  write_unwritten_pose(mesh);
  if (count > 0) {
    mark_vertices(mesh, first_vertex, first_vertex + count);
    poses_since_clear_[mesh] = nullptr;
  }
  return m;
}

void Scene::pose_mesh(uint32_t mesh, std::shared_ptr<const MeshPose> pose) {
  const Mesh& m = meshes_.at(mesh);
  if (pose == nullptr) throw std::invalid_argument("pose_mesh: no pose for mesh " + m.name);
  if (pose->vertex_count() != m.positions.size()) {
    throw std::invalid_argument("pose_mesh: a pose of " + std::to_string(pose->vertex_count()) +
                                " vertices for mesh " + std::to_string(mesh) + " (\"" + m.name +
                                "\"), which has " + std::to_string(m.positions.size()));
  }
  // Another kind of edit since the consumer last took the changes: it must
  // copy the mesh, whatever poses follow.
  const bool other_edit = (meshes_dirty_.mask[mesh] & kDirtyVertices) && !poses_since_clear_[mesh];
  std::shared_ptr<const MeshPose>& slot = unwritten_poses_[mesh];
  if (slot == nullptr) ++unwritten_count_;
  slot = pose;
  mark_vertices(mesh, 0, uint32_t(m.positions.size()));
  poses_since_clear_[mesh] = other_edit ? nullptr : std::move(pose);
}

void Scene::write_unwritten_pose(uint32_t mesh) const {
  if (mesh >= unwritten_poses_.size() || unwritten_poses_[mesh] == nullptr) return;
  // Out of the slot first: a pose that throws is not written again over
  // half-written vertices.
  const std::shared_ptr<const MeshPose> pose = std::move(unwritten_poses_[mesh]);
  unwritten_poses_[mesh] = nullptr;
  --unwritten_count_;
  pose->write(meshes_[mesh]);
}

void Scene::write_unwritten_poses() const {
  for (uint32_t m = 0; m < unwritten_poses_.size() && unwritten_count_ != 0; ++m)
    write_unwritten_pose(m);
}

Scene::VertexRange Scene::mesh_dirty_vertices(uint32_t mesh) const {
  if (mesh >= mesh_vertex_ranges_.size() || !(meshes_dirty_.mask[mesh] & kDirtyVertices)) return {};
  return mesh_vertex_ranges_[mesh];
}

Camera& Scene::edit_camera() {
  camera_dirty_ = true;
  has_camera_ = true;
  return camera_;
}

Environment& Scene::edit_environment() {
  environment_dirty_ = true;
  return environment_;
}

size_t Scene::triangle_count_unique() const {
  size_t n = 0;
  for (const Mesh& m : meshes_)
    n += m.triangles.size();
  return n;
}

size_t Scene::triangle_count_instanced() const {
  size_t n = 0;
  for (const Instance& i : instances_)
    n += i.hidden ? 0 : meshes_[i.mesh].triangles.size();
  return n;
}

SceneBounds Scene::bounds() const {
  // A posed mesh the cache reads is written first. Only the cache's
  // changed meshes can be (a posed mesh was marked changed), so the walk
  // stays O(edits) like the cache's own.
  if (unwritten_count_ != 0) {
    for (uint32_t m : bounds_cache_.stale_meshes()) {
      if (bounds_cache_.reads_vertices(m)) write_unwritten_pose(m);
    }
  }
  return bounds_cache_.bounds(meshes_, instances_);
}

SceneBounds Scene::mesh_bounds(uint32_t mesh) const {
  bounds();
  return bounds_cache_.mesh_box(mesh);
}

bool Scene::any_dirty() const {
  return camera_dirty_ || environment_dirty_ || !textures_dirty_.list.empty() ||
         !materials_dirty_.list.empty() || !meshes_dirty_.list.empty() ||
         !instances_dirty_.list.empty() || !lights_dirty_.list.empty();
}

void Scene::clear_dirty() {
  // Every posed mesh is on the dirty list (kDirtyVertices).
  for (uint32_t m : meshes_dirty_.list)
    poses_since_clear_[m] = nullptr;
  for (DirtySet* d :
       {&textures_dirty_, &materials_dirty_, &meshes_dirty_, &instances_dirty_, &lights_dirty_})
    d->clear();
  camera_dirty_ = false;
  environment_dirty_ = false;
}

Camera frame_bounds_camera(const SceneBounds& bounds, float yfov, float aspect) {
  Camera cam;
  cam.yfov = yfov;
  if (bounds.empty) return cam;
  const glm::vec3 center = bounds.center();
  const float radius = std::max(bounds.radius(), 1e-3f);
  // Look from the front (+z), slightly above, like most glTF viewers.
  const glm::vec3 dir = glm::normalize(glm::vec3(0.0f, -0.25f, -1.0f));
  const float half_fov = 0.5f * std::min(yfov, 2.0f * std::atan(std::tan(0.5f * yfov) * aspect));
  const float distance = radius / std::sin(half_fov) * 1.05f;
  cam.position = center - dir * distance;
  cam.forward = dir;
  const glm::vec3 right = glm::normalize(glm::cross(dir, glm::vec3(0.0f, 1.0f, 0.0f)));
  cam.up = glm::cross(right, dir);
  cam.focus_distance = distance;
  return cam;
}

}  // namespace tandem
