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
TANDEM_KERNEL_BEGIN

// Most entries a binary leaf can have (the builder caps leaves at 16).
constexpr uint32_t kBvhMaxLeafEntries = 16;

// Traversal work of the queries it is passed to, summed over rays: for
// measurement only (tandem bench --accstruc, tests). The traversal takes it
// as a template parameter, so the renderer's instantiation (kCount = false)
// contains no counting code at all.
struct BvhCounters {
  uint64_t nodes = 0;       // nodes visited, TLAS and BLAS
  uint64_t boxes = 0;       // child boxes tested
  uint64_t triangles = 0;   // ray/triangle tests
  uint64_t instances = 0;   // BLAS entered (instance leaves whose mesh has a BVH)
  uint64_t blas_nodes = 0;  // of `nodes`, those visited inside a BLAS
};

// ---------------------------------------------------------------------------
// Loads of the scene arrays. Every array the traversal reads is read-only
// for the whole launch, so on the device the loads go through the read-only
// (non-coherent) path in 16-byte pieces: a wide node is five vector loads
// instead of one load per byte field. On the host a plain copy is the same
// thing.

template <class T>
TANDEM_HD T load_readonly_16(const T* p) {
  static_assert(sizeof(T) % 16 == 0 && alignof(T) >= 16, "16-byte pieces");
#if TANDEM_GPU_CODE
  GpuWord4 words[sizeof(T) / 16];
  const GpuWord4* src = reinterpret_cast<const GpuWord4*>(p);
  TANDEM_GPU_UNROLL
  for (uint32_t i = 0; i < sizeof(T) / 16; ++i)
    words[i] = gpu_load_readonly(src + i);
  T out;
  memcpy(&out, words, sizeof(T));
  return out;
#else
  return *p;
#endif
}

TANDEM_HD uint32_t load_readonly(const uint32_t* p) {
#if TANDEM_GPU_CODE
  return gpu_load_readonly(p);
#else
  return *p;
#endif
}

TANDEM_HD Vec3 load_readonly(const Vec3* p) {
#if TANDEM_GPU_CODE
  const float* f = reinterpret_cast<const float*>(p);
  return make_vec3(gpu_load_readonly(f), gpu_load_readonly(f + 1), gpu_load_readonly(f + 2));
#else
  return *p;
#endif
}

TANDEM_HD KTriangle load_readonly(const KTriangle* p) {
#if TANDEM_GPU_CODE
  const GpuWord4 w = gpu_load_readonly(reinterpret_cast<const GpuWord4*>(p));
  return KTriangle{w.x, w.y, w.z, w.w};
#else
  return *p;
#endif
}

// A binary node in two loads: its children's boxes, and their links (the
// node's last 16 bytes).
struct KBvhNodeBoxes {
  Vec4 c0_xy, c1_xy, c01_z;
};
struct KBvhNodeLinks {
  uint32_t child[2];
  uint32_t count[2];
};
static_assert(offsetof(KBvhNode, child) == sizeof(KBvhNodeBoxes) && sizeof(KBvhNodeLinks) == 16 &&
                  sizeof(KBvhNode) == 64,
              "a node is its boxes, then its links");

TANDEM_HD KBvhNodeBoxes load_node_boxes(const KBvhNode* p) {
#if TANDEM_GPU_CODE
  const GpuWord4* words = reinterpret_cast<const GpuWord4*>(p);
  KBvhNodeBoxes out;
  const GpuWord4 w0 = gpu_load_readonly(words), w1 = gpu_load_readonly(words + 1),
                 w2 = gpu_load_readonly(words + 2);
  memcpy(&out.c0_xy, &w0, 16);
  memcpy(&out.c1_xy, &w1, 16);
  memcpy(&out.c01_z, &w2, 16);
  return out;
#else
  return KBvhNodeBoxes{p->c0_xy, p->c1_xy, p->c01_z};
#endif
}

