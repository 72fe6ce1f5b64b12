// From a ray hit to a shading point: world-space position, geometric and
// shading normals, texture coordinates, material. Also the self-intersection
// safe ray offset used by every backend.
#pragma once

#include "core/kernel/kernel_data.h"
#include "core/kernel/texture.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

struct SurfacePoint {
  Vec3 position;
  Vec3 geometric_normal;  // world space, unit, from the triangle winding
  Vec3 shading_normal;    // world space, unit, interpolated (+ normal map)
  Vec3 tangent;           // world space, unit, orthogonal to shading_normal
  Vec3 bitangent;         // cross(shading_normal, tangent): the shading frame, built once
  Vec3 front_normal;      // geometric normal of the front face (glTF winding)
  Vec2 uv[2];
  uint32_t material;
  float area_world;  // triangle area in world space (for light pdfs)
};

// Offsets p along the geometric normal so a ray spawned there cannot hit the
// surface it left, using integer ULP steps that scale with |p| (Wachter and
// Binder, "A Fast and Robust Method for Avoiding Self-Intersection", 2019).
TANDEM_HD Vec3 offset_ray_origin(Vec3 p, Vec3 n) {
  const float kOrigin = 1.0f / 32.0f;
  const float kFloatScale = 1.0f / 65536.0f;
  const float kIntScale = 256.0f;
  const int ox = int(kIntScale * n.x), oy = int(kIntScale * n.y), oz = int(kIntScale * n.z);
  const Vec3 pi = {uint_as_float(uint32_t(int(float_as_uint(p.x)) + (p.x < 0 ? -ox : ox))),
                   uint_as_float(uint32_t(int(float_as_uint(p.y)) + (p.y < 0 ? -oy : oy))),
                   uint_as_float(uint32_t(int(float_as_uint(p.z)) + (p.z < 0 ? -oz : oz)))};
  return {fabsf(p.x) < kOrigin ? p.x + kFloatScale * n.x : pi.x,
          fabsf(p.y) < kOrigin ? p.y + kFloatScale * n.y : pi.y,
          fabsf(p.z) < kOrigin ? p.z + kFloatScale * n.z : pi.z};
}

// Spawns a ray leaving a surface point towards dir (on the side dir points to).
TANDEM_HD Ray spawn_ray(const SurfacePoint& sp, Vec3 dir) {
  const Vec3 n = dot(dir, sp.geometric_normal) >= 0.0f ? sp.geometric_normal : -sp.geometric_normal;
  return {offset_ray_origin(sp.position, n), 0.0f, dir, kFloatMax};
}

// Spawns a shadow ray from a surface point to a point on a light. The far end
// is shortened relative to the distance so the light's own triangle never
// counts as an occluder.
TANDEM_HD Ray spawn_shadow_ray(const SurfacePoint& sp, Vec3 target) {
  const Vec3 to = target - sp.position;
  const Vec3 n = dot(to, sp.geometric_normal) >= 0.0f ? sp.geometric_normal : -sp.geometric_normal;
  const Vec3 o = offset_ray_origin(sp.position, n);
  const Vec3 d = target - o;
  const float dist = length(d);
  return {o, 0.0f, d * (1.0f / dist), dist * (1.0f - 1e-4f)};
}

// object_to_world (and its inverse transpose for normals) of an instance,
// skipped for identity instances: x * 1 + y * 0 + z * 0 + 0 is x, so only
// the sign of a zero can differ, and a hit saves four 3x4 products (a
// fifth of make_surface_point's instructions on the Cornell box).
TANDEM_HD_INLINE Vec3 instance_point(const KInstance& inst, Vec3 p) {
  return (inst.flags & kInstanceIdentity) ? p : transform_point(inst.object_to_world, p);
}
TANDEM_HD_INLINE Vec3 instance_vector(const KInstance& inst, Vec3 v) {
  return (inst.flags & kInstanceIdentity) ? v : transform_vector(inst.object_to_world, v);
}
TANDEM_HD_INLINE Vec3 instance_normal(const KInstance& inst, Vec3 n) {
  return (inst.flags & kInstanceIdentity) ? n : transform_normal(inst.world_to_object, n);
}

struct TriangleVertices {
  Vec3 p0, p1, p2;  // object space
  KTriangle tri;
  const KMesh* mesh;
};

TANDEM_HD TriangleVertices fetch_triangle(const KernelData& kd, uint32_t mesh_index,
                                          uint32_t prim) {
  TriangleVertices tv;
  tv.mesh = &kd.meshes[mesh_index];
  tv.tri = kd.triangles[tv.mesh->triangle_offset + prim];
  const uint32_t base = tv.mesh->vertex_offset;
  tv.p0 = kd.positions[base + tv.tri.v0];
  tv.p1 = kd.positions[base + tv.tri.v1];
  tv.p2 = kd.positions[base + tv.tri.v2];
  return tv;
}

