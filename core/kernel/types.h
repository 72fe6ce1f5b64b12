// Plain-old-data records shared by every backend. Layouts are fixed with
// static_asserts because the CUDA backend copies these arrays byte for byte.
#pragma once

#include "core/kernel/math.h"

#if !defined(__CUDACC_RTC__)
#include <cstddef>  // offsetof
#endif

namespace tandem {
TANDEM_KERNEL_BEGIN

struct Ray {
  Vec3 origin;
  float tmin;
  Vec3 dir;
  float tmax;
};

// Result of a closest-hit query. instance == kInvalidIndex means a miss.
// (u, v) are the barycentrics of vertices 1 and 2 (Embree convention).
struct Hit {
  float t;
  float u, v;
  uint32_t instance;
  uint32_t prim;
};
TANDEM_HD bool hit_valid(const Hit& h) {
  return h.instance != kInvalidIndex;
}
TANDEM_HD Hit make_miss() {
  return {kFloatMax, 0.0f, 0.0f, kInvalidIndex, kInvalidIndex};
}

// Triangle record: vertex indices relative to its mesh's vertex_offset, and
// the material it uses. 16 bytes so Embree can read it as a strided UINT3.
struct KTriangle {
  uint32_t v0, v1, v2;
  uint32_t material;
};
static_assert(sizeof(KTriangle) == 16, "GPU layout");

enum KMeshFlags : uint32_t {
  kMeshHasNormals = 1u << 0,
  kMeshHasTangents = 1u << 1,
  kMeshHasUv0 = 1u << 2,
  kMeshHasUv1 = 1u << 3,
  kMeshHasAlphaTest = 1u << 4,  // some triangle uses MASK/BLEND: run the alpha test
  kMeshHasEmission = 1u << 5,
  // For the host's BVH builder, not the kernels: a deformer rewrites the
  // mesh's vertices every frame (Scene::set_mesh_deforms), so its BLAS is
  // built to be refit (no spatial splits).
  kMeshDeforms = 1u << 6,
};

struct KMesh {
  uint32_t vertex_offset;
  uint32_t vertex_count;
  uint32_t triangle_offset;
  uint32_t triangle_count;
  uint32_t flags;
  uint32_t pad[3];  // the BLAS roots are in blas_roots (core/kernel/bvh.h)
};
static_assert(sizeof(KMesh) == 32, "GPU layout");

enum KInstanceFlags : uint32_t {
  // object_to_world is exactly the identity (most glTF nodes, the built-in
  // scenes): shading skips the transforms of its points, normals and
  // tangents, and Embree traces its mesh without an instance level.
  kInstanceIdentity = 1u << 0,
  // Not drawn (core/world/scene_ranges.h: a singular transform, or positions
  // no tracer can take): its transforms are zero, it is out of the TLAS and
  // disabled in Embree, so no ray ever reaches it.
  kInstanceHidden = 1u << 1,
};

struct KInstance {
  Mat34 object_to_world;
  Mat34 world_to_object;
  uint32_t mesh;
  uint32_t flags;  // KInstanceFlags
  // Sign of the determinant: mirrored instances flip triangle winding.
  float handedness;
  float pad;
};
static_assert(sizeof(KInstance) == 112, "GPU layout");

enum KWrapMode : uint32_t { kWrapRepeat = 0, kWrapClamp = 1, kWrapMirror = 2 };
enum KTextureFlags : uint32_t {
  kTextureSrgb = 1u << 0,     // decode RGB from sRGB on fetch (alpha stays linear)
  kTextureNearest = 1u << 1,  // magnification filter NEAREST
  kTextureFloat = 1u << 2,    // texels in texels_f32, linear floats (never sRGB)
};

// An RGBA8 texture stored in the texels array starting at texel_offset.
struct KTexture {
  uint32_t width, height;
  uint32_t texel_offset;
  uint32_t flags;
  uint32_t wrap_s, wrap_t;
  uint32_t pad[2];
};
static_assert(sizeof(KTexture) == 32, "GPU layout");

// A material's reference to a texture: which texture, which UV set, and the
// KHR_texture_transform as a 2x3 matrix (uv' = M * (u, v, 1)).
struct KTextureRef {
  int32_t texture;  // -1: none
  uint32_t uv_set;
  float m[6];
};
static_assert(sizeof(KTextureRef) == 32, "GPU layout");

enum KAlphaMode : uint32_t { kAlphaOpaque = 0, kAlphaMask = 1, kAlphaBlend = 2 };
enum KMaterialFlags : uint32_t { kMaterialDoubleSided = 1u << 0 };

// glTF metallic-roughness material with the extensions Tandem supports
// (emissive_strength, transmission, ior, specular, clearcoat, sheen). Factors
// are already multiplied out (emission = emissiveFactor * emissiveStrength).
// The layer fields were added after the others, in what was padding and at
// the end, so that the offsets of the older fields did not move.
struct KMaterial {
  Vec4 base_color;  // linear RGB + alpha
  Vec3 emission;
  float metallic;
  Vec3 specular_color;  // KHR_materials_specular specularColorFactor
  float roughness;      // perceptual roughness; GGX alpha = roughness^2
  float transmission;
  float ior;
  float specular;  // KHR_materials_specular specularFactor (0: pure Lambert)
  float alpha_cutoff;
  uint32_t alpha_mode;
  uint32_t flags;
  float normal_scale;
  float emission_luminance_scale;  // mean luminance of the emissive texture (1 if none)
  // Hemispherical averages of the dielectric Fresnel term for eta = ior
  // (entering) and 1/ior (leaving), precomputed on the host because the
  // diffuse-under-specular energy normalisation needs them at every hit.
  float fresnel_avg_enter;
  float fresnel_avg_leave;
  float clearcoat;            // KHR_materials_clearcoat clearcoatFactor (0: no coat)
  float clearcoat_roughness;  // clearcoatRoughnessFactor, perceptual
  KTextureRef base_color_tex;
  KTextureRef metallic_roughness_tex;
  KTextureRef normal_tex;
  KTextureRef emissive_tex;
  KTextureRef transmission_tex;
  Vec3 sheen_color;           // KHR_materials_sheen sheenColorFactor, linear (black: no sheen)
  float sheen_roughness;      // sheenRoughnessFactor, perceptual
  KTextureRef clearcoat_tex;  // R: clearcoat
  KTextureRef clearcoat_roughness_tex;  // G: clearcoat roughness
  KTextureRef sheen_color_tex;          // RGB, sRGB-encoded
  KTextureRef sheen_roughness_tex;      // A: sheen roughness
};
static_assert(sizeof(KMaterial) == 96 + 5 * 32 + 16 + 4 * 32, "GPU layout");
static_assert(offsetof(KMaterial, clearcoat) == 88 && offsetof(KMaterial, base_color_tex) == 96 &&
                  offsetof(KMaterial, sheen_color) == 256 &&
                  offsetof(KMaterial, clearcoat_tex) == 272,
              "GPU layout");

enum KLightType : uint32_t {
  kLightMeshInstance = 0,  // an instance of an emissive mesh: its triangle lights
  kLightPoint = 1,
  kLightSpot = 2,
  kLightDirectional = 3,
  kLightEnvironment = 4,
};

// One entry of the light list: punctual lights with their world-space frame,
// the environment, and one per instance of an emissive mesh (`instance`,
// `power` the summed power of its triangles in world space). A light is
// chosen among these first; an instance then chooses one of its mesh's
// triangle lights (KMeshLights), so the list grows with the instances and
// the meshes' triangles, never with their product.
struct KLight {
  uint32_t type;
  uint32_t instance;  // kLightMeshInstance
  uint32_t pad[2];
  Vec3 position;    // point/spot
  float cos_inner;  // spot: cos of inner cone angle
  Vec3 direction;   // spot/directional: direction the light travels
  float cos_outer;
  Vec3 intensity;  // point/spot: W/sr; directional: W/m^2 (colour already applied)
  float power;     // kLightMeshInstance: its triangles' power in world space
};
static_assert(sizeof(KLight) == 64, "GPU layout");

// One emissive triangle of a mesh, in object space: what make_light_point
// computes for it at an identity instance (cache_triangle_light), with the
// same float operations, so that sample_light skips the triangle fetch,
// the normal and the area there.
struct KTriangleLight {
  Vec3 p0;
  uint32_t prim;  // the triangle in its mesh
  Vec3 p1;
  uint32_t material;
  Vec3 p2;
  float power;  // triangle_light_power of its material and object-space area
  Vec3 normal;  // unit geometric normal (the winding's)
  float area;
};
static_assert(sizeof(KTriangleLight) == 64, "GPU layout");

// The triangle lights of one mesh: entries [first, first + count) of
// triangle_lights (in the order of their prims), of triangle_light_alias
// (the mesh's own table by power, the power sampler) and of
// triangle_light_trails; `tree_root` its light tree in light_tree_nodes
// (the tree sampler), in object space, shared by every instance.
struct KMeshLights {
  uint32_t first;
  uint32_t count;
  uint32_t tree_root;
  float power;  // summed over its triangle lights, object space
};
static_assert(sizeof(KMeshLights) == 16, "GPU layout");

// Walker alias table entry for O(1) sampling of a discrete distribution.
struct KAliasEntry {
  float threshold;  // keep this entry when u < threshold
  uint32_t alias;
  float pdf;  // probability of this entry itself
  float pad;
};
static_assert(sizeof(KAliasEntry) == 16, "GPU layout");

enum KCameraType : uint32_t { kCameraPerspective = 0, kCameraOrthographic = 1 };

struct KCamera {
  Vec3 position;
  uint32_t type;
  Vec3 right;  // unit vectors of the camera frame
  float tan_half_fov_y;
  Vec3 up;
  float aspect;  // width / height of the film
  Vec3 forward;
  float aperture_radius;  // thin lens; 0 = pinhole
  float focus_distance;
  float ortho_half_height;
  uint32_t width, height;
};
static_assert(sizeof(KCamera) == 80, "GPU layout");

struct KEnvironment {
  Vec3 color;       // constant radiance, or multiplier of the map
  int32_t has_map;  // 1: equirectangular map in env_texels
  uint32_t width, height;
  float rotation;      // radians about +y
  float map_integral;  // sum of sin-weighted luminance (for pdf normalisation)
  // cos and sin of the rotation, sincos_pi(rotation / pi) taken once by the
  // scene compiler: every missed ray and every sample of the map turns by it.
  float rotation_cos, rotation_sin;
};
static_assert(sizeof(KEnvironment) == 40, "GPU layout");

struct KIntegratorParams {
  uint32_t max_depth;       // scattering events; 1 = direct lighting only
  uint32_t rr_start_depth;  // Russian roulette starts after this many bounces
  float radiance_clamp;     // 0: off. Clamps indirect sample radiance (biased).
  uint32_t seed;
};

enum SceneFlags : uint32_t {
  // Some mesh has kMeshHasAlphaTest: only then do rays need alpha keys.
  kSceneHasAlphaTest = 1u << 0,
};

// Scalars that accompany the device arrays.
struct KernelConstants {
  KCamera camera;
  KEnvironment environment;
  KIntegratorParams integrator;
  Vec3 scene_center;
  float scene_radius;
  float total_light_power;
  uint32_t environment_light_index;  // kInvalidIndex if the environment is black
  uint32_t scene_flags;              // SceneFlags
  // The light tree sampler (core/kernel/light_tree.h) is on when > 0: the
  // probability of sampling a finite light (triangles, points, spots)
  // through the tree, the rest going to the infinite lights (directional,
  // environment) through light_alias. 0: every light from light_alias, by
  // power.
  float light_tree_fraction;
  // The root of the tree over the light list's finite lights in
  // light_tree_nodes (after the meshes' trees), with the tree sampler.
  uint32_t light_tree_root;
  // The BVH's roots and layout are in KernelData::bvh (core/kernel/bvh.h).
};

TANDEM_KERNEL_END
}  // namespace tandem