TANDEM_HD KBvhNodeLinks load_node_links(const KBvhNode* p) {
#if TANDEM_GPU_CODE
  const GpuWord4 w = gpu_load_readonly(reinterpret_cast<const GpuWord4*>(p) + 3);
  return KBvhNodeLinks{{w.x, w.y}, {w.z, w.w}};
#else
  return KBvhNodeLinks{{p->child[0], p->child[1]}, {p->count[0], p->count[1]}};
#endif
}

// Host only: starts fetching a cache line the traversal will read soon. The
// large scenes are bound by memory latency (a triangle test is a chain of
// dependent loads: leaf entry, triangle, vertices), and prefetching a
// whole leaf first lets those chains overlap. A no-op on the device, whose
// latency hiding is other warps.
TANDEM_HD void prefetch_readonly(const void* p) {
#if !TANDEM_GPU_CODE
  __builtin_prefetch(p, 0, 3);
#else
  (void)p;
#endif
}

// ---------------------------------------------------------------------------
// Two-level traversal in one loop.
//
// The TLAS and the BLAS of the instance being visited share one loop and one
// stack: entering an instance moves the ray into object space and notes the
// stack depth (blas_sp); once the BLAS's part of the stack is used up, the
// ray goes back to world space and the TLAS carries on. This is for the GPU:
// with a loop per level (the BLAS loop inside the TLAS's leaf handler) the
// TLAS loop's whole state, its ray included, stays live in registers while
// the BLAS runs, which held the traversal kernels at 89-96 registers. Nodes,
// instances and triangles are visited in exactly the order of a loop per
// level (depth first; the instances of a TLAS leaf in order, each BLAS to its
// end before the next instance), so the hits are the same down to which of
// two equal-t hits wins (accstruc_two_level_test.cpp checks it against the
// nested loops).

// The traversal's memory (its stack frame; on the GPU local memory, which
// the L1 cache serves) holds, besides the stack entries, what the loop needs
// only now and then, so that it does not take registers for the whole loop:
//   - a header: the world ray's direction (read when an instance is entered)
//     and the hit record (written on each closer hit, read at the end);
//   - while a BLAS is traversed, an instance record just below its first
//     stack entry: the world ray's origin (read when the BLAS is left) and
//     what the leaves need (the shear of the watertight test, the mesh's
//     triangle and vertex offsets, the instance).
// The loop itself carries only the box ray, the interval, the stack pointers
// and the node: the traversal kernels then fit 64 registers without spills.
enum BvhFrameWord : uint32_t {
  kFrameWorldDir = 0,  // 3 words
  kFrameHitU = 3,
  kFrameHitV,
  kFrameHitInstance,
  kFrameHitPrim,
  kBvhFrameHeaderWords = 8,  // even: the wide stack's entries are word pairs
};
enum BvhInstanceRecordWord : uint32_t {
  kRecordWorldOrigin = 0,  // 3 words
  kRecordShear = 3,        // sx, sy, sz
  kRecordTriangleOffset = 6,
  kRecordVertexOffset,
  kRecordInstance,
  kRecordBlasFlags,              // KBlasRoot::flags
  kBvhInstanceRecordWords = 10,  // even, as the header
};
// Words of the traversal frame: the header, a TLAS and a BLAS path (each
// under kBvhStackSize levels, up to two words per level), the instance record
// and what one TLAS node leaves pending while one of its instances is visited.
constexpr uint32_t kBvhFrameWords =
    kBvhFrameHeaderWords + 4 * kBvhStackSize + kBvhInstanceRecordWords + 8;
// blas_sp while the loop is in the TLAS.
constexpr uint32_t kBvhInTlas = ~0u;

TANDEM_HD void store_vec3(uint32_t* words, Vec3 v) {
  words[0] = float_as_uint(v.x);
  words[1] = float_as_uint(v.y);
  words[2] = float_as_uint(v.z);
}
TANDEM_HD Vec3 load_vec3(const uint32_t* words) {
  return make_vec3(uint_as_float(words[0]), uint_as_float(words[1]), uint_as_float(words[2]));
}

