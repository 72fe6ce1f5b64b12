// The one list of arrays that describes a scene to the kernels.
//
// TANDEM_KERNEL_ARRAYS is the single source of truth: the host-side
// KernelScene stores one std::vector per entry, the CUDA backend one device
// buffer per entry, and KernelData (below) one pointer + count per entry.
// Adding an array here adds it everywhere; nothing is mirrored by hand.
#pragma once

#include "core/kernel/bvh.h"
#include "core/kernel/light_tree.h"
#include "core/kernel/types.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// X(element type, name). Every array has one writer: TANDEM_SCENE_ARRAYS
// (and KernelConstants) the SceneCompiler (core/world), TANDEM_BVH_ARRAYS
// (and KBvhConstants) the BVH updater (accstruc/AccelStructure). Each
// reports what it rewrote in a SceneDelta of its own; the backends commit
// the union of the two.
#define TANDEM_SCENE_ARRAYS(X)                                                                    \
  X(Vec3, positions)      /* per vertex, object space; padded by one for SSE loads */             \
  X(Vec3, normals)        /* per vertex, or empty for a mesh without kMeshHasNormals */           \
  X(Vec4, tangents)       /* per vertex: xyz + handedness w */                                    \
  X(Vec2, uv0)            /* per vertex */                                                        \
  X(Vec2, uv1)            /* per vertex */                                                        \
  X(KTriangle, triangles) /* per triangle, indices relative to the mesh */                        \
  X(KMesh, meshes)        /* one per BLAS */                                                      \
  X(KInstance, instances) /* one per TLAS entry */                                                \
  X(KMaterial, materials)                                                                         \
  X(KTexture, textures)                                                                           \
  X(uint32_t, texels) /* RGBA8 texels of all 8-bit textures */                                    \
  X(Vec4, texels_f32) /* linear RGBA texels of all float textures */                              \
  X(KLight, lights)                                                                               \
  X(KAliasEntry, light_alias)          /* distribution over lights, by power */                   \
  X(KLightTreeNode, light_tree_nodes)  /* the light tree sampler's BVHs: meshes', then lights' */ \
  X(uint64_t, light_tree_trails)       /* per light: its path from light_tree_root */             \
  X(uint32_t, instance_lights)         /* per instance: its kLightMeshInstance, or invalid */     \
  X(KTriangleLight, triangle_lights)   /* per emissive mesh: its emissive triangles */            \
  X(KAliasEntry, triangle_light_alias) /* per triangle light: its mesh's table by power */        \
  X(uint64_t, triangle_light_trails)   /* per triangle light: its path in its mesh's tree */      \
  X(KMeshLights, mesh_lights)          /* per mesh: its triangle lights */                        \
  X(Vec4, env_texels)                  /* equirectangular environment, linear RGB */              \
  X(float, env_marginal_cdf)           /* height + 1 entries */                                   \
  X(float, env_conditional_cdf)        /* height * (width + 1) entries */                         \
  X(uint32_t, env_marginal_guide)      /* height + 1 entries: see find_interval_guided */         \
  X(uint32_t, env_conditional_guide)   /* height * (width + 1) entries */

#define TANDEM_BVH_ARRAYS(X)                                                                      \
  X(KBlasRoot, blas_roots)      /* one per mesh */                                                \
  X(KBvhNode, bvh_nodes)        /* binary BVH: all BLAS, then the TLAS */                         \
  X(uint32_t, bvh_prim_indices) /* leaf ranges of bvh_nodes: triangle / instance indices */       \
  X(KLeafTriangle,                                                                                \
    bvh_leaf_triangles)              /* per bvh_prim_indices entry: a BLAS triangle's vertices */ \
  X(KWideBvhNode, bvh_wide_nodes)    /* 8-wide compressed BVH: all BLAS, then the TLAS */         \
  X(uint32_t, bvh_wide_prim_indices) /* leaf entries of bvh_wide_nodes */                         \
  X(KLeafTriangle,                                                                                \
    bvh_wide_leaf_triangles) /* per bvh_wide_prim_indices entry: a BLAS triangle's vertices */

#define TANDEM_KERNEL_ARRAYS(X) TANDEM_SCENE_ARRAYS(X) TANDEM_BVH_ARRAYS(X)

// Read-only view of a scene: pointers into host vectors (CPU and host
// backends) or device buffers (CUDA backend). Trivially copyable so it can be
// passed to a kernel by value.
struct KernelData {
#define TANDEM_DECLARE_VIEW(T, name) \
  const T* name;                     \
  uint32_t name##_count;
  TANDEM_KERNEL_ARRAYS(TANDEM_DECLARE_VIEW)
#undef TANDEM_DECLARE_VIEW
  KernelConstants constants;
  KBvhConstants bvh;
};

TANDEM_KERNEL_END
}  // namespace tandem