TANDEM_HD Vec2 interpolate_uv(const Vec2* uvs, uint32_t base, const KTriangle& t, float u,
                              float v) {
  const Vec2 a = uvs[base + t.v0], b = uvs[base + t.v1], c = uvs[base + t.v2];
  const float w = 1.0f - u - v;
  return {a.x * w + b.x * u + c.x * v, a.y * w + b.y * u + c.y * v};
}

TANDEM_HD Vec2 material_uv(const KTextureRef& ref, const Vec2 uv[2]) {
  return apply_texture_transform(ref, uv[ref.uv_set == 1 ? 1 : 0]);
}

// Base colour * texture (linear RGB + alpha) at a shading point.
TANDEM_HD Vec4 material_base_color(const KernelData& kd, const KMaterial& m, const Vec2 uv[2]) {
  Vec4 c = m.base_color;
  if (m.base_color_tex.texture >= 0) {
    const Vec4 t =
        sample_texture(kd, uint32_t(m.base_color_tex.texture), material_uv(m.base_color_tex, uv));
    c = {c.x * t.x, c.y * t.y, c.z * t.z, c.w * t.w};
  }
  return c;
}

// Texture coordinates of both UV sets at barycentrics (u, v); UV set 1
// falls back to set 0 when a mesh has only one.
TANDEM_HD void interpolate_uvs(const KernelData& kd, const KMesh& mesh, const KTriangle& tri,
                               float u, float v, Vec2 uv[2]) {
  uv[0] = (mesh.flags & kMeshHasUv0) ? interpolate_uv(kd.uv0, mesh.vertex_offset, tri, u, v)
                                     : make_vec2(0, 0);
  uv[1] =
      (mesh.flags & kMeshHasUv1) ? interpolate_uv(kd.uv1, mesh.vertex_offset, tri, u, v) : uv[0];
}

// The part of a shading point that light sampling needs: position, front
// normal, area, material, and the UVs where the material reads them (an
// emissive texture; zero otherwise). Much cheaper than make_surface_point
// (no normal interpolation, tangents or normal maps); inlined, so that
// sample_light does not pay for the fields it never reads.
TANDEM_HD_INLINE SurfacePoint make_light_point(const KernelData& kd, uint32_t instance,
                                               uint32_t prim, float u, float v) {
  const KInstance& inst = kd.instances[instance];
  const TriangleVertices tv = fetch_triangle(kd, inst.mesh, prim);
  SurfacePoint sp;
  const float w = 1.0f - u - v;
  sp.position = instance_point(inst, tv.p0 * w + tv.p1 * u + tv.p2 * v);
  const Vec3 e1 = instance_vector(inst, tv.p1 - tv.p0);
  const Vec3 e2 = instance_vector(inst, tv.p2 - tv.p0);
  const Vec3 ng_raw = cross(e1, e2) * inst.handedness;
  const float ng_len = length(ng_raw);
  sp.area_world = 0.5f * ng_len;
  sp.geometric_normal = ng_len > 0.0f ? ng_raw * (1.0f / ng_len) : make_vec3(0.0f, 0.0f, 1.0f);
  sp.front_normal = sp.geometric_normal;
  sp.shading_normal = sp.geometric_normal;
  sp.tangent = make_vec3(0.0f);
  sp.bitangent = make_vec3(0.0f);
  sp.material = tv.tri.material;
  if (kd.materials[sp.material].emissive_tex.texture >= 0) {
    interpolate_uvs(kd, *tv.mesh, tv.tri, u, v, sp.uv);
  } else {
    sp.uv[0] = sp.uv[1] = make_vec2(0.0f, 0.0f);
  }
  return sp;
}