// The loop's state besides its stack. `box` is the ray in the space the loop
// traverses now: the world ray in the TLAS, the object-space ray in a BLAS,
// where the shear's axes (kx | ky << 2 | kz << 4) ride in bits 8..13 of
// box.octant (the box test reads bits 0..2 only; the wide loop masks with
// octant()).
template <bool kCount>
struct TwoLevelTrace {
  const KernelData* kd;
  uint32_t* frame;  // kBvhFrameWords
  float tmin, tmax;
  uint32_t alpha_key;
  bool any_hit;
  BoxRay box;
  BvhCounters* counters;

  TANDEM_HD uint32_t octant() const { return box.octant & 7u; }

  // Moves the ray into the object space of instance `index` and returns its
  // BLAS root in the layout, or kInvalidIndex when its mesh has nothing to
  // hit (the ray then stays in world space). Fills the instance record.
  TANDEM_HD uint32_t enter_instance(uint32_t index, bool wide, uint32_t* record) {
    const KInstance& inst = kd->instances[index];
    const KBlasRoot& roots = kd->blas_roots[inst.mesh];
    const uint32_t root = wide ? roots.wide_root : roots.bvh_root;
    if (root == kInvalidIndex) return root;
    if constexpr (kCount) counters->instances += 1;
    const KMesh& mesh = kd->meshes[inst.mesh];
    const Vec3 world_origin = box.origin;
    const Vec3 world_dir = load_vec3(frame + kFrameWorldDir);
    // Subtract the instance's translation first and then apply the inverse
    // linear part: far more accurate than world_to_object's own translation
    // column, which the inversion rounds relative to the (large) world
    // coordinates.
    const Vec3 translation = {inst.object_to_world.rows[0].w, inst.object_to_world.rows[1].w,
                              inst.object_to_world.rows[2].w};
    const Vec3 o = transform_vector(inst.world_to_object, world_origin - translation);
    const Vec3 d = transform_vector(inst.world_to_object, world_dir);
    const ShearRay s = make_shear_ray(o, d);
    store_vec3(record + kRecordWorldOrigin, world_origin);
    store_vec3(record + kRecordShear, make_vec3(s.sx, s.sy, s.sz));
    record[kRecordTriangleOffset] = mesh.triangle_offset;
    record[kRecordVertexOffset] = mesh.vertex_offset;
    record[kRecordInstance] = index;
    record[kRecordBlasFlags] = roots.flags;
    box = make_box_ray(o, d);
    box.octant |= (s.kx | (s.ky << 2) | (s.kz << 4)) << 8;
    return root;
  }

  // Back to the world ray, from `record` (enter_instance's) and the header.
  TANDEM_HD void leave_instance(const uint32_t* record) {
    box = make_box_ray(load_vec3(record + kRecordWorldOrigin), load_vec3(frame + kFrameWorldDir));
  }

  // Tests the triangle of leaf entry `entry` (of bvh_prim_indices, and of
  // bvh_leaf_triangles parallel to it: an entry of the binary layout, or
  // what a BLAS's wide entry holds) of the current BLAS, whose instance
  // record is `record`; true: stop (an any-hit query found a hit). The leaf
  // record holds the vertices: one load instead of the three dependent ones
  // of an indexed triangle. A BLAS without records (kBlasNoLeafRecords)
  // takes the indexed path; the record's vertices are the mesh's own floats,
  // so both paths test the same three points and find the same hit.
  TANDEM_HD bool leaf_triangle(uint32_t entry, const uint32_t* record) {
    if ((record[kRecordBlasFlags] & kBlasNoLeafRecords) != 0u) {
      const uint32_t prim = load_readonly(kd->bvh_prim_indices + entry);
      const KTriangle t = load_readonly(kd->triangles + record[kRecordTriangleOffset] + prim);
      const Vec3* v = kd->positions + record[kRecordVertexOffset];
      return test_triangle(load_readonly(v + t.v0), load_readonly(v + t.v1),
                           load_readonly(v + t.v2), prim, record);
    }
    const KLeafTriangle lt = load_readonly_16(kd->bvh_leaf_triangles + entry);
    return test_triangle(make_vec3(lt.p0.x, lt.p0.y, lt.p0.z), make_vec3(lt.p1.x, lt.p1.y, lt.p1.z),
                         make_vec3(lt.p2.x, lt.p2.y, lt.p2.z), float_as_uint(lt.p0.w), record);
  }

