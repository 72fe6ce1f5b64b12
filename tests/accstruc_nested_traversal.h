// The two-level traversal as it was before it became one loop (one stack
// and one loop per level, the BLAS traversed inside the TLAS's leaf
// functor), kept only as the reference the single loop of
// core/kernel/bvh_traverse.h must match exactly: same hits, same bits, same
// traversal counters (accstruc_two_level_test.cpp).
#pragma once

#include "core/kernel/bvh_traverse.h"

namespace tandem::nested_reference {

// ---------------------------------------------------------------------------
// Generic traversal loops. A Leaf functor is called once per primitive entry
// of a leaf (an index into the layout's primitive array):
//   bool leaf(uint32_t entry, float* tmax);
//   void leaf.prefetch(const uint32_t* entries, uint32_t count);  // hint only
// It may shrink *tmax (closest hit) and returns true to stop the traversal
// (any hit found). With kCount, visits and box tests are added to *counters.

template <bool kCount, class Leaf>
TANDEM_HD bool traverse_binary(const KBvhNode* nodes, uint32_t root, const BoxRay& ray, float tmin,
                               float* tmax, Leaf& leaf, BvhCounters* counters) {
  uint32_t stack[kBvhStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  for (;;) {
    const KBvhNode n = load_readonly_16(nodes + node_index);
    if constexpr (kCount) {
      counters->nodes += 1;
      counters->boxes += 2;
    }
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
#if !defined(__CUDA_ARCH__)
      uint32_t entries[kBvhMaxLeafEntries];
      const uint32_t count = min_u(n.count[c], kBvhMaxLeafEntries);
      for (uint32_t i = 0; i < count; ++i)
        entries[i] = first + i;
      leaf.prefetch(entries, count);
#endif
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
      const uint32_t far_child = swap ? n.child[0] : n.child[1];
      prefetch_readonly(nodes + far_child);
      if (sp < kBvhStackSize) stack[sp++] = far_child;
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

// Wide traversal after Ylitie et al. 2017: a stack of node groups. A group is
// (child_base, hits | imask): bits 24..31 of hits are the interior children
// still to visit, at position (slot ^ octant) so the lowest bit is the
// (approximately) nearest child; bits 0..7 repeat the node's imask to find
// the child's index. Leaf primitives are tested as soon as their node is.
template <bool kCount, class Leaf>
TANDEM_HD bool traverse_wide(const KWideBvhNode* nodes, uint32_t root, const BoxRay& ray,
                             float tmin, float* tmax, Leaf& leaf, BvhCounters* counters) {
  uint32_t stack_base[kBvhStackSize];
  uint32_t stack_bits[kBvhStackSize];
  uint32_t sp = 0;
  uint32_t node_index = root;
  for (;;) {
    const KWideBvhNode n = load_readonly_16(nodes + node_index);
    if constexpr (kCount) counters->nodes += 1;
    const Vec3 scale = {wide_node_scale(n, 0), wide_node_scale(n, 1), wide_node_scale(n, 2)};
    uint32_t node_hits = 0, prim_hits = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t meta = n.meta[s];
      if (meta == 0) continue;
      if constexpr (kCount) counters->boxes += 1;
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
#if !defined(__CUDA_ARCH__)
    if (prim_hits != 0) {
      uint32_t entries[32];
      uint32_t count = 0;
      for (uint32_t bits = prim_hits; bits != 0; bits &= bits - 1u)
        entries[count++] = prim_base + count_trailing_zeros(bits);
      leaf.prefetch(entries, count);
    }
#endif
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
template <bool kCount>
struct BvhTriangleLeaf {
  const KernelData* kd;
  const uint32_t* prim_indices;
  bool wide_entries;  // prim_indices holds a wide BLAS's entries: binary leaf entries (bvh.h)
  const KMesh* mesh;
  uint32_t instance;
  uint32_t alpha_key;
  bool any_hit;
  bool alpha_test;
  ShearRay ray;
  float tmin;
  Hit* hit;
  BvhCounters* counters;

  // The triangle index of leaf entry `entry`.
  TANDEM_HD uint32_t prim_of(uint32_t entry) const {
    const uint32_t e = load_readonly(prim_indices + entry);
    return wide_entries ? load_readonly(kd->bvh_prim_indices + e) : e;
  }

  // The triangles first, then (once they arrive) their vertices.
  TANDEM_HD void prefetch(const uint32_t* entries, uint32_t count) const {
#if !defined(__CUDA_ARCH__)
    const KTriangle* tris = kd->triangles + mesh->triangle_offset;
    const Vec3* pos = kd->positions + mesh->vertex_offset;
    for (uint32_t i = 0; i < count; ++i)
      prefetch_readonly(tris + prim_of(entries[i]));
    for (uint32_t i = 0; i < count; ++i) {
      const KTriangle& t = tris[prim_of(entries[i])];
      prefetch_readonly(pos + t.v0);
      prefetch_readonly(pos + t.v1);
      prefetch_readonly(pos + t.v2);
    }
#else
    (void)entries;
    (void)count;
#endif
  }

  TANDEM_HD bool operator()(uint32_t entry, float* tmax) {
    const uint32_t prim = prim_of(entry);
    const KTriangle tri = load_readonly(kd->triangles + mesh->triangle_offset + prim);
    const Vec3* pos = kd->positions + mesh->vertex_offset;
    if constexpr (kCount) counters->triangles += 1;
    TriangleHit th;
    if (!intersect_triangle_watertight(ray, load_readonly(pos + tri.v0),
                                       load_readonly(pos + tri.v1), load_readonly(pos + tri.v2),
                                       tmin, *tmax, &th)) {
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
template <bool kCount>
struct BvhInstanceLeaf {
  const KernelData* kd;
  const uint32_t* prim_indices;
  uint32_t layout;
  uint32_t alpha_key;
  bool any_hit;
  Ray world_ray;
  Hit* hit;
  BvhCounters* counters;

  TANDEM_HD void prefetch(const uint32_t* entries, uint32_t count) const {
    (void)entries;
    (void)count;
  }

  TANDEM_HD bool operator()(uint32_t entry, float* tmax) {
    const uint32_t instance = load_readonly(prim_indices + entry);
    const KInstance& inst = kd->instances[instance];
    const KMesh& mesh = kd->meshes[inst.mesh];
    const KBlasRoot& roots = kd->blas_roots[inst.mesh];
    const uint32_t root = layout == kBvhLayoutWide ? roots.wide_root : roots.bvh_root;
    if (root == kInvalidIndex) return false;
    if constexpr (kCount) counters->instances += 1;
    // Subtract the instance's translation first and then apply the inverse
    // linear part: far more accurate than world_to_object's own translation
    // column, which the inversion rounds relative to the (large) world
    // coordinates.
    const Vec3 translation = {inst.object_to_world.rows[0].w, inst.object_to_world.rows[1].w,
                              inst.object_to_world.rows[2].w};
    const Vec3 o = transform_vector(inst.world_to_object, world_ray.origin - translation);
    const Vec3 d = transform_vector(inst.world_to_object, world_ray.dir);
    const BoxRay box_ray = make_box_ray(o, d);
    BvhTriangleLeaf<kCount> tri_leaf{kd,
                                     nullptr,
                                     false,
                                     &mesh,
                                     instance,
                                     alpha_key,
                                     any_hit,
                                     (mesh.flags & kMeshHasAlphaTest) != 0u,
                                     make_shear_ray(o, d),
                                     world_ray.tmin,
                                     hit,
                                     counters};
    uint64_t nodes_before = 0;
    if constexpr (kCount) nodes_before = counters->nodes;
    bool stop;
    if (layout == kBvhLayoutWide) {
      tri_leaf.prim_indices = kd->bvh_wide_prim_indices;
      tri_leaf.wide_entries = true;
      stop = traverse_wide<kCount>(kd->bvh_wide_nodes, root, box_ray, world_ray.tmin, tmax,
                                   tri_leaf, counters);
    } else {
      tri_leaf.prim_indices = kd->bvh_prim_indices;
      tri_leaf.wide_entries = false;
      stop = traverse_binary<kCount>(kd->bvh_nodes, root, box_ray, world_ray.tmin, tmax, tri_leaf,
                                     counters);
    }
    if constexpr (kCount) counters->blas_nodes += counters->nodes - nodes_before;
    return stop;
  }
};

// ---------------------------------------------------------------------------
// Queries.

// Closest (any_hit = false) or any (any_hit = true) hit along the ray in the
// given layout. Returns a miss when the scene has no BVH. With kCount the
// query's traversal work is added to *counters.
template <bool kCount>
TANDEM_HD Hit nested_trace_counted(const KernelData& kd, const Ray& ray, uint32_t alpha_key,
                                   uint32_t layout, bool any_hit, BvhCounters* counters) {
  Hit hit = make_miss();
  const bool wide = layout == kBvhLayoutWide;
  const uint32_t root = wide ? kd.bvh.tlas_wide_root : kd.bvh.tlas_root;
  if (root >= (wide ? kd.bvh_wide_nodes_count : kd.bvh_nodes_count)) return hit;
  float tmax = ray.tmax;
  BvhInstanceLeaf<kCount> leaf{&kd,     wide ? kd.bvh_wide_prim_indices : kd.bvh_prim_indices,
                               layout,  alpha_key,
                               any_hit, ray,
                               &hit,    counters};
  const BoxRay box_ray = make_box_ray(ray.origin, ray.dir);
  if (wide)
    traverse_wide<kCount>(kd.bvh_wide_nodes, root, box_ray, ray.tmin, &tmax, leaf, counters);
  else
    traverse_binary<kCount>(kd.bvh_nodes, root, box_ray, ray.tmin, &tmax, leaf, counters);
  return hit;
}

}  // namespace tandem::nested_reference
