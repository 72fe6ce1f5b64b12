#include "core/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tandem {

void SceneBounds::extend(const glm::vec3& p) {
  if (empty) {
    lo = hi = p;
    empty = false;
  } else {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
}

float SceneBounds::radius() const { return empty ? 0.0f : 0.5f * glm::length(hi - lo); }

namespace {
template <class T>
uint32_t append(std::vector<T>& items, std::vector<uint32_t>& dirty, T item) {
  items.push_back(std::move(item));
  dirty.push_back(kDirtyCreated | kDirtyParams);
  return uint32_t(items.size() - 1);
}
}  // namespace

uint32_t Scene::add_texture(Texture t) { return append(textures_, texture_dirty_, std::move(t)); }
uint32_t Scene::add_material(Material m) { return append(materials_, material_dirty_, std::move(m)); }
uint32_t Scene::add_mesh(Mesh m) {
  const uint32_t id = append(meshes_, mesh_dirty_, std::move(m));
  mesh_dirty_[id] |= kDirtyTopology | kDirtyVertices;
  return id;
}
uint32_t Scene::add_instance(Instance i) {
  const uint32_t id = append(instances_, instance_dirty_, std::move(i));
  instance_dirty_[id] |= kDirtyTransform;
  return id;
}
uint32_t Scene::add_light(Light l) { return append(lights_, light_dirty_, std::move(l)); }

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
  instance_dirty_[instance] |= kDirtyTransform;
}

Material& Scene::edit_material(uint32_t material) {
  material_dirty_.at(material) |= kDirtyParams;
  return materials_[material];
}

Light& Scene::edit_light(uint32_t light) {
  light_dirty_.at(light) |= kDirtyParams;
  return lights_[light];
}

Mesh& Scene::edit_mesh_vertices(uint32_t mesh) {
  mesh_dirty_.at(mesh) |= kDirtyVertices;
  return meshes_[mesh];
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
  for (const Mesh& m : meshes_) n += m.triangles.size();
  return n;
}

size_t Scene::triangle_count_instanced() const {
  size_t n = 0;
  for (const Instance& i : instances_) n += meshes_[i.mesh].triangles.size();
  return n;
}

SceneBounds Scene::bounds() const {
  // Per-mesh object-space bounds, then the 8 transformed corners per instance.
  std::vector<SceneBounds> mesh_bounds(meshes_.size());
  for (size_t i = 0; i < meshes_.size(); ++i) {
    for (const glm::uvec3& t : meshes_[i].triangles) {
      for (int k = 0; k < 3; ++k) mesh_bounds[i].extend(meshes_[i].positions[t[k]]);
    }
  }
  SceneBounds b;
  for (const Instance& inst : instances_) {
    const SceneBounds& mb = mesh_bounds[inst.mesh];
    if (mb.empty) continue;
    for (int c = 0; c < 8; ++c) {
      const glm::vec3 corner((c & 1) ? mb.hi.x : mb.lo.x, (c & 2) ? mb.hi.y : mb.lo.y,
                             (c & 4) ? mb.hi.z : mb.lo.z);
      b.extend(glm::vec3(inst.transform * glm::vec4(corner, 1.0f)));
    }
  }
  return b;
}

bool Scene::any_dirty() const {
  auto any = [](const std::vector<uint32_t>& v) {
    return std::any_of(v.begin(), v.end(), [](uint32_t d) { return d != 0; });
  };
  return camera_dirty_ || environment_dirty_ || any(texture_dirty_) || any(material_dirty_) ||
         any(mesh_dirty_) || any(instance_dirty_) || any(light_dirty_);
}

void Scene::clear_dirty() {
  for (auto* v : {&texture_dirty_, &material_dirty_, &mesh_dirty_, &instance_dirty_, &light_dirty_}) {
    std::fill(v->begin(), v->end(), 0u);
  }
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