  // Tests the triangle of wide leaf entry `wide_entry` (of
  // bvh_wide_prim_indices) of the current BLAS: from its wide-order record,
  // whose place follows from the node alone, or, when the BLAS's flags say
  // those are not current (kBlasNoWideRecords) or not kept, through the
  // binary leaf entry the wide entry names (leaf_triangle). Every path
  // tests the same three points.
  TANDEM_HD bool wide_leaf_triangle(uint32_t wide_entry, const uint32_t* record) {
    if ((record[kRecordBlasFlags] & (kBlasNoLeafRecords | kBlasNoWideRecords)) != 0u)
      return leaf_triangle(load_readonly(kd->bvh_wide_prim_indices + wide_entry), record);
    const KLeafTriangle lt = load_readonly_16(kd->bvh_wide_leaf_triangles + wide_entry);
    return test_triangle(make_vec3(lt.p0.x, lt.p0.y, lt.p0.z), make_vec3(lt.p1.x, lt.p1.y, lt.p1.z),
                         make_vec3(lt.p2.x, lt.p2.y, lt.p2.z), float_as_uint(lt.p0.w), record);
  }

  // Host only: starts fetching what the tests of leaf entries [first, first
  // + count) read first: their leaf records, or (no records) their entries
  // of bvh_prim_indices.
  TANDEM_HD void prefetch_leaf_triangles(uint32_t first, uint32_t count,
                                         const uint32_t* record) const {
#if !TANDEM_GPU_CODE
    const bool indexed = (record[kRecordBlasFlags] & kBlasNoLeafRecords) != 0u;
    const char* begin = indexed ? reinterpret_cast<const char*>(kd->bvh_prim_indices + first)
                                : reinterpret_cast<const char*>(kd->bvh_leaf_triangles + first);
    const char* end = indexed
                          ? reinterpret_cast<const char*>(kd->bvh_prim_indices + first + count)
                          : reinterpret_cast<const char*>(kd->bvh_leaf_triangles + first + count);
    for (const char* p = begin; p < end; p += 64)
      prefetch_readonly(p);
    if (count != 0) prefetch_readonly(end - 1);
#else
    (void)first;
    (void)count;
    (void)record;
#endif
  }

  // The watertight test of triangle `prim` (p0, p1, p2 in object space) of
  // the current BLAS. The instance record is read for each triangle rather
  // than once per leaf, so that it is not live in registers during the alpha
  // test, the loop's busiest point.
  TANDEM_HD bool test_triangle(Vec3 p0, Vec3 p1, Vec3 p2, uint32_t prim, const uint32_t* record) {
    if constexpr (kCount) counters->triangles += 1;
    ShearRay shear;
    shear.origin = box.origin;
    shear.kx = (box.octant >> 8) & 3u;
    shear.ky = (box.octant >> 10) & 3u;
    shear.kz = box.octant >> 12;
    shear.sx = uint_as_float(record[kRecordShear]);
    shear.sy = uint_as_float(record[kRecordShear + 1]);
    shear.sz = uint_as_float(record[kRecordShear + 2]);
    TriangleHit th;
    if (!intersect_triangle_watertight(shear, p0, p1, p2, tmin, tmax, &th)) return false;
    if (!record_hit(th, prim, record)) return false;
    return any_hit;
  }

