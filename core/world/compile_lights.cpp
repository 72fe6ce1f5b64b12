// The light list: punctual lights, the environment light and one light per
// instance of an emissive mesh (whose triangles compile_mesh_lights.cpp
// makes lights of, once per mesh), and what chooses among them: the alias
// table by power, or (the tree sampler) the light tree over the finite
// lights beside an alias table of the infinite ones. A full build walks the
// meshes' emissive triangles; a moved instance, a deformed mesh, a changed
// punctual light or a change of the scene's size (which scales directional
// and environment powers) recompute what they change and refit the tree
// along their paths.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>
#include "core/util/log.h"
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

#include "core/kernel/lights.h"
#include "core/world/light_tables.h"
#include "core/world/light_tree_build.h"

namespace tandem {

namespace {

// Whether a punctual light can be traced (scene_ranges.h): a finite place
// within the world's range, a finite direction where it has one, and a
// radiance floats can carry. An animation or an API edit can take a light
// anywhere; loading a file refuses such a light (check_scene_traceable).
bool punctual_light_traceable(const Light& l) {
  const auto finite = [](const glm::vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
  };
  const double radiance = double(l.intensity) * double(std::max({l.color.r, l.color.g, l.color.b}));
  const bool placed =
      l.type == LightType::kDirectional ||
      (finite(l.position) &&
       glm::all(glm::lessThanEqual(glm::abs(l.position), glm::vec3(kMaxWorldCoordinate))));
  const bool aimed =
      l.type == LightType::kPoint || (finite(l.direction) && glm::length(l.direction) > 0.0f);
  return placed && aimed && std::fabs(radiance) <= kMaxRadiance;
}

KLight punctual_light(const Light& l) {
  KLight k{};
  if (!punctual_light_traceable(l)) {
    // Off: no radiance, so no power and never chosen.
    k.type = kLightPoint;
    k.direction = Vec3{0.0f, 0.0f, -1.0f};
    return k;
  }
  const glm::vec3 intensity = l.color * l.intensity;
  k.intensity = to_vec3(intensity);
  k.position = to_vec3(l.position);
  k.direction = to_vec3(glm::normalize(l.direction));
  k.cos_inner = std::cos(l.inner_cone_angle);
  k.cos_outer = std::cos(l.outer_cone_angle);
  switch (l.type) {
    case LightType::kPoint:
      k.type = kLightPoint;
      break;
    case LightType::kSpot:
      k.type = kLightSpot;
      break;
    case LightType::kDirectional:
      k.type = kLightDirectional;
      break;
  }
  return k;
}

// Emitted power, what light selection is proportional to. A directional
// light's flux is through the scene's bounding disk of `radius`.
double punctual_power(const KLight& k, float radius) {
  const float lum = luminance(k.intensity);
  switch (k.type) {
    case kLightSpot:
      return 2.0 * kPi * lum * (1.0 - 0.5 * (k.cos_inner + k.cos_outer));
    case kLightDirectional:
      return kPi * radius * radius * lum;
    default:
      return 4.0 * kPi * lum;
  }
}

float environment_luminance(const KEnvironment& env) {
  return env.has_map ? luminance(env.color) * env.map_integral /
                           std::max(1.0f, float(env.width) * float(env.height) * 0.6366f)
                     : luminance(env.color);
}

// Flux of a uniform radiance through the scene's bounding disk.
double environment_power(float env_lum, float radius) {
  return kPi * kPi * radius * radius * env_lum;
}

float light_radius(const SceneBounds& bounds) {
  return std::max(bounds.radius(), 1e-3f);
}

bool light_at_infinity(const KLight& l) {
  return l.type == kLightDirectional || l.type == kLightEnvironment;
}

glm::vec3 to_glm(Vec3 v) {
  return glm::vec3(v.x, v.y, v.z);
}

// The Gram matrix of the linear part of `m` (M^T M), in doubles.
void gram(const Mat34& m, double g[3][3]) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      g[i][j] = 0.0;
      for (int r = 0; r < 3; ++r)
        g[i][j] += double((&m.rows[r].x)[i]) * double((&m.rows[r].x)[j]);
    }
  }
}

// Whether a linear part of Gram matrix `g` scales every direction alike (a
// rotation, a mirror and a uniform scale): `g` is s^2 times the identity,
// s^2 into *scale2.
bool similarity(const double g[3][3], double* scale2) {
  const double trace = g[0][0] + g[1][1] + g[2][2];
  *scale2 = trace / 3.0;
  const double tolerance = 1e-5 * trace;
  return std::fabs(g[0][1]) <= tolerance && std::fabs(g[0][2]) <= tolerance &&
         std::fabs(g[1][2]) <= tolerance && std::fabs(g[0][0] - *scale2) <= tolerance &&
         std::fabs(g[1][1] - *scale2) <= tolerance && std::fabs(g[2][2] - *scale2) <= tolerance;
}

