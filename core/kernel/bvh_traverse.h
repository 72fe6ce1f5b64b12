// Closest-hit and any-hit traversal of Tandem's own two-level BVH
// (core/kernel/bvh.h), for both the binary and the 8-wide compressed layout.
// Host/device code: no recursion, fixed-size stacks, no allocation.
//
// The TLAS is traversed in world space; at an instance leaf the ray is moved
// into the instance's object space with world_to_object and the mesh's BLAS
// is traversed with its own stack. The direction is not renormalised, so t
// is the same parameter in both spaces and the closest distance found so far
// simply carries over. Results follow Embree's conventions (prim = triangle
// index within the mesh, (u, v) = barycentrics of vertices 1 and 2), so this
// tracer and the Embree backend are interchangeable.
#pragma once

#include "core/kernel/alpha.h"
#include "core/kernel/bvh.h"
#include "core/kernel/bvh_intersect.h"

namespace tandem {

// ---------------------------------------------------------------------------
// Generic traversal loops. A Leaf functor is called once per primitive entry
// of a leaf (an index into the layout's primitive array):
//   bool leaf(uint32_t entry, float* tmax);
// It may shrink *tmax (closest hit) and returns true to stop the traversal
// (any hit found).

template <class Leaf>
TANDEM_HD bool traverse_binary(const KBvhNode* nodes, uint32_t root, const BoxRay& ray, float tmin,
                               float* tmax, Leaf& leaf) {
  uint32_t stack[kBvhStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  for (;;) {
    const KBvhNode n = nodes[node_index];
    float t0, t1;
    bool hit0 = intersect_box(ray, make_vec3(n.c0_xy.x, n.c0_xy.z, n.c01_z.x),
                              make_vec3(n.c0_xy.y, n.c0_xy.w, n.c01_z.y), tmin, *tmax, &t0);
    bool hit1 = intersect_box(ray, make_vec3(n.c1_xy.x, n.c1_xy.z, n.c01_z.z),
                              make_vec3(n.c1_xy.y, n.c1_xy.w, n.c01_z.w), tmin, *tmax, &t1);
    // Leaves are handled right away; only interior children are descended.
    for (uint32_t c = 0; c < 2; ++c) {
      const bool hit = c == 0 ? hit0 : hit1;
      if (!hit || !(n.child[c] & kBvhLeafFlag)) continue;
      const uint32_t first = n.child[c] & ~kBvhLeafFlag;
      for (uint32_t i = 0; i < n.count[c]; ++i) {
        if (leaf(first + i, tmax)) return true;
      }
      if (c == 0)
        hit0 = false;
      else
        hit1 = false;
    }
    if (hit0 && hit1) {
      // Nearer child first; the other waits on the stack.
      const bool swap = t1 < t0;
      node_index = swap ? n.child[1] : n.child[0];
      if (sp < kBvhStackSize) stack[sp++] = swap ? n.child[0] : n.child[1];
    } else if (hit0) {
      node_index = n.child[0];
    } else if (hit1) {
      node_index = n.child[1];
    } else {
      if (sp == 0) return false;
      node_index = stack[--sp];
    }
  }
}

// Decoded child box of a wide node, in float exactly as the builder checked.
TANDEM_HD void wide_child_box(const KWideBvhNode& n, Vec3 scale, uint32_t slot, Vec3* lo,
                              Vec3* hi) {
  *lo = make_vec3(n.origin.x + float(n.qlo[0][slot]) * scale.x,
                  n.origin.y + float(n.qlo[1][slot]) * scale.y,
                  n.origin.z + float(n.qlo[2][slot]) * scale.z);
  *hi = make_vec3(n.origin.x + float(n.qhi[0][slot]) * scale.x,
                  n.origin.y + float(n.qhi[1][slot]) * scale.y,
                  n.origin.z + float(n.qhi[2][slot]) * scale.z);
}

// Wide traversal after Ylitie et al. 2017: a stack of node groups. A group is
// (child_base, hits | imask): bits 24..31 of hits are the interior children
// still to visit, at position (slot ^ octant) so the lowest bit is the
// (approximately) nearest child; bits 0..7 repeat the node's imask to find
// the child's index. Leaf primitives are tested as soon as their node is.
template <class Leaf>
TANDEM_HD bool traverse_wide(const KWideBvhNode* nodes, uint32_t root, const BoxRay& ray,
                             float tmin, float* tmax, Leaf& leaf) {
  uint32_t stack_base[kBvhStackSize];
  uint32_t stack_bits[kBvhStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  for (;;) {
    const KWideBvhNode& n = nodes[node_index];
    const Vec3 scale = {wide_node_scale(n, 0), wide_node_scale(n, 1), wide_node_scale(n, 2)};
    uint32_t node_hits = 0, prim_hits = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t meta = n.meta[s];
      if (meta == 0) continue;
      Vec3 lo, hi;
      wide_child_box(n, scale, s, &lo, &hi);
      float t_entry;
      if (!intersect_box(ray, lo, hi, tmin, *tmax, &t_entry)) continue;
      if ((n.imask >> s) & 1u)
        node_hits |= 1u << (24u + (s ^ ray.octant));
      else
        prim_hits |= (meta >> 5) << (meta & 31u);
    }
    if (node_hits != 0 && sp < kBvhStackSize) {
      stack_base[sp] = n.child_base;
      stack_bits[sp] = node_hits | n.imask;
      ++sp;
    }
    const uint32_t prim_base = n.prim_base;
    while (prim_hits != 0) {
      const uint32_t p = count_trailing_zeros(prim_hits);
      prim_hits &= prim_hits - 1u;
      if (leaf(prim_base + p, tmax)) return true;
    }
    // Next node: the nearest remaining child of the innermost group.
    if (sp == 0) return false;
    uint32_t& bits = stack_bits[sp - 1];
    const uint32_t pos = count_trailing_zeros(bits >> 24);
    bits &= ~(1u << (24u + pos));
    const uint32_t slot = pos ^ ray.octant;
    const uint32_t imask = bits & 0xffu;
    node_index = stack_base[sp - 1] + popcount(imask & ((1u << slot) - 1u));
    if ((bits >> 24) == 0) --sp;
  }
}

// ---------------------------------------------------------------------------
// Leaf functors.

// Triangles of one instance's mesh, ray in object space.
struct BvhTriangleLeaf {
  const KernelData* kd;
  const uint32_t* prim_indices;
  const KMesh* mesh;
  uint32_t instance;
  uint32_t alpha_key;
  bool any_hit;
  bool alpha_test;
  ShearRay ray;
  float tmin;
  Hit* hit;

  TANDEM_HD bool operator()(uint32_t entry, float* tmax) {
    const uint32_t prim = prim_indices[entry];
    const KTriangle tri = kd->triangles[mesh->triangle_offset + prim];
    const Vec3* pos = kd->positions + mesh->vertex_offset;
    TriangleHit th;
    if (!intersect_triangle_watertight(ray, pos[tri.v0], pos[tri.v1], pos[tri.v2], tmin, *tmax,
                                       &th)) {
      return false;
    }
    if (alpha_test && !alpha_test_opaque(*kd, instance, prim, th.u, th.v, alpha_key)) return false;
    *tmax = th.t;
    hit->t = th.t;
    hit->u = th.u;
    hit->v = th.v;
    hit->instance = instance;
    hit->prim = prim;
    return any_hit;
  }
};

// Instances of the TLAS, ray in world space: descends into the BLAS.
struct BvhInstanceLeaf {
  const KernelData* kd;
  const uint32_t* prim_indices;
  uint32_t layout;
  uint32_t alpha_key;
  bool any_hit;
  Ray world_ray;
  Hit* hit;

  TANDEM_HD bool operator()(uint32_t entry, float* tmax) {
    const uint32_t instance = prim_indices[entry];
    const KInstance& inst = kd->instances[instance];
    const KMesh& mesh = kd->meshes[inst.mesh];
    const uint32_t root = layout == kBvhLayoutWide ? mesh.wide_root : mesh.bvh_root;
    if (root == kInvalidIndex) return false;
    // Subtract the instance's translation first and then apply the inverse
    // linear part: far more accurate than world_to_object's own translation
    // column, which the inversion rounds relative to the (large) world
    // coordinates.
    const Vec3 translation = {inst.object_to_world.rows[0].w, inst.object_to_world.rows[1].w,
                              inst.object_to_world.rows[2].w};
    const Vec3 o = transform_vector(inst.world_to_object, world_ray.origin - translation);
    const Vec3 d = transform_vector(inst.world_to_object, world_ray.dir);
    const BoxRay box_ray = make_box_ray(o, d);
    BvhTriangleLeaf tri_leaf{kd,
                             nullptr,
                             &mesh,
                             instance,
                             alpha_key,
                             any_hit,
                             (mesh.flags & kMeshHasAlphaTest) != 0u,
                             make_shear_ray(o, d),
                             world_ray.tmin,
                             hit};
    if (layout == kBvhLayoutWide) {
      tri_leaf.prim_indices = kd->bvh_wide_prim_indices;
      return traverse_wide(kd->bvh_wide_nodes, root, box_ray, world_ray.tmin, tmax, tri_leaf);
    }
    tri_leaf.prim_indices = kd->bvh_prim_indices;
    return traverse_binary(kd->bvh_nodes, root, box_ray, world_ray.tmin, tmax, tri_leaf);
  }
};

// ---------------------------------------------------------------------------
// Queries.

// Closest (any_hit = false) or any (any_hit = true) hit along the ray in the
// given layout. Returns a miss when the scene has no BVH.
TANDEM_HD Hit bvh_trace(const KernelData& kd, const Ray& ray, uint32_t alpha_key, uint32_t layout,
                        bool any_hit) {
  Hit hit = make_miss();
  const bool wide = layout == kBvhLayoutWide;
  const uint32_t root = wide ? kd.constants.tlas_wide_root : kd.constants.tlas_root;
  if (root >= (wide ? kd.bvh_wide_nodes_count : kd.bvh_nodes_count)) return hit;
  float tmax = ray.tmax;
  BvhInstanceLeaf leaf{
      &kd, wide ? kd.bvh_wide_prim_indices : kd.bvh_prim_indices, layout, alpha_key, any_hit, ray,
      &hit};
  const BoxRay box_ray = make_box_ray(ray.origin, ray.dir);
  if (wide)
    traverse_wide(kd.bvh_wide_nodes, root, box_ray, ray.tmin, &tmax, leaf);
  else
    traverse_binary(kd.bvh_nodes, root, box_ray, ray.tmin, &tmax, leaf);
  return hit;
}

TANDEM_HD Hit bvh_intersect(const KernelData& kd, const Ray& ray, uint32_t alpha_key,
                            uint32_t layout) {
  return bvh_trace(kd, ray, alpha_key, layout, false);
}

TANDEM_HD bool bvh_occluded(const KernelData& kd, const Ray& ray, uint32_t alpha_key,
                            uint32_t layout) {
  return hit_valid(bvh_trace(kd, ray, alpha_key, layout, true));
}

// The kernel Tracer (see integrator.h) over Tandem's BVH, in the layout
// selected by kd.constants.bvh_layout.
struct BvhTracer {
  const KernelData* kd;
  TANDEM_HD Hit intersect(const Ray& ray, uint32_t alpha_key) const {
    return bvh_intersect(*kd, ray, alpha_key, kd->constants.bvh_layout);
  }
  TANDEM_HD bool occluded(const Ray& ray, uint32_t alpha_key) const {
    return bvh_occluded(*kd, ray, alpha_key, kd->constants.bvh_layout);
  }
};

}  // namespace tandem