  // A hit of triangle `prim` of the current BLAS inside the interval: false
  // when the alpha test cuts it out; otherwise it becomes the closest hit
  // (tmax shrinks to its t). Also the host's four-triangle test's
  // (bvh_leaf_host.h), which finds the same hits.
  TANDEM_HD bool record_hit(const TriangleHit& th, uint32_t prim, const uint32_t* record) {
    // The mesh's flags only now: most triangle tests miss.
    const uint32_t instance = record[kRecordInstance];
    const uint32_t mesh_flags = kd->meshes[kd->instances[instance].mesh].flags;
    if ((mesh_flags & kMeshHasAlphaTest) != 0u &&
        !alpha_test_opaque(*kd, instance, prim, th.u, th.v, alpha_key))
      return false;
    // The hit's t is tmax, put in the hit at the end.
    tmax = th.t;
    frame[kFrameHitU] = float_as_uint(th.u);
    frame[kFrameHitV] = float_as_uint(th.v);
    frame[kFrameHitInstance] = instance;
    frame[kFrameHitPrim] = prim;
    return true;
  }
};

TANDEM_KERNEL_END
}  // namespace tandem

// The host's own loops: the binary layout's (same hits, fewer node visits)
// and the wide layout's in distance order (same closest t, fewer node
// visits and triangle tests), wherever the compiler is not nvcc and the
// GPU's code is not being emulated.
#if !defined(__CUDACC__) && !TANDEM_GPU_CODE
#define TANDEM_BVH_HOST_TRAVERSAL 1
#include "core/kernel/bvh_traverse_host.h"
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