// A bound on how much the map of normals of `m` (its inverse transpose)
// widens angles: the sine of the angle between two mapped unit vectors is
// at most this times the sine of theirs (the squared condition number,
// bounded by trace(G)^3 / det(G) of the Gram matrix G); 1 for a similarity.
double normal_angle_widening(const Mat34& m) {
  double g[3][3], scale2 = 0.0;
  gram(m, g);
  if (similarity(g, &scale2)) return 1.0;
  const double trace = g[0][0] + g[1][1] + g[2][2];
  const double det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1]) -
                     g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0]) +
                     g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
  return det > 0.0 ? trace * trace * trace / det : INFINITY;
}

// The power of instance `inst`'s triangle lights in world space: its mesh's
// times the area scale of a similarity, else their world areas summed.
double instance_light_power(const KernelData& kd, const KInstance& inst) {
  if (inst.flags & kInstanceHidden) return 0.0;
  const KMeshLights& ml = kd.mesh_lights[inst.mesh];
  if (inst.flags & kInstanceIdentity) return double(ml.power);
  double g[3][3], scale2 = 0.0;
  gram(inst.object_to_world, g);
  if (similarity(g, &scale2)) return double(ml.power) * scale2;
  double power = 0.0;
  for (uint32_t t = ml.first; t < ml.first + ml.count; ++t) {
    const KTriangleLight& tl = kd.triangle_lights[t];
    const Vec3 e1 = instance_vector(inst, tl.p1 - tl.p0);
    const Vec3 e2 = instance_vector(inst, tl.p2 - tl.p0);
    power += triangle_light_power(kd.materials[tl.material], 0.5f * length(cross(e1, e2)));
  }
  return power;
}

}  // namespace

