// Lights: punctual lights, the environment light and one light per
// emissive (instance, triangle), and the alias table that picks among them
// by power. A full build walks the emissive triangles; a change of punctual
// lights or of the scene's size (which scales directional and environment
// powers) only recomputes those powers and the alias table.
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

void finish_light_tables(const std::vector<double>& power, KernelScene& out, SceneDelta& delta) {
  out.light_alias = build_alias_table(power);
  double total = 0.0;
  for (double p : power)
    total += p;
  out.constants.total_light_power = float(total);
  delta.constants = true;
}

}  // namespace

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
  instance_lights_.assign(out.instances.size() + 1, 0);
  emissive_mesh_instances_.assign(out.meshes.size(), {});
  for (uint32_t i = 0; i < out.instances.size(); ++i) {
    const uint32_t mesh_index = out.instances[i].mesh;
    instance_lights_[i] = uint32_t(out.lights.size());
    instance_lights_[i + 1] = uint32_t(out.lights.size());
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
    instance_lights_[i + 1] = uint32_t(out.lights.size());
  }
  finish_light_tables(power, out, delta);
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
  finish_light_tables(light_power_, out, delta);
  delta.light_alias.mark(0, uint32_t(out.light_alias.size()));
}

bool SceneCompiler::update_triangle_light_powers(const Scene& scene, KernelScene& out,
                                                 SceneDelta& delta,
                                                 const std::vector<uint32_t>& meshes,
                                                 bool punctual_too) {
  // Rigid moves since the last build changed powers in the last bits: only
  // a full build then gives what a fresh compile would.
  if (triangle_powers_stale_ || instance_lights_.size() != out.instances.size() + 1 ||
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
      uint32_t light = instance_lights_[i];
      const uint32_t end = instance_lights_[i + 1];
      for (uint32_t p = 0; p < km.triangle_count; ++p) {
        if (!(power[p] > 0.0f)) continue;
        if (light == end || out.lights[light].prim != p) return false;
        light_power_[light++] = power[p];
      }
      if (light != end) return false;
      // The cached vertices, normals and areas (and the powers from them)
      // follow the new vertices.
      for (light = instance_lights_[i]; light < end; ++light)
        cache_triangle_light(kd, &out.lights[light]);
      if (instance_lights_[i] < end) delta.lights.mark(instance_lights_[i], end);
    }
  }
  if (punctual_too) {
    update_light_powers(scene, out, delta);
  } else {
    finish_light_tables(light_power_, out, delta);
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