// Binary layout. In a BLAS, leaf triangles are tested as soon as their node
// is; in the TLAS a hit leaf's instance range goes on the stack (two entries:
// its count, then kBvhLeafFlag | first entry) above the node's interior
// children, so its instances come first, in order, as they did when the
// TLAS's leaf handler traversed them on the spot. Returns true when an
// any-hit query stopped.
template <bool kCount>
TANDEM_HD bool trace_two_level_binary(TwoLevelTrace<kCount>& tr, const KBvhNode* nodes,
                                      uint32_t root) {
  const uint32_t* prim_indices = tr.kd->bvh_prim_indices;
  uint32_t* const stack = tr.frame;
  uint32_t sp = kBvhFrameHeaderWords;
  uint32_t blas_sp = kBvhInTlas;
  uint32_t node_index = root;
  for (;;) {
    // The boxes, then the links once the boxes are tested: loaded as one
    // 64-byte node, the node went through a copy in the GPU's local memory
    // (ptxas: 96 B more stack in every traversal kernel).
    const KBvhNodeBoxes boxes = load_node_boxes(nodes + node_index);
    const bool in_blas = blas_sp != kBvhInTlas;
    if constexpr (kCount) {
      tr.counters->nodes += 1;
      tr.counters->boxes += 2;
      if (in_blas) tr.counters->blas_nodes += 1;
    }
    float t0, t1;
    bool hit0 = intersect_box(tr.box, make_vec3(boxes.c0_xy.x, boxes.c0_xy.z, boxes.c01_z.x),
                              make_vec3(boxes.c0_xy.y, boxes.c0_xy.w, boxes.c01_z.y), tr.tmin,
                              tr.tmax, &t0);
    bool hit1 = intersect_box(tr.box, make_vec3(boxes.c1_xy.x, boxes.c1_xy.z, boxes.c01_z.z),
                              make_vec3(boxes.c1_xy.y, boxes.c1_xy.w, boxes.c01_z.w), tr.tmin,
                              tr.tmax, &t1);
    const KBvhNodeLinks n = load_node_links(nodes + node_index);
    bool leaf0 = hit0 && (n.child[0] & kBvhLeafFlag) != 0u;
    bool leaf1 = hit1 && (n.child[1] & kBvhLeafFlag) != 0u;
    if (in_blas && (leaf0 || leaf1)) {
      const uint32_t* record = stack + blas_sp - kBvhInstanceRecordWords;
      // Both leaves' records on their way before the first test.
      if (leaf0) tr.prefetch_leaf_triangles(n.child[0] & ~kBvhLeafFlag, n.count[0], record);
      if (leaf1) tr.prefetch_leaf_triangles(n.child[1] & ~kBvhLeafFlag, n.count[1], record);
      for (uint32_t c = 0; c < 2; ++c) {
        if (!(c == 0 ? leaf0 : leaf1)) continue;
        const uint32_t first = n.child[c] & ~kBvhLeafFlag;
        for (uint32_t i = 0; i < n.count[c]; ++i) {
          if (tr.leaf_triangle(first + i, record)) return true;
        }
      }
      leaf0 = leaf1 = false;
    }
    const bool inner0 = hit0 && !(n.child[0] & kBvhLeafFlag);
    const bool inner1 = hit1 && !(n.child[1] & kBvhLeafFlag);
    uint32_t next = kInvalidIndex;
    if (inner0 && inner1) {
      // Nearer child first; the other waits on the stack.
      const bool swap = t1 < t0;
      next = swap ? n.child[1] : n.child[0];
      const uint32_t far_child = swap ? n.child[0] : n.child[1];
      prefetch_readonly(nodes + far_child);
      if (sp < kBvhFrameWords) stack[sp++] = far_child;
    } else if (inner0) {
      next = n.child[0];
    } else if (inner1) {
      next = n.child[1];
    }
    if (leaf0 || leaf1) {
      // TLAS leaves before the interior children.
      if (next != kInvalidIndex && sp < kBvhFrameWords) stack[sp++] = next;
      next = kInvalidIndex;
      for (uint32_t c = 2; c-- > 0;) {
        if (!(c == 0 ? leaf0 : leaf1) || n.count[c] == 0 || sp + 2 > kBvhFrameWords) continue;
        stack[sp++] = n.count[c];
        stack[sp++] = n.child[c];
      }
    }
    while (next == kInvalidIndex) {
      if (sp == blas_sp) {
        sp -= kBvhInstanceRecordWords;
        tr.leave_instance(stack + sp);
        blas_sp = kBvhInTlas;
      }
      if (sp == kBvhFrameHeaderWords) return false;
      const uint32_t top = stack[sp - 1];
      if ((top & kBvhLeafFlag) == 0u) {
        next = top;
        --sp;
        continue;
      }
      // The next instance of a TLAS leaf.
      const uint32_t entry = top & ~kBvhLeafFlag;
      const uint32_t left = stack[sp - 2];
      if (left > 1) {
        stack[sp - 1] = (entry + 1) | kBvhLeafFlag;
        stack[sp - 2] = left - 1;
      } else {
        sp -= 2;
      }
      if (sp + kBvhInstanceRecordWords > kBvhFrameWords) continue;
      next = tr.enter_instance(load_readonly(prim_indices + entry), false, stack + sp);
      if (next != kInvalidIndex) {
        sp += kBvhInstanceRecordWords;
        blas_sp = sp;
      }
    }
    node_index = next;
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

// Wide layout, after Ylitie et al. 2017: a stack of node groups. A group is
// (child_base, hits | imask): bits 24..31 of hits are the interior children
// still to visit, at position (slot ^ octant) so the lowest bit is the
// (approximately) nearest child; bits 0..7 repeat the node's imask to find
// the child's index. In a BLAS, leaf triangles are tested as soon as their
// node is; in the TLAS the hit instances go on the stack as an instance group
// (prim_base, prim_hits: bits 0..23 only, so its top byte, unlike a node
// group's, is zero) above the node's group, so they come first, in order.
// In a BLAS, a wide entry's triangle is tested from its wide-order record
// (bvh_wide_leaf_triangles, at the entry's own index); its entry of
// bvh_wide_prim_indices is not a triangle index but the triangle's entry in
// bvh_leaf_triangles, the binary layout's records (accstruc's
// emit_blas_wide_entries), which a BLAS refit since its layout reads
// instead (wide_leaf_triangle); in the TLAS it is an instance index.
// Returns true when an any-hit query stopped. (The host has its own loop in
// distance order, host_trace_two_level_wide.)
template <bool kCount>
TANDEM_HD bool trace_two_level_wide(TwoLevelTrace<kCount>& tr, const KWideBvhNode* nodes,
                                    uint32_t root) {
  const uint32_t* prim_indices = tr.kd->bvh_wide_prim_indices;
  // A group is two words, (base, bits).
  uint32_t* const stack = tr.frame;
  uint32_t sp = kBvhFrameHeaderWords;
  uint32_t blas_sp = kBvhInTlas;
  uint32_t node_index = root;
  for (;;) {
    const KWideBvhNode n = load_readonly_16(nodes + node_index);
    const bool in_blas = blas_sp != kBvhInTlas;
    if constexpr (kCount) {
      tr.counters->nodes += 1;
      if (in_blas) tr.counters->blas_nodes += 1;
    }
    const Vec3 scale = {wide_node_scale(n, 0), wide_node_scale(n, 1), wide_node_scale(n, 2)};
    uint32_t node_hits = 0, prim_hits = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const uint32_t meta = n.meta[s];
      if (meta == 0) continue;
      if constexpr (kCount) tr.counters->boxes += 1;
      Vec3 lo, hi;
      wide_child_box(n, scale, s, &lo, &hi);
      float t_entry;
      if (!intersect_box(tr.box, lo, hi, tr.tmin, tr.tmax, &t_entry)) continue;
      if ((n.imask >> s) & 1u)
        node_hits |= 1u << (24u + (s ^ tr.octant()));
      else
        prim_hits |= (meta >> 5) << (meta & 31u);
    }
    if (node_hits != 0 && sp + 2 <= kBvhFrameWords) {
      stack[sp] = n.child_base;
      stack[sp + 1] = node_hits | n.imask;
      sp += 2;
    }
    const uint32_t prim_base = n.prim_base;
    if (!in_blas) {
      if (prim_hits != 0 && sp + 2 <= kBvhFrameWords) {
        stack[sp] = prim_base;
        stack[sp + 1] = prim_hits;
        sp += 2;
      }
    } else if (prim_hits != 0) {
      // A BLAS's wide entries have records of their own (bvh.h).
      const uint32_t* record = stack + blas_sp - kBvhInstanceRecordWords;
      while (prim_hits != 0) {
        const uint32_t p = count_trailing_zeros(prim_hits);
        prim_hits &= prim_hits - 1u;
        if (tr.wide_leaf_triangle(prim_base + p, record)) return true;
      }
    }
    // Next node: the nearest remaining child of the innermost group, or the
    // BLAS root of the next instance of an instance group.
    for (;;) {
      if (sp == blas_sp) {
        sp -= kBvhInstanceRecordWords;
        tr.leave_instance(stack + sp);
        blas_sp = kBvhInTlas;
      }
      if (sp == kBvhFrameHeaderWords) return false;
      uint32_t& bits = stack[sp - 1];
      const uint32_t base = stack[sp - 2];
      if ((bits >> 24) == 0) {
        const uint32_t p = count_trailing_zeros(bits);
        bits &= bits - 1u;
        if (bits == 0) sp -= 2;
        if (sp + kBvhInstanceRecordWords > kBvhFrameWords) continue;
        node_index = tr.enter_instance(load_readonly(prim_indices + base + p), true, stack + sp);
        if (node_index == kInvalidIndex) continue;
        sp += kBvhInstanceRecordWords;
        blas_sp = sp;
        break;
      }
      const uint32_t pos = count_trailing_zeros(bits >> 24);
      bits &= ~(1u << (24u + pos));
      const uint32_t slot = pos ^ tr.octant();
      const uint32_t imask = bits & 0xffu;
      node_index = base + popcount(imask & ((1u << slot) - 1u));
      if ((bits >> 24) == 0) sp -= 2;
      break;
    }
  }
}

// ---------------------------------------------------------------------------
// Queries.

// Closest (any_hit = false) or any (any_hit = true) hit along the ray in the
// given layout. Returns a miss when the scene has no BVH. With kCount the
// query's traversal work is added to *counters. kPortable: the loops the GPU
// runs even where the host has its own (bvh_traverse_host.h), which finds the
// same hits (in the wide layout the same closest t; of hits at exactly equal
// t it may report another); for tests and measurements.
template <bool kCount, bool kPortable = false>
TANDEM_HD Hit bvh_trace_counted(const KernelData& kd, const Ray& ray, uint32_t alpha_key,
                                uint32_t layout, bool any_hit, BvhCounters* counters) {
  const bool wide = layout == kBvhLayoutWide;
  const uint32_t root = wide ? kd.bvh.tlas_wide_root : kd.bvh.tlas_root;
  if (root >= (wide ? kd.bvh_wide_nodes_count : kd.bvh_nodes_count)) return make_miss();
  uint32_t frame[kBvhFrameWords];
  store_vec3(frame + kFrameWorldDir, ray.dir);
  frame[kFrameHitU] = frame[kFrameHitV] = 0;
  frame[kFrameHitInstance] = frame[kFrameHitPrim] = kInvalidIndex;
  TwoLevelTrace<kCount> tr;
  tr.kd = &kd;
  tr.frame = frame;
  tr.tmin = ray.tmin;
  tr.tmax = ray.tmax;
  tr.alpha_key = alpha_key;
  tr.any_hit = any_hit;
  tr.box = make_box_ray(ray.origin, ray.dir);
  tr.counters = counters;
  if (wide) {
#if defined(TANDEM_BVH_HOST_TRAVERSAL)
    if constexpr (!kPortable) {
      host_trace_two_level_wide<kCount>(tr, kd.bvh_wide_nodes, root);
    } else {
      trace_two_level_wide<kCount>(tr, kd.bvh_wide_nodes, root);
    }
#else
    trace_two_level_wide<kCount>(tr, kd.bvh_wide_nodes, root);
#endif
  } else {
#if defined(TANDEM_BVH_HOST_TRAVERSAL)
    if constexpr (!kPortable) {
      host_trace_two_level_binary<kCount>(tr, kd.bvh_nodes, root);
    } else {
      trace_two_level_binary<kCount>(tr, kd.bvh_nodes, root);
    }
#else
    trace_two_level_binary<kCount>(tr, kd.bvh_nodes, root);
#endif
  }
  Hit hit = make_miss();
  hit.instance = frame[kFrameHitInstance];
  if (hit_valid(hit)) {
    hit.t = tr.tmax;
    hit.u = uint_as_float(frame[kFrameHitU]);
    hit.v = uint_as_float(frame[kFrameHitV]);
    hit.prim = frame[kFrameHitPrim];
  }
  return hit;
}

// The renderer's query: no counting.
TANDEM_HD Hit bvh_trace(const KernelData& kd, const Ray& ray, uint32_t alpha_key, uint32_t layout,
                        bool any_hit) {
  return bvh_trace_counted<false>(kd, ray, alpha_key, layout, any_hit, nullptr);
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
// selected by kd.bvh.layout.
struct BvhTracer {
  const KernelData* kd;
  TANDEM_HD Hit intersect(const Ray& ray, uint32_t alpha_key) const {
    return bvh_intersect(*kd, ray, alpha_key, kd->bvh.layout);
  }
  TANDEM_HD bool occluded(const Ray& ray, uint32_t alpha_key) const {
    return bvh_occluded(*kd, ray, alpha_key, kd->bvh.layout);
  }
  // Either query (render_pixel_sample_one_trace_site).
  TANDEM_HD Hit trace(const Ray& ray, uint32_t alpha_key, bool any_hit) const {
    return bvh_trace(*kd, ray, alpha_key, kd->bvh.layout, any_hit);
  }
};

TANDEM_KERNEL_END
}  // namespace tandem
