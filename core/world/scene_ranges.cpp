#include "core/world/scene_ranges.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/util/errors.h"
#include "core/world/scene.h"

namespace tandem {

namespace {

bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool within_world(const glm::dvec3& p) {
  const double m = kMaxWorldCoordinate;
  return std::fabs(p.x) <= m && std::fabs(p.y) <= m && std::fabs(p.z) <= m;
}

std::string num(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

std::string vec_text(const glm::dvec3& v) {
  char text[96];
  std::snprintf(text, sizeof text, "(%g, %g, %g)", v.x, v.y, v.z);
  return text;
}

std::string quoted(const std::string& name, const char* kind, size_t index) {
  return std::string(kind) + " " + std::to_string(index) +
         (name.empty() ? "" : " ('" + name.substr(0, 80) + (name.size() > 80 ? "...'" : "'") + ")");
}

}  // namespace

InstanceState classify_instance(const glm::mat4& transform, const SceneBounds& mesh_box) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(transform[c][r])) return InstanceState::kNonFinite;
  if (!mesh_box.empty && !mesh_box.finite) return InstanceState::kNonFinite;
  // In double: the products that overflow float are what is being checked.
  const glm::dmat4 t(transform);
  // Where it puts its mesh (or, without one, its origin) first: a node far
  // away is out of range, not singular, though its inverse is large too.
  if (!within_world(glm::dvec3(t[3]))) return InstanceState::kOutOfRange;
  if (!mesh_box.empty) {
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? mesh_box.hi.x : mesh_box.lo.x,
                              (c & 2) ? mesh_box.hi.y : mesh_box.lo.y,
                              (c & 4) ? mesh_box.hi.z : mesh_box.lo.z);
      if (!within_world(glm::dvec3(t * glm::dvec4(corner, 1.0)))) return InstanceState::kOutOfRange;
    }
  }
  const glm::dmat3 linear(t);
  const double det = glm::determinant(linear);
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return InstanceState::kSingular;
  const glm::dmat3 inverse = glm::inverse(linear);
  const glm::dvec3 back = -(inverse * glm::dvec3(t[3]));
  for (int r = 0; r < 3; ++r) {
    // The largest |coordinate| the inverse gives a point within the world range.
    const double reach =
        (std::fabs(inverse[0][r]) + std::fabs(inverse[1][r]) + std::fabs(inverse[2][r])) *
            double(kMaxWorldCoordinate) +
        std::fabs(back[r]);
    if (!(reach <= kMaxInstanceCoordinate)) return InstanceState::kSingular;
  }
  return InstanceState::kVisible;
}

const char* instance_state_text(InstanceState state) {
  switch (state) {
    case InstanceState::kVisible:
      return "is drawn";
    case InstanceState::kSingular:
      return "has a singular transform (scaled to 0, or below what can be traced)";
    case InstanceState::kNonFinite:
      return "has positions that are not finite (its transform or vertices overflow float)";
    case InstanceState::kOutOfRange:
      return "lies beyond 1e+09 of the origin, the range Tandem can trace";
  }
  return "";
}

std::string camera_problem(const Camera& c) {
  if (!finite3(c.position)) return "its position is not finite";
  if (!within_world(glm::dvec3(c.position)))
    return "its position " + vec_text(glm::dvec3(c.position)) + " lies beyond " +
           num(kMaxWorldCoordinate) + " of the origin";
  if (!finite3(c.forward) || !finite3(c.up) || !(glm::length(c.forward) > 0.5f) ||
      !(glm::length(c.up) > 0.5f))
    return "its orientation is not a finite frame";
  if (c.type == CameraType::kOrthographic &&
      !(c.ortho_half_height > 0.0f && c.ortho_half_height <= kMaxWorldCoordinate))
    return "its orthographic half height " + num(c.ortho_half_height) + " is not in (0, " +
           num(kMaxWorldCoordinate) + "]";
  if (c.type == CameraType::kPerspective && !(c.yfov > 0.0f && c.yfov < 3.14159f))
    return "its vertical field of view " + num(c.yfov) + " is not in (0, pi)";
  if (!(c.aperture_radius >= 0.0f && c.aperture_radius <= kMaxWorldCoordinate))
    return "its aperture radius " + num(c.aperture_radius) + " is not in [0, " +
           num(kMaxWorldCoordinate) + "]";
  if (!(c.focus_distance > 0.0f && std::isfinite(c.focus_distance)))
    return "its focus distance " + num(c.focus_distance) + " is not positive and finite";
  return "";
}

void check_scene_traceable(const Scene& scene, const std::string& where) {
  auto fail = [&](const std::string& what) { throw InputError(where + ": " + what); };
  const std::vector<Instance>& instances = scene.instances();
  for (size_t i = 0; i < instances.size(); ++i) {
    const Instance& inst = instances[i];
    if (inst.mesh >= scene.mesh_count()) continue;  // the loader's to report
    const InstanceState s = classify_instance(inst.transform, scene.mesh_bounds(inst.mesh));
    if (s == InstanceState::kNonFinite || s == InstanceState::kOutOfRange)
      fail(quoted(inst.name, "node", i) + " with " +
           quoted(scene.meshes()[inst.mesh].name, "mesh", inst.mesh) + " " +
           instance_state_text(s));
  }
  if (scene.has_camera()) {
    const std::string problem = camera_problem(scene.camera());
    if (!problem.empty()) fail("the camera cannot be rendered: " + problem);
  }
  const std::vector<Light>& lights = scene.lights();
  for (size_t i = 0; i < lights.size(); ++i) {
    const Light& l = lights[i];
    if (l.type != LightType::kDirectional &&
        (!finite3(l.position) || !within_world(glm::dvec3(l.position))))
      fail(quoted(l.name, "light", i) + " is placed at " + vec_text(glm::dvec3(l.position)) +
           ", not a finite point within " + num(kMaxWorldCoordinate) + " of the origin");
    if (l.type != LightType::kPoint && !(finite3(l.direction) && glm::length(l.direction) > 0.5f))
      fail(quoted(l.name, "light", i) + " points along " + vec_text(glm::dvec3(l.direction)) +
           ", not a finite direction");
    const double radiance =
        double(l.intensity) * double(std::max({l.color.r, l.color.g, l.color.b}));
    if (!(std::fabs(radiance) <= kMaxRadiance))
      fail(quoted(l.name, "light", i) + " has an intensity of " + num(radiance) +
           ", beyond the largest radiance that can be rendered (" + num(kMaxRadiance) + ")");
  }
  const std::vector<Material>& materials = scene.materials();
  for (size_t i = 0; i < materials.size(); ++i) {
    const Material& m = materials[i];
    const double emission = double(m.emissive_strength) *
                            double(std::max({std::fabs(m.emissive.r), std::fabs(m.emissive.g),
                                             std::fabs(m.emissive.b)}));
    if (!(emission <= kMaxRadiance))
      fail(quoted(m.name, "material", i) + " emits " + num(emission) +
           " (emissive times strength), beyond the largest radiance that can be rendered (" +
           num(kMaxRadiance) + ")");
  }
}

}  // namespace tandem
