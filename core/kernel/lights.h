// Light sampling for next-event estimation. All lights (emissive triangles,
// punctual lights, environment) live in one list. Two samplers choose among
// them (RenderSettings::light_sampler):
//   power  an alias table by power: O(1), blind to where the shading point is;
//   tree   the finite lights (triangles, points, spots) by the light tree
//          (light_tree.h), which prefers lights near the point and facing it,
//          and the infinite ones (directional, environment) by the alias
//          table, each group with its share of the power.
// The probability of choosing a light is recomputed for multiple importance
// sampling where a BSDF sample finds it (triangle_light_pdf,
// environment_light_pdf).
#pragma once

#include "core/kernel/environment.h"
#include "core/kernel/geometry.h"
#include "core/kernel/light_tree.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

struct LightSample {
  Vec3 radiance;  // incident radiance (area/env) or intensity/d^2 (punctual)
  Vec3 wi;        // unit direction from the shading point to the light
  Vec3 point;     // sampled point on the light (finite lights)
  float distance;
  float pdf;  // solid angle density incl. selection (delta lights: selection probability)
  bool is_delta;
  bool at_infinity;
};

// Picks an entry of an alias table with one uniform number.
TANDEM_HD uint32_t alias_sample(const KAliasEntry* table, uint32_t n, float u, float* pmf) {
  const float scaled = u * float(n);
  uint32_t i = min_u(uint32_t(scaled), n - 1);
  const float frac = scaled - float(i);
  if (frac >= table[i].threshold) i = table[i].alias;
  *pmf = table[i].pdf;
  return i;
}

TANDEM_HD Vec3 material_emission(const KernelData& kd, const KMaterial& m, const Vec2 uv[2]) {
  Vec3 e = m.emission;
  if (m.emissive_tex.texture >= 0 && !is_black(e)) {
    const Vec4 t =
        sample_texture(kd, uint32_t(m.emissive_tex.texture), material_uv(m.emissive_tex, uv));
    e = e * xyz(t);
  }
  return e;
}

// Power used to pick an emissive triangle. The host table builder and the
// kernel's MIS both call this, so the selection pmf is known at a BSDF hit
// without a lookup table.
TANDEM_HD float triangle_light_power(const KMaterial& m, float area_world) {
  const float sides = (m.flags & kMaterialDoubleSided) ? 2.0f : 1.0f;
  return luminance(m.emission) * m.emission_luminance_scale * area_world * sides * kPi;
}

TANDEM_HD float triangle_world_area(const KernelData& kd, const KInstance& inst, uint32_t prim) {
  const TriangleVertices tv = fetch_triangle(kd, inst.mesh, prim);
  const Vec3 e1 = instance_vector(inst, tv.p1 - tv.p0);
  const Vec3 e2 = instance_vector(inst, tv.p2 - tv.p0);
  return 0.5f * length(cross(e1, e2));
}

// Whether lights are chosen by the light tree (see the top of this file).
TANDEM_HD_INLINE bool light_tree_on(const KernelData& kd) {
  return kd.constants.light_tree_fraction > 0.0f;
}

// Chooses the light to sample at point p (n: its unit normal, which the
// tree weighs lights by) with one uniform number u: its index, and in *pmf
// the probability of that choice (0, with no light, when the tree finds
// none that can light p).
TANDEM_HD uint32_t select_light(const KernelData& kd, Vec3 p, Vec3 n, float u, float* pmf) {
  const float tree = kd.constants.light_tree_fraction;
  if (tree > 0.0f) {
    if (u < tree) {
      const uint32_t index = light_tree_sample(kd.light_tree_nodes, kd.light_tree_nodes_count, p, n,
                                               min_f(u / tree, 0x1.fffffep-1f), pmf);
      *pmf *= tree;
      return index;
    }
    // The infinite lights' table (the finite ones have no share of it).
    u = min_f((u - tree) / (1.0f - tree), 0x1.fffffep-1f);
  }
  return alias_sample(kd.light_alias, kd.light_alias_count, u, pmf);
}

// The probability of choosing a triangle light of the given power: `tree_pmf`
// (what select_light or triangle_light_tree_pmf gave) with the tree, else its
// share of the power. Both are the same bits whether a light sample or a
// BSDF sample asks.
TANDEM_HD_INLINE float triangle_light_selection(const KernelData& kd, float power, float tree_pmf) {
  if (light_tree_on(kd)) return tree_pmf;
  const float total = kd.constants.total_light_power;
  return total > 0.0f ? power / total : 0.0f;
}

// The solid-angle pdf of a triangle light chosen with probability `pmf`, of
// the given world area (normal: either side's unit normal) towards a point at
// `dist` along wi.
TANDEM_HD float triangle_light_pdf_of(float pmf, float area_world, Vec3 normal, Vec3 wi,
                                      float dist) {
  if (!(pmf > 0.0f) || !(area_world > 0.0f)) return 0.0f;
  const float cos_l = fabsf(dot(wi, normal));
  if (!(cos_l > 0.0f)) return 0.0f;
  return pmf * dist * dist / (cos_l * area_world);
}

