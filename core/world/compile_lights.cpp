// Lights: punctual lights, the environment light and one light per
// emissive (instance, triangle), and what chooses among them: the alias
// table by power, or (the tree sampler) the light tree over the finite
// lights beside an alias table of the infinite ones. A full build walks the
// emissive triangles; a change of punctual lights or of the scene's size
// (which scales directional and environment powers) only recomputes those
// powers and the tables.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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

// What the light tree knows of light `index` (finite, of the given power):
// where it is and which way it emits, in world space.
LightTreeInput light_tree_input(const KernelData& kd, uint32_t index, float power) {
  const KLight& l = kd.lights[index];
  LightTreeInput in;
  in.light = index;
  in.power = power;
  const auto vec = [](Vec3 v) { return glm::vec3(v.x, v.y, v.z); };
  if (l.type == kLightTriangle) {
    const KInstance& inst = kd.instances[l.instance];
    const TriangleVertices tv = fetch_triangle(kd, inst.mesh, l.prim);
    const glm::vec3 p[3] = {vec(instance_point(inst, tv.p0)), vec(instance_point(inst, tv.p1)),
                            vec(instance_point(inst, tv.p2))};
    in.lo = glm::min(p[0], glm::min(p[1], p[2]));
    in.hi = glm::max(p[0], glm::max(p[1], p[2]));
    // The side it emits to: make_light_point's front normal.
    in.axis = vec(make_light_point(kd, l.instance, l.prim, 0.0f, 0.0f).front_normal);
    in.cos_theta_o = 1.0f;
    in.cos_theta_e = 0.0f;
    in.two_sided = (kd.materials[l.material].flags & kMaterialDoubleSided) != 0;
    return in;
  }
  in.lo = in.hi = vec(l.position);
  if (l.type == kLightSpot) {
    // No light beyond the outer cone.
    in.axis = vec(l.direction);
    in.cos_theta_o = l.cos_outer;
    in.cos_theta_e = 1.0f;
  } else {
    in.cos_theta_o = -1.0f;  // every direction
    in.cos_theta_e = 1.0f;
  }
  return in;
}

}  // namespace

void SceneCompiler::finish_light_tables(KernelScene& out, SceneDelta& delta) {
  const std::vector<double>& power = light_power_;
  double total = 0.0, finite = 0.0;
  for (size_t i = 0; i < power.size(); ++i) {
    total += power[i];
    if (!light_at_infinity(out.lights[i])) finite += power[i];
  }
  out.constants.total_light_power = float(total);
  out.constants.light_tree_fraction = 0.0f;
  out.light_tree_nodes.clear();
  out.light_tree_trails.clear();
  if (light_sampler_ == LightSampler::kTree && finite > 0.0) {
    const KernelData kd = out.view();
    std::vector<LightTreeInput> inputs;
    std::vector<double> infinite(power.size(), 0.0);
    for (uint32_t i = 0; i < power.size(); ++i) {
      if (light_at_infinity(out.lights[i])) {
        infinite[i] = power[i];
      } else if (power[i] > 0.0) {
        inputs.push_back(light_tree_input(kd, i, float(power[i])));
      }
    }
    LightTree tree = build_light_tree(std::move(inputs), uint32_t(power.size()));
    out.light_tree_nodes = std::move(tree.nodes);
    out.light_tree_trails = std::move(tree.trails);
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
  } else {
    out.light_alias = build_alias_table(power);
  }
  delta.light_tree_nodes.reallocated = true;
  delta.light_tree_trails.reallocated = true;
  delta.constants = true;
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
  triangle_powers_stale_ = false;

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

  // Emissive triangles, one light per (instance, triangle). Power comes from
  // the same kernel function the integrator uses for MIS.
  const KernelData kd = out.view();
  out.instance_lights.assign(out.instances.size() + 1, 0);
  emissive_mesh_instances_.assign(out.meshes.size(), {});
  for (uint32_t i = 0; i < out.instances.size(); ++i) {
    const uint32_t mesh_index = out.instances[i].mesh;
    out.instance_lights[i] = uint32_t(out.lights.size());
    out.instance_lights[i + 1] = uint32_t(out.lights.size());
    if (!mesh_emissive_[mesh_index]) continue;
    emissive_mesh_instances_[mesh_index].push_back(i);
    const KMesh& km = out.meshes[mesh_index];
    for (uint32_t p = 0; p < km.triangle_count; ++p) {
      const KMaterial& m = out.materials[out.triangles[km.triangle_offset + p].material];
      if (is_black(m.emission)) continue;
      const float pw = triangle_light_power(m, triangle_world_area(kd, out.instances[i], p));
      if (!(pw > 0.0f)) continue;
      KLight k{};
      k.type = kLightTriangle;
      k.instance = i;
      k.prim = p;
      cache_triangle_light(kd, &k);
      out.lights.push_back(k);
      power.push_back(pw);
    }
    out.instance_lights[i + 1] = uint32_t(out.lights.size());
  }
  delta.instance_lights.reallocated = true;
  finish_light_tables(out, delta);
  delta.lights.reallocated = true;
  delta.light_alias.reallocated = true;
}