// What the light tree knows of light `index` (finite, of the given power):
// where it is and which way it emits, in world space. An instance's is its
// mesh's tree's root moved by its transform: the box's corners, and the
// cone turned with the normals, widened where the transform is not a
// similarity.
LightTreeInput SceneCompiler::light_tree_input(const KernelData& kd, uint32_t index,
                                               float power) const {
  const KLight& l = kd.lights[index];
  LightTreeInput in;
  in.light = index;
  in.power = power;
  if (l.type == kLightMeshInstance) {
    const KInstance& inst = kd.instances[l.instance];
    const KLightTreeNode& root = kd.light_tree_nodes[kd.mesh_lights[inst.mesh].tree_root];
    const glm::vec3 lo = mesh_light_lo_[inst.mesh], hi = mesh_light_hi_[inst.mesh];
    in.lo = glm::vec3(INFINITY);
    in.hi = glm::vec3(-INFINITY);
    for (int corner = 0; corner < 8; ++corner) {
      const glm::vec3 c((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y,
                        (corner & 4) ? hi.z : lo.z);
      const glm::vec3 w = to_glm(instance_point(inst, make_vec3(c.x, c.y, c.z)));
      in.lo = glm::min(in.lo, w);
      in.hi = glm::max(in.hi, w);
    }
    // Normals go by the inverse transpose, which a similarity turns without
    // changing their angles; any other widens a spread of them by at most
    // normal_angle_widening (the whole sphere when that bound says nothing).
    const double widening =
        (inst.flags & kInstanceIdentity) ? 1.0 : normal_angle_widening(inst.object_to_world);
    const glm::vec3 axis = to_glm(instance_normal(inst, root.axis));
    in.cos_theta_o = -1.0f;
    if (glm::dot(axis, axis) > 0.0f) {
      in.axis = glm::normalize(axis);
      const double sin_o = widening * double(root.sin_theta_o);
      if (widening == 1.0) {
        in.cos_theta_o = root.cos_theta_o;
      } else if (root.cos_theta_o > 0.0f && sin_o < 1.0) {
        // Below pi/2 all along (the sine never reaches 1), so the angle is
        // the arcsine's.
        in.cos_theta_o = float(std::sqrt(1.0 - sin_o * sin_o));
      }
    }
    in.cos_theta_e = root.cos_theta_e;
    in.two_sided = (root.flags & kLightTreeTwoSided) != 0;
    return in;
  }
  in.lo = in.hi = to_glm(l.position);
  if (l.type == kLightSpot) {
    // No light beyond the outer cone.
    in.axis = to_glm(l.direction);
    in.cos_theta_o = l.cos_outer;
    in.cos_theta_e = 1.0f;
  } else {
    in.cos_theta_o = -1.0f;  // every direction
    in.cos_theta_e = 1.0f;
  }
  return in;
}

bool SceneCompiler::tree_sampler() const {
  return light_sampler_ == LightSampler::kTree;
}

// The alias table and total power from light_power_: with the tree, the
// infinite lights' table beside it and the tree's share of the power.
void SceneCompiler::compile_light_alias(KernelScene& out, bool with_tree) {
  const std::vector<double>& power = light_power_;
  double total = 0.0, finite = 0.0;
  std::vector<double> infinite(power.size(), 0.0);
  for (size_t i = 0; i < power.size(); ++i) {
    total += power[i];
    if (light_at_infinity(out.lights[i])) {
      infinite[i] = power[i];
    } else {
      finite += power[i];
    }
  }
  out.constants.total_light_power = float(total);
  out.constants.light_tree_fraction = 0.0f;
  if (!with_tree || !(finite > 0.0)) {
    out.light_alias = build_alias_table(power);
    return;
  }
  // The finite lights' share goes to the tree; the infinite ones keep
  // theirs, each entry's pdf its power over all (what the kernel's MIS
  // reads for the environment), so only their own table is drawn from.
  const float fraction = float(finite / total);
  out.constants.light_tree_fraction = fraction;
  if (fraction < 1.0f) {
    out.light_alias = build_alias_table(infinite);
    for (size_t i = 0; i < power.size(); ++i)
      out.light_alias[i].pdf = float(infinite[i] / total);
  } else {
    out.light_alias.assign(power.size(), KAliasEntry{0.0f, 0, 0.0f, 0.0f});
  }
}

void SceneCompiler::finish_light_tables(KernelScene& out, SceneDelta& delta) {
  // The meshes' trees stay; the lights' tree after them is built anew.
  out.light_tree_nodes.resize(mesh_light_tree_nodes_);
  out.light_tree_trails.assign(out.lights.size(), 0);
  out.constants.light_tree_root = kInvalidIndex;
  if (tree_sampler()) {
    const KernelData kd = out.view();
    std::vector<LightTreeInput> inputs;
    for (uint32_t i = 0; i < light_power_.size(); ++i) {
      if (!light_at_infinity(out.lights[i]) && light_power_[i] > 0.0)
        inputs.push_back(light_tree_input(kd, i, float(light_power_[i])));
    }
    out.constants.light_tree_root = append_light_tree(std::move(inputs), out.light_tree_nodes,
                                                      out.light_tree_trails, &top_shape_);
  }
  compile_light_alias(out, out.constants.light_tree_root != kInvalidIndex);
  delta.light_tree_nodes.reallocated = true;
  delta.light_tree_trails.reallocated = true;
  delta.light_alias.reallocated = true;
  delta.constants = true;
}

void SceneCompiler::refresh_light_tables(KernelScene& out, SceneDelta& delta,
                                         std::vector<uint32_t> changed) {
  const bool tree = out.constants.light_tree_root != kInvalidIndex;
  if (tree_sampler() != tree) {
    finish_light_tables(out, delta);
    return;
  }
  // The tree keeps its shape when every light in it still has power and no
  // light without one gained some: then only the changed lights' paths.
  for (uint32_t i : changed) {
    if (tree && !light_at_infinity(out.lights[i]) &&
        (top_shape_.leaf_of[i] != kInvalidIndex) != (light_power_[i] > 0.0)) {
      finish_light_tables(out, delta);
      return;
    }
  }
  compile_light_alias(out, tree);
  delta.light_alias.mark(0, uint32_t(out.light_alias.size()));
  delta.constants = true;
  if (!tree) return;
  std::vector<uint32_t> leaves;
  for (uint32_t i : changed) {
    if (top_shape_.leaf_of[i] != kInvalidIndex) leaves.push_back(top_shape_.leaf_of[i]);
  }
  std::sort(leaves.begin(), leaves.end());
  leaves.erase(std::unique(leaves.begin(), leaves.end()), leaves.end());
  const KernelData kd = out.view();
  std::vector<uint32_t> rewritten;
  refit_light_tree_paths(
      out.light_tree_nodes, top_shape_, leaves,
      [&](uint32_t light) { return light_tree_input(kd, light, float(light_power_[light])); },
      &rewritten);
  for (uint32_t node : rewritten) {
    // A leaf's entries follow it.
    const uint32_t count = out.light_tree_nodes[node].count;
    delta.light_tree_nodes.mark(node, node + 1 + (count > 1 ? count : 0));
  }
}

void SceneCompiler::note_light(const Scene& scene, uint32_t index) {
  if (lights_noted_.size() <= index) lights_noted_.resize(index + 1, 0);
  const Light& l = scene.lights()[index];
  const bool off = !punctual_light_traceable(l);
  if (off && !lights_noted_[index]) {
    log_warning((scene.source.empty() ? std::string() : scene.source + ": ") + "light " +
                std::to_string(index) + " ('" + l.name.substr(0, 80) +
                "') is not finite, out of range or brighter than can be rendered: it is off");
  }
  lights_noted_[index] = off;
}

void SceneCompiler::compile_lights(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  out.lights.clear();
  std::vector<double>& power = light_power_;
  power.clear();
  const float radius = light_radius(scene_bounds(scene));
  lights_radius_ = radius;

  for (const Light& l : scene.lights()) {
    note_light(scene, uint32_t(out.lights.size()));
    const KLight k = punctual_light(l);
    power.push_back(punctual_power(k, radius));
    out.lights.push_back(k);
  }

  out.constants.environment_light_index = kInvalidIndex;
  const float env_lum = environment_luminance(out.constants.environment);
  if (env_lum > 0.0f) {
    KLight k{};
    k.type = kLightEnvironment;
    out.constants.environment_light_index = uint32_t(out.lights.size());
    out.lights.push_back(k);
    power.push_back(environment_power(env_lum, radius));
  }

  // The meshes' triangle lights (and trees), then one light per instance
  // of a mesh that has some.
  compile_mesh_lights(out, delta);
  const KernelData kd = out.view();
  out.instance_lights.assign(out.instances.size(), kInvalidIndex);
  emissive_mesh_instances_.assign(out.meshes.size(), {});
  for (uint32_t i = 0; i < out.instances.size(); ++i) {
    const uint32_t mesh = out.instances[i].mesh;
    if (out.mesh_lights[mesh].count == 0) continue;
    emissive_mesh_instances_[mesh].push_back(i);
    const double pw = instance_light_power(kd, out.instances[i]);
    if (!(pw > 0.0)) continue;
    KLight k{};
    k.type = kLightMeshInstance;
    k.instance = i;
    k.power = float(pw);
    out.instance_lights[i] = uint32_t(out.lights.size());
    out.lights.push_back(k);
    power.push_back(pw);
  }
  finish_light_tables(out, delta);
  delta.instance_lights.reallocated = true;
  delta.lights.reallocated = true;
}

void SceneCompiler::update_light_powers(const Scene& scene, KernelScene& out, SceneDelta& delta,
                                        std::vector<uint32_t>& changed) {
  const float radius = light_radius(scene_bounds(scene));
  lights_radius_ = radius;
  std::vector<uint32_t> dirty = scene.dirty_lights();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    note_light(scene, i);
    out.lights[i] = punctual_light(scene.lights()[i]);
    delta.lights.mark(i, i + 1);
    changed.push_back(i);
  }
  // Directional powers follow the radius: all punctual lights, never the
  // (many) instance lights after them.
  for (uint32_t i = 0; i < scene.lights().size(); ++i)
    light_power_[i] = punctual_power(out.lights[i], radius);
  const uint32_t env = out.constants.environment_light_index;
  if (env != kInvalidIndex) {
    light_power_[env] = environment_power(environment_luminance(out.constants.environment), radius);
  }
}