// The index in kd.lights of the triangle light of (instance, prim), or
// kInvalidIndex: an instance's triangle lights are its emissive triangles
// in order (instance_lights), found by bisection.
TANDEM_HD uint32_t triangle_light_index(const KernelData& kd, uint32_t instance, uint32_t prim) {
  if (instance + 1 >= kd.instance_lights_count) return kInvalidIndex;
  uint32_t lo = kd.instance_lights[instance], hi = kd.instance_lights[instance + 1];
  while (lo < hi) {
    const uint32_t mid = lo + (hi - lo) / 2;
    const uint32_t mid_prim = kd.lights[mid].prim;
    if (mid_prim == prim) return mid;
    if (mid_prim < prim) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return kInvalidIndex;
}

// The probability that select_light at `ref` (normal `n`) chooses the
// triangle light of (instance, prim) through the tree.
TANDEM_HD float triangle_light_tree_pmf(const KernelData& kd, uint32_t instance, uint32_t prim,
                                        Vec3 ref, Vec3 n) {
  const uint32_t index = triangle_light_index(kd, instance, prim);
  if (index == kInvalidIndex || index >= kd.light_tree_trails_count) return 0.0f;
  return kd.constants.light_tree_fraction *
         light_tree_pmf(kd.light_tree_nodes, kd.light_tree_nodes_count, kd.light_tree_trails[index],
                        index, ref, n);
}

// Density (solid angle, including selection) with which sample_light at
// `ref` (normal `ref_normal`) picks the point `sp_light` of the emissive
// triangle `hit` found, seen from distance `dist` along direction `wi`
// (unit, from the shading point to the light).
TANDEM_HD float triangle_light_pdf(const KernelData& kd, const Hit& hit,
                                   const SurfacePoint& sp_light, Vec3 wi, float dist, Vec3 ref,
                                   Vec3 ref_normal) {
  const KMaterial& m = kd.materials[sp_light.material];
  const float tree_pmf = light_tree_on(kd)
                             ? triangle_light_tree_pmf(kd, hit.instance, hit.prim, ref, ref_normal)
                             : 0.0f;
  const float pmf =
      triangle_light_selection(kd, triangle_light_power(m, sp_light.area_world), tree_pmf);
  return triangle_light_pdf_of(pmf, sp_light.area_world, sp_light.geometric_normal, wi, dist);
}

TANDEM_HD float environment_light_pdf(const KernelData& kd, Vec3 dir) {
  const uint32_t idx = kd.constants.environment_light_index;
  if (idx == kInvalidIndex) return 0.0f;
  return kd.light_alias[idx].pdf * env_pdf(kd, dir);
}
// environment_light_pdf with dir's map coordinates uv = env_map_uv(kd, dir)
// already computed (unused without a map): the same bits.
TANDEM_HD float environment_light_pdf_at(const KernelData& kd, Vec3 dir, Vec2 uv) {
  const uint32_t idx = kd.constants.environment_light_index;
  if (idx == kInvalidIndex) return 0.0f;
  return kd.light_alias[idx].pdf * env_pdf_at(kd, dir, uv);
}

// Whether a surface emits towards direction w (unit, pointing away from it).
// Single-sided materials emit from the front face given by the winding.
TANDEM_HD bool emits_towards(const KMaterial& m, Vec3 front_normal, Vec3 w) {
  return (m.flags & kMaterialDoubleSided) || dot(w, front_normal) > 0.0f;
}
TANDEM_HD bool emits_towards(const KMaterial& m, const SurfacePoint& sp, Vec3 w) {
  return emits_towards(m, sp.front_normal, w);
}

// A triangle light's per-light constants: what make_light_point and
// triangle_light_pdf compute for it at an identity instance, with the same
// float operations in the same order (so a cached sample has the same bits
// as one computed from the triangle). Host code calls this whenever the
// light list is built or the light's mesh deforms.
TANDEM_HD void cache_triangle_light(const KernelData& kd, KLight* light) {
  const TriangleVertices tv = fetch_triangle(kd, kd.instances[light->instance].mesh, light->prim);
  light->material = tv.tri.material;
  light->position = tv.p0;
  light->direction = tv.p1;
  light->intensity = tv.p2;
  // An identity instance has handedness +1: make_light_point's product with
  // it leaves the bits as they are.
  const Vec3 ng_raw = cross(tv.p1 - tv.p0, tv.p2 - tv.p0);
  const float ng_len = length(ng_raw);
  light->area = 0.5f * ng_len;
  light->normal = ng_len > 0.0f ? ng_raw * (1.0f / ng_len) : make_vec3(0.0f, 0.0f, 1.0f);
  light->power = triangle_light_power(kd.materials[light->material], light->area);
}

// A triangle light's sample at `position` of the light (front_normal: the
// side a single-sided material emits to), from both of sample_light's
// triangle branches: direction, distance and pdf into *out; false when
// there is no sample. The radiance is the caller's.
TANDEM_HD bool triangle_light_sample_towards(Vec3 ref, Vec3 position, Vec3 front_normal,
                                             float area_world, float pmf, const KMaterial& m,
                                             LightSample* out) {
  Vec3 d = position - ref;
  const float dist2 = length_sq(d);
  if (!(dist2 > 0.0f)) return false;
  const float dist = sqrtf(dist2);
  d = d * (1.0f / dist);
  if (!emits_towards(m, front_normal, -d)) return false;
  out->pdf = triangle_light_pdf_of(pmf, area_world, front_normal, d, dist);
  if (!(out->pdf > 0.0f) || !is_finite(out->pdf)) return false;
  out->wi = d;
  out->point = position;
  out->distance = dist;
  return true;
}

// sample_light's triangle branch from the cached constants (the instance
// is the identity, so object space is world space): the same bits as the
// branch through make_light_point, without the triangle fetch, the edges,
// the normal and the power. `tree_pmf`: select_light's pmf.
TANDEM_HD bool sample_cached_triangle_light(const KernelData& kd, const KLight& light, Vec3 ref,
                                            Vec2 b, float tree_pmf, LightSample* out) {
  const float w = 1.0f - b.x - b.y;
  const Vec3 position = light.position * w + light.direction * b.x + light.intensity * b.y;
  const KMaterial& m = kd.materials[light.material];
  if (!triangle_light_sample_towards(ref, position, light.normal, light.area,
                                     triangle_light_selection(kd, light.power, tree_pmf), m, out)) {
    return false;
  }
  Vec2 uv[2] = {make_vec2(0.0f, 0.0f), make_vec2(0.0f, 0.0f)};
  if (m.emissive_tex.texture >= 0) {
    const KMesh& mesh = kd.meshes[kd.instances[light.instance].mesh];
    interpolate_uvs(kd, mesh, kd.triangles[mesh.triangle_offset + light.prim], b.x, b.y, uv);
  }
  out->radiance = material_emission(kd, m, uv);
  return true;
}

// delta_only: the integrator's smooth mirrors and glass (bsdf_near_specular),
// where only punctual and directional lights are sampled; an emissive
// triangle or the environment picked there gives no sample (the BSDF sample
// that reaches it carries its full weight instead).
// `ref_normal`: the unit normal at ref (either side), for the tree.
TANDEM_HD bool sample_light(const KernelData& kd, const Vec3& ref, const Vec3& ref_normal,
                            float u_select, float u1, float u2, LightSample* out,
                            bool delta_only = false) {
  if (kd.lights_count == 0) return false;
  float pmf;
  const uint32_t index = select_light(kd, ref, ref_normal, u_select, &pmf);
  if (!(pmf > 0.0f)) return false;
  // By reference: a triangle light reads three of the 64 bytes, and the copy
  // was 15 instructions of a Cornell-box light sample.
  const KLight& light = kd.lights[index];
  if (delta_only && (light.type == kLightTriangle || light.type == kLightEnvironment)) return false;
  out->is_delta = false;
  out->at_infinity = false;

  if (light.type == kLightTriangle) {
    const Vec2 b = sample_triangle_barycentrics(u1, u2);
    if (kd.instances[light.instance].flags & kInstanceIdentity) {
      return sample_cached_triangle_light(kd, light, ref, b, pmf, out);
    }
    const SurfacePoint lp = make_light_point(kd, light.instance, light.prim, b.x, b.y);
    const KMaterial& m = kd.materials[lp.material];
    if (!triangle_light_sample_towards(
            ref, lp.position, lp.front_normal, lp.area_world,
            triangle_light_selection(kd, triangle_light_power(m, lp.area_world), pmf), m, out)) {
      return false;
    }
    out->radiance = material_emission(kd, m, lp.uv);
    return true;
  }

  if (light.type == kLightEnvironment) {
    const EnvSample es = env_sample(kd, u1, u2);
    if (!(es.pdf > 0.0f)) return false;
    out->radiance = es.radiance;
    out->wi = es.dir;
    out->pdf = es.pdf * pmf;
    out->distance = kFloatMax;
    out->at_infinity = true;
    return true;
  }

  out->is_delta = true;
  out->pdf = pmf;
  if (light.type == kLightDirectional) {
    out->wi = -light.direction;
    out->radiance = light.intensity;
    out->distance = kFloatMax;
    out->at_infinity = true;
    return true;
  }
  // Point and spot lights.
  Vec3 d = light.position - ref;
  const float dist2 = length_sq(d);
  if (!(dist2 > 0.0f)) return false;
  const float dist = sqrtf(dist2);
  d = d * (1.0f / dist);
  float falloff = 1.0f;
  if (light.type == kLightSpot) {
    const float cd = dot(-d, light.direction);
    const float range = max_f(light.cos_inner - light.cos_outer, 1e-4f);
    const float t = saturate((cd - light.cos_outer) / range);
    falloff = t * t;
    if (falloff <= 0.0f) return false;
  }
  out->radiance = light.intensity * (falloff / dist2);
  out->wi = d;
  out->point = light.position;
  out->distance = dist;
  return true;
}

TANDEM_KERNEL_END
}  // namespace tandem
