// Light sampling for next-event estimation. The light list holds punctual
// lights, the environment and one entry per instance of an emissive mesh;
// an instance's light is one of its mesh's triangles (KMeshLights), chosen
// in a second step, so a mesh instanced a thousand times has a thousand
// entries and its triangles once. Two samplers choose
// (RenderSettings::light_sampler):
//   power  an alias table by power over the list, then the mesh's own table
//          by power: O(1), blind to where the shading point is;
//   tree   the finite lights (instances, points, spots) by the light tree
//          (light_tree.h), an instance then by its mesh's tree in object
//          space, which prefer lights near the point and facing it; the
//          infinite ones (directional, environment) by the alias table, each
//          group with its share of the power.
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

// Picks an entry of an alias table with one uniform number; in *u_rest
// (when asked) what is left of u, uniform in [0, 1) again.
TANDEM_HD uint32_t alias_sample(const KAliasEntry* table, uint32_t n, float u, float* pmf,
                                float* u_rest = nullptr) {
  const float scaled = u * float(n);
  uint32_t i = min_u(uint32_t(scaled), n - 1);
  const float frac = scaled - float(i);
  const float threshold = table[i].threshold;
  const bool kept = frac < threshold;
  if (u_rest) {
    const float rest = kept ? frac / threshold : (frac - threshold) / (1.0f - threshold);
    *u_rest = min_f(max_f(rest, 0.0f), 0x1.fffffep-1f);
  }
  if (!kept) i = table[i].alias;
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

// Point p and receiver normal n (unit, or zero) in the object space of
// `inst`, where its mesh's light tree is: n goes by the transpose of the
// instance's linear part, which keeps the sign of its dot product with any
// object-space direction as the world-space one has (the side a light is
// on), and the front of a triangle (its winding) is the same side in both.
TANDEM_HD_INLINE void instance_light_frame(const KInstance& inst, Vec3 p, Vec3 n, Vec3* p_object,
                                           Vec3* n_object) {
  if (inst.flags & kInstanceIdentity) {
    *p_object = p;
    *n_object = n;
    return;
  }
  *p_object = transform_point(inst.world_to_object, p);
  const Vec3 m = transform_normal(inst.object_to_world, n);
  const float len2 = length_sq(m);
  *n_object = len2 > 0.0f ? m * (1.0f / sqrtf(len2)) : make_vec3(0.0f);
}

// What select_light chose: `light` in kd.lights, and for an instance of an
// emissive mesh `triangle` in kd.triangle_lights; `pmf` the probability of
// the whole choice (0: no light).
struct LightChoice {
  uint32_t light;
  uint32_t triangle;
  float pmf;
};

// Chooses the light to sample at point p (n: its unit normal, which the
// tree weighs lights by, or zero) with one uniform number u.
TANDEM_HD LightChoice select_light(const KernelData& kd, Vec3 p, Vec3 n, float u) {
  LightChoice c{0xffffffffu, 0xffffffffu, 0.0f};
  const float tree = kd.constants.light_tree_fraction;
  float u_rest = 0.0f;
  if (tree > 0.0f && u < tree) {
    c.light = light_tree_sample_at(kd.light_tree_nodes, kd.constants.light_tree_root, p, n,
                                   min_f(u / tree, 0x1.fffffep-1f), &c.pmf, &u_rest);
    c.pmf *= tree;
  } else {
    // With the tree, the infinite lights' table (the finite ones have no
    // share of it).
    if (tree > 0.0f) u = min_f((u - tree) / (1.0f - tree), 0x1.fffffep-1f);
    c.light = alias_sample(kd.light_alias, kd.light_alias_count, u, &c.pmf, &u_rest);
  }
  if (!(c.pmf > 0.0f) || kd.lights[c.light].type != kLightMeshInstance) return c;
  // One of the instance's triangles: by its mesh's tree or table.
  const KInstance& inst = kd.instances[kd.lights[c.light].instance];
  const KMeshLights& ml = kd.mesh_lights[inst.mesh];
  float pmf;
  if (tree > 0.0f) {
    Vec3 p_object, n_object;
    instance_light_frame(inst, p, n, &p_object, &n_object);
    c.triangle = light_tree_sample_at(kd.light_tree_nodes, ml.tree_root, p_object, n_object, u_rest,
                                      &pmf, &u_rest);
  } else {
    c.triangle =
        ml.first + alias_sample(kd.triangle_light_alias + ml.first, ml.count, u_rest, &pmf);
  }
  c.pmf *= pmf;
  return c;
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

// The index in kd.triangle_lights of triangle `prim` of the mesh whose
// lights are `ml`, or kInvalidIndex: its lights are its emissive triangles
// in order, found by bisection.
TANDEM_HD uint32_t mesh_triangle_light(const KernelData& kd, const KMeshLights& ml, uint32_t prim) {
  uint32_t lo = ml.first, hi = ml.first + ml.count;
  while (lo < hi) {
    const uint32_t mid = lo + (hi - lo) / 2;
    const uint32_t mid_prim = kd.triangle_lights[mid].prim;
    if (mid_prim == prim) return mid;
    if (mid_prim < prim) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return kInvalidIndex;
}

// The probability that select_light at `ref` (normal `n`) chooses triangle
// `prim` of `instance`: the same products of the same numbers.
TANDEM_HD float triangle_light_pmf(const KernelData& kd, uint32_t instance, uint32_t prim, Vec3 ref,
                                   Vec3 n) {
  if (instance >= kd.instance_lights_count) return 0.0f;
  const uint32_t light = kd.instance_lights[instance];
  if (light == kInvalidIndex) return 0.0f;
  const KInstance& inst = kd.instances[instance];
  const KMeshLights& ml = kd.mesh_lights[inst.mesh];
  const uint32_t triangle = mesh_triangle_light(kd, ml, prim);
  if (triangle == kInvalidIndex) return 0.0f;
  const float tree = kd.constants.light_tree_fraction;
  if (!(tree > 0.0f)) return kd.light_alias[light].pdf * kd.triangle_light_alias[triangle].pdf;
  float pmf = light_tree_pmf_at(kd.light_tree_nodes, kd.constants.light_tree_root,
                                kd.light_tree_trails[light], light, ref, n) *
              tree;
  if (!(pmf > 0.0f)) return 0.0f;
  Vec3 p_object, n_object;
  instance_light_frame(inst, ref, n, &p_object, &n_object);
  return pmf * light_tree_pmf_at(kd.light_tree_nodes, ml.tree_root,
                                 kd.triangle_light_trails[triangle], triangle, p_object, n_object);
}

// Density (solid angle, including selection) with which sample_light at
// `ref` (normal `ref_normal`) picks the point `sp_light` of the emissive
// triangle `hit` found, seen from distance `dist` along direction `wi`
// (unit, from the shading point to the light).
TANDEM_HD float triangle_light_pdf(const KernelData& kd, const Hit& hit,
                                   const SurfacePoint& sp_light, Vec3 wi, float dist, Vec3 ref,
                                   Vec3 ref_normal) {
  const float pmf = triangle_light_pmf(kd, hit.instance, hit.prim, ref, ref_normal);
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

// Triangle `prim` of mesh `mesh` as a triangle light: what make_light_point
// computes for it at an identity instance, with the same float operations
// in the same order (so a cached sample has the same bits as one computed
// from the triangle). Host code calls this whenever the mesh's lights are
// built or it deforms.
TANDEM_HD KTriangleLight cache_triangle_light(const KernelData& kd, uint32_t mesh, uint32_t prim) {
  const TriangleVertices tv = fetch_triangle(kd, mesh, prim);
  KTriangleLight light;
  light.prim = prim;
  light.material = tv.tri.material;
  light.p0 = tv.p0;
  light.p1 = tv.p1;
  light.p2 = tv.p2;
  // An identity instance has handedness +1: make_light_point's product with
  // it leaves the bits as they are.
  const Vec3 ng_raw = cross(tv.p1 - tv.p0, tv.p2 - tv.p0);
  const float ng_len = length(ng_raw);
  light.area = 0.5f * ng_len;
  light.normal = ng_len > 0.0f ? ng_raw * (1.0f / ng_len) : make_vec3(0.0f, 0.0f, 1.0f);
  light.power = triangle_light_power(kd.materials[light.material], light.area);
  return light;
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

// sample_light's triangle branch from the cached constants of `light`, of
// an identity instance (object space is world space) of mesh `mesh`: the
// same bits as the branch through make_light_point, without the triangle
// fetch, the edges, the normal and the area.
TANDEM_HD bool sample_cached_triangle_light(const KernelData& kd, const KTriangleLight& light,
                                            uint32_t mesh, Vec3 ref, Vec2 b, float pmf,
                                            LightSample* out) {
  const float w = 1.0f - b.x - b.y;
  const Vec3 position = light.p0 * w + light.p1 * b.x + light.p2 * b.y;
  const KMaterial& m = kd.materials[light.material];
  if (!triangle_light_sample_towards(ref, position, light.normal, light.area, pmf, m, out)) {
    return false;
  }
  Vec2 uv[2] = {make_vec2(0.0f, 0.0f), make_vec2(0.0f, 0.0f)};
  if (m.emissive_tex.texture >= 0) {
    const KMesh& km = kd.meshes[mesh];
    interpolate_uvs(kd, km, kd.triangles[km.triangle_offset + light.prim], b.x, b.y, uv);
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
  const LightChoice choice = select_light(kd, ref, ref_normal, u_select);
  const float pmf = choice.pmf;
  if (!(pmf > 0.0f)) return false;
  // By reference: the copy was 15 instructions of a Cornell-box light sample.
  const KLight& light = kd.lights[choice.light];
  if (delta_only && (light.type == kLightMeshInstance || light.type == kLightEnvironment)) {
    return false;
  }
  out->is_delta = false;
  out->at_infinity = false;

  if (light.type == kLightMeshInstance) {
    const KTriangleLight& tl = kd.triangle_lights[choice.triangle];
    const KInstance& inst = kd.instances[light.instance];
    const Vec2 b = sample_triangle_barycentrics(u1, u2);
    if (inst.flags & kInstanceIdentity) {
      return sample_cached_triangle_light(kd, tl, inst.mesh, ref, b, pmf, out);
    }
    const SurfacePoint lp = make_light_point(kd, light.instance, tl.prim, b.x, b.y);
    const KMaterial& m = kd.materials[lp.material];
    if (!triangle_light_sample_towards(ref, lp.position, lp.front_normal, lp.area_world, pmf, m,
                                       out)) {
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