bool SceneCompiler::update_instance_lights(KernelScene& out, SceneDelta& delta,
                                           const std::vector<uint32_t>& instances,
                                           std::vector<uint32_t>& changed) {
  if (out.instance_lights.size() != out.instances.size()) return false;
  const KernelData kd = out.view();
  for (uint32_t i : instances) {
    const uint32_t light = out.instance_lights[i];
    const KInstance& inst = out.instances[i];
    const bool emissive = out.mesh_lights[inst.mesh].count > 0;
    const double pw = emissive ? instance_light_power(kd, inst) : 0.0;
    // A light that appears, vanishes or changes mesh changes the list.
    if ((light == kInvalidIndex) != !(pw > 0.0)) return false;
    if (light == kInvalidIndex) continue;
    if (out.lights[light].instance != i) return false;
    light_power_[light] = pw;
    out.lights[light].power = float(pw);
    delta.lights.mark(light, light + 1);
    changed.push_back(light);
  }
  return true;
}

// Directional and environment light powers scale with the scene's size,
// which bodies moving about change a little every frame. The powers only
// steer light selection (the alias table and total_light_power are rebuilt
// together, so pdfs stay consistent), so they are refreshed only when the
// size changed by more than 10%.
bool SceneCompiler::scene_size_changed(const Scene& scene) {
  return std::fabs(light_radius(scene_bounds(scene)) - lights_radius_) > 0.1f * lights_radius_;
}

}  // namespace tandem