// Builds the full shading point for a hit. Normals are not flipped towards
// the ray here; the integrator decides sidedness.
TANDEM_HD SurfacePoint make_surface_point(const KernelData& kd, const Hit& hit) {
  const KInstance& inst = kd.instances[hit.instance];
  const TriangleVertices tv = fetch_triangle(kd, inst.mesh, hit.prim);
  const KMesh& mesh = *tv.mesh;
  const uint32_t base = mesh.vertex_offset;
  const float u = hit.u, v = hit.v, w = 1.0f - u - v;

  SurfacePoint sp;
  const Vec3 p_obj = tv.p0 * w + tv.p1 * u + tv.p2 * v;
  // Re-deriving the point from barycentrics is more precise than o + t*d.
  sp.position = instance_point(inst, p_obj);

  const Vec3 e1 = instance_vector(inst, tv.p1 - tv.p0);
  const Vec3 e2 = instance_vector(inst, tv.p2 - tv.p0);
  // Mirrored instances reverse the winding (glTF 3.7.4): undo that so the
  // geometric normal keeps pointing to the mesh's front side.
  const Vec3 ng_raw = cross(e1, e2) * inst.handedness;
  const float ng_len = length(ng_raw);
  sp.area_world = 0.5f * ng_len;
  // Both fields from the value, not one copied from the other: g++ copies
  // a Vec3 field as an 8-byte and a 4-byte load, and the 8-byte one cannot
  // take its value from the two 4-byte stores just made (a store-forwarding
  // stall, a tenth of this function's time on the Cornell box).
  const Vec3 ng = ng_len > 0.0f ? ng_raw * (1.0f / ng_len) : make_vec3(0.0f, 0.0f, 1.0f);
  sp.geometric_normal = ng;
  sp.front_normal = ng;
  sp.material = tv.tri.material;

  interpolate_uvs(kd, mesh, tv.tri, u, v, sp.uv);

  Vec3 ns = ng;
  if (mesh.flags & kMeshHasNormals) {
    const Vec3 n_obj = kd.normals[base + tv.tri.v0] * w + kd.normals[base + tv.tri.v1] * u +
                       kd.normals[base + tv.tri.v2] * v;
    const Vec3 n_world = normalize(instance_normal(inst, n_obj));
    if (length_sq(n_world) > 0.5f && is_finite(n_world)) ns = n_world;
  }
  // Keep the shading normal in the geometric normal's hemisphere: flipped
  // vertex normals would otherwise make the triangle black from both sides.
  if (dot(ns, sp.geometric_normal) < 0.0f) sp.geometric_normal = -sp.geometric_normal;

  Vec3 tangent_hint = normalize(e1);
  float bitangent_sign = 1.0f;
  if (mesh.flags & kMeshHasTangents) {
    const Vec4 t0 = kd.tangents[base + tv.tri.v0], t1 = kd.tangents[base + tv.tri.v1],
               t2 = kd.tangents[base + tv.tri.v2];
    const Vec3 t_obj = xyz(t0) * w + xyz(t1) * u + xyz(t2) * v;
    tangent_hint = normalize(instance_vector(inst, t_obj));
    bitangent_sign = t0.w < 0.0f ? -1.0f : 1.0f;
  } else if (mesh.flags & kMeshHasUv0) {
    // Derive the tangent from the UV parameterisation (dp/du).
    const Vec2 a = kd.uv0[base + tv.tri.v0], b = kd.uv0[base + tv.tri.v1],
               c = kd.uv0[base + tv.tri.v2];
    const float du1 = b.x - a.x, dv1 = b.y - a.y, du2 = c.x - a.x, dv2 = c.y - a.y;
    const float det = du1 * dv2 - dv1 * du2;
    if (fabsf(det) > 1e-20f) {
      const Vec3 dpdu = (e1 * dv2 - e2 * dv1) * (1.0f / det);
      const Vec3 dpdv = (e2 * du1 - e1 * du2) * (1.0f / det);
      if (length_sq(dpdu) > 0.0f) tangent_hint = normalize(dpdu);
      // glTF's v runs down the image, so the normal map's +Y (image up) is
      // -dp/dv; pick the bitangent sign that points that way.
      bitangent_sign = dot(cross(ns, tangent_hint), dpdv) > 0.0f ? -1.0f : 1.0f;
    }
  }
  Frame frame = make_frame(ns, tangent_hint);

  const KMaterial& mat = kd.materials[sp.material];
  if (mat.normal_tex.texture >= 0) {
    const Vec4 t =
        sample_texture(kd, uint32_t(mat.normal_tex.texture), material_uv(mat.normal_tex, sp.uv));
    Vec3 nt = {(t.x * 2.0f - 1.0f) * mat.normal_scale, (t.y * 2.0f - 1.0f) * mat.normal_scale,
               t.z * 2.0f - 1.0f};
    const Vec3 bitangent = frame.b * bitangent_sign;
    Vec3 mapped = normalize(frame.t * nt.x + bitangent * nt.y + frame.n * nt.z);
    if (is_finite(mapped) && length_sq(mapped) > 0.5f && dot(mapped, sp.geometric_normal) > 0.0f) {
      frame = make_frame(mapped, frame.t);
    }
  }
  sp.shading_normal = frame.n;
  sp.tangent = frame.t;
  sp.bitangent = frame.b;
  return sp;
}

TANDEM_KERNEL_END
}  // namespace tandem