void SceneCompiler::update_light_powers(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  const float radius = light_radius(scene_bounds(scene));
  lights_radius_ = radius;
  std::vector<uint32_t> dirty = scene.dirty_lights();
  std::sort(dirty.begin(), dirty.end());
  for (uint32_t i : dirty) {
    note_light(scene, i);
    out.lights[i] = punctual_light(scene.lights()[i]);
    delta.lights.mark(i, i + 1);
  }
  // Directional powers follow the radius: all punctual lights, never the
  // (many) triangle lights after them.
  for (uint32_t i = 0; i < scene.lights().size(); ++i)
    light_power_[i] = punctual_power(out.lights[i], radius);
  const uint32_t env = out.constants.environment_light_index;
  if (env != kInvalidIndex) {
    light_power_[env] = environment_power(environment_luminance(out.constants.environment), radius);
  }
  finish_light_tables(out, delta);
  delta.light_alias.mark(0, uint32_t(out.light_alias.size()));
}

bool SceneCompiler::update_triangle_light_powers(const Scene& scene, KernelScene& out,
                                                 SceneDelta& delta,
                                                 const std::vector<uint32_t>& meshes,
                                                 bool punctual_too) {
  // Rigid moves since the last build changed powers in the last bits: only
  // a full build then gives what a fresh compile would.
  if (triangle_powers_stale_ || out.instance_lights.size() != out.instances.size() + 1 ||
      emissive_mesh_instances_.size() != out.meshes.size() ||
      light_power_.size() != out.lights.size()) {
    return false;
  }
  const KernelData kd = out.view();
  std::vector<float> power;
  for (uint32_t m : meshes) {
    const KMesh& km = out.meshes[m];
    power.resize(km.triangle_count);
    for (uint32_t i : emissive_mesh_instances_[m]) {
      // The same computation as compile_lights(), so the powers (and the
      // alias table built from them) are bit for bit a fresh compile's.
      const KInstance& inst = out.instances[i];
      tbb::parallel_for(tbb::blocked_range<uint32_t>(0, km.triangle_count, 16384), [&](auto r) {
        for (uint32_t p = r.begin(); p < r.end(); ++p) {
          const KMaterial& mat = out.materials[out.triangles[km.triangle_offset + p].material];
          power[p] = is_black(mat.emission)
                         ? 0.0f
                         : triangle_light_power(mat, triangle_world_area(kd, inst, p));
        }
      });
      // The lights of this instance are its triangles of positive power, in
      // order; a triangle that gained or lost all its area changes the list.
      uint32_t light = out.instance_lights[i];
      const uint32_t end = out.instance_lights[i + 1];
      for (uint32_t p = 0; p < km.triangle_count; ++p) {
        if (!(power[p] > 0.0f)) continue;
        if (light == end || out.lights[light].prim != p) return false;
        light_power_[light++] = power[p];
      }
      if (light != end) return false;
      // The cached vertices, normals and areas (and the powers from them)
      // follow the new vertices.
      for (light = out.instance_lights[i]; light < end; ++light)
        cache_triangle_light(kd, &out.lights[light]);
      if (out.instance_lights[i] < end) delta.lights.mark(out.instance_lights[i], end);
    }
  }
  if (punctual_too) {
    update_light_powers(scene, out, delta);
  } else {
    finish_light_tables(out, delta);
    delta.light_alias.mark(0, uint32_t(out.light_alias.size()));
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
