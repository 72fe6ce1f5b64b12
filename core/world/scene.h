// The host-side scene model: what loaders build and what games edit.
//
// Objects live in flat vectors and are referred to by index. Every mutation
// goes through a method that marks the touched object dirty, so the scene
// compiler can turn exactly the changed objects into kernel-array deltas
// (and the CUDA backend can upload only those bytes). Nothing here is hashed
// or diffed to find changes.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/world/mesh_pose.h"
#include "core/world/scene_bounds.h"

namespace tandem {

enum class AlphaMode : uint8_t { kOpaque, kMask, kBlend };
enum class WrapMode : uint8_t { kRepeat, kClampToEdge, kMirroredRepeat };

// KHR_texture_transform plus the UV set a texture reads.
struct TextureTransform {
  glm::vec2 offset{0.0f};
  glm::vec2 scale{1.0f};
  float rotation = 0.0f;  // radians, counter-clockwise in UV space
  uint32_t uv_set = 0;    // TEXCOORD_n
};

struct TextureRef {
  int32_t texture = -1;  // index into Scene::textures(), -1 = none
  TextureTransform transform;
};

// How an 8-bit texture's RGB is encoded: as glTF has it, by the slot that
// uses it (base colour, emission, sheen colour: sRGB; the others linear),
// or as its owner says for every slot (an embedding game's choice).
enum class TextureEncoding : uint8_t { kBySlot, kSrgb, kLinear };

// An 8-bit RGBA image, or a float one (linear RGBA, e.g. HDR emission).
struct Texture {
  std::string name;
  uint32_t width = 0, height = 0;
  std::vector<uint32_t> rgba8;     // packed R | G<<8 | B<<16 | A<<24, row 0 = top
  std::vector<glm::vec4> rgba32f;  // instead of rgba8: linear floats, row 0 = top
  TextureEncoding encoding = TextureEncoding::kBySlot;  // of rgba8
  WrapMode wrap_s = WrapMode::kRepeat, wrap_t = WrapMode::kRepeat;
  bool nearest = false;  // magnification filter NEAREST
  size_t texel_count() const { return rgba8.empty() ? rgba32f.size() : rgba8.size(); }
  // Whether a slot that decodes sRGB when `slot_srgb` decodes this texture so.
  bool decodes_srgb(bool slot_srgb) const {
    if (!rgba32f.empty() || encoding == TextureEncoding::kLinear) return false;
    return encoding == TextureEncoding::kSrgb || slot_srgb;
  }
};

// glTF metallic-roughness material plus supported extensions. Defaults are
// the glTF defaults.
struct Material {
  std::string name;
  glm::vec4 base_color{1.0f};
  float metallic = 1.0f;
  float roughness = 1.0f;
  glm::vec3 emissive{0.0f};
  float emissive_strength = 1.0f;  // KHR_materials_emissive_strength
  float transmission = 0.0f;       // KHR_materials_transmission
  float ior = 1.5f;                // KHR_materials_ior
  float specular = 1.0f;           // KHR_materials_specular
  glm::vec3 specular_color{1.0f};
  AlphaMode alpha_mode = AlphaMode::kOpaque;
  float alpha_cutoff = 0.5f;
  bool double_sided = false;
  float normal_scale = 1.0f;
  TextureRef base_color_texture, metallic_roughness_texture, normal_texture, emissive_texture,
      transmission_texture;
  // KHR_materials_clearcoat (clearcoat 0: no coat) and KHR_materials_sheen
  // (black sheen colour: no sheen); roughness values are perceptual.
  float clearcoat = 0.0f;
  float clearcoat_roughness = 0.0f;
  glm::vec3 sheen_color{0.0f};
  float sheen_roughness = 0.0f;
  TextureRef clearcoat_texture, clearcoat_roughness_texture, sheen_color_texture,
      sheen_roughness_texture;
};

// Triangle mesh (one BLAS). glTF primitives of one mesh are merged into one
// Mesh with a material per triangle, so instancing a glTF mesh instances all
// of its primitives at once.
struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;   // empty or one per vertex
  std::vector<glm::vec4> tangents;  // empty or one per vertex (w = handedness)
  std::vector<glm::vec2> uv0, uv1;  // empty or one per vertex
  std::vector<glm::uvec3> triangles;
  std::vector<uint32_t> triangle_materials;  // one per triangle
};

struct Instance {
  std::string name;
  uint32_t mesh = 0;
  glm::mat4 transform{1.0f};  // object to world
  // Not drawn, not lit, not in the bounds: as if it were not there, while
  // its slot stays for reuse (a game's despawned object, see
  // Scene::set_instance_hidden).
  bool hidden = false;
};

enum class LightType : uint8_t { kPoint, kSpot, kDirectional };

// KHR_lights_punctual light in world space. Intensity is used as a radiometric
// quantity (W/sr for point/spot, W/m^2 for directional); see docs/scene-units.md.
struct Light {
  std::string name;
  LightType type = LightType::kPoint;
  glm::vec3 color{1.0f};
  float intensity = 1.0f;
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, 0.0f, -1.0f};  // direction light travels (spot/directional)
  float inner_cone_angle = 0.0f;
  float outer_cone_angle = 0.7853981634f;
};

enum class CameraType : uint8_t { kPerspective, kOrthographic };

struct Camera {
  CameraType type = CameraType::kPerspective;
  glm::vec3 position{0.0f, 0.0f, 5.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};  // unit
  glm::vec3 up{0.0f, 1.0f, 0.0f};        // unit, orthogonal to forward
  float yfov = 0.6911112f;               // radians (39.6 degrees)
  float ortho_half_height = 1.0f;
  float aperture_radius = 0.0f;  // world units, 0 = pinhole
  float focus_distance = 1.0f;   // world units along forward
  float aspect_ratio = 0.0f;     // preferred width / height; 0 = unspecified
};

// Either a constant colour or an equirectangular map (linear RGB) scaled by
// colour * intensity.
struct Environment {
  glm::vec3 color{0.0f};
  float intensity = 1.0f;
  float rotation = 0.0f;  // radians about +y
  uint32_t width = 0, height = 0;
  std::vector<glm::vec3> texels;  // empty for a constant environment
  std::string source;             // file it came from, for messages
};

// Bits of a per-object dirty mask.
enum DirtyBits : uint32_t {
  kDirtyCreated = 1u << 0,    // object is new since the last compile
  kDirtyTransform = 1u << 1,  // instance transform changed (TLAS update)
  kDirtyVertices = 1u << 2,   // vertex data changed, topology kept (BLAS refit)
  kDirtyTopology = 1u << 3,   // triangles changed (BLAS rebuild)
  kDirtyParams = 1u << 4,     // material / light / texture parameters
};

class Scene {
 public:
  // --- building -----------------------------------------------------------
  uint32_t add_texture(Texture t);
  uint32_t add_material(Material m);
  uint32_t add_mesh(Mesh m);
  uint32_t add_instance(Instance i);
  uint32_t add_light(Light l);
  void set_camera(const Camera& c);
  void set_environment(Environment e);

  // --- editing (marks the object dirty) ------------------------------------
  void set_instance_transform(uint32_t instance, const glm::mat4& transform);
  // Hides or shows an instance. Hiding is how objects are removed at the
  // cost of a TLAS update: the slot (and its index) stays, and the caller
  // may show it again with a new transform for the next object of its mesh,
  // so memory follows the most objects alive at once, not all ever made.
  void set_instance_hidden(uint32_t instance, bool hidden);
  // Removes a light; later lights move down one index. The compiler then
  // rebuilds the light list only (as for add_light), not the scene.
  void remove_light(uint32_t light);
  // Removes a mesh and every instance of it; later meshes and instances move
  // down. Returns, for each instance index before the call, its index after
  // it (kRemovedIndex for those removed). A change of the mesh list: the
  // next compile is a full one.
  static constexpr uint32_t kRemovedIndex = 0xffffffffu;
  std::vector<uint32_t> remove_mesh(uint32_t mesh);
  Material& edit_material(uint32_t material);
  Light& edit_light(uint32_t light);
  // Caller may change vertex attributes in place but not the vertex count.
  Mesh& edit_mesh_vertices(uint32_t mesh);
  // The same for vertices [first_vertex, first_vertex + count) only: the
  // caller changes no attribute outside that range, so the compiler converts
  // and uploads just those vertices. Ranges edited before the next compile
  // merge into their bounding range. Throws std::out_of_range when the range
  // does not fit the mesh; count 0 marks nothing.
  Mesh& edit_mesh_vertices(uint32_t mesh, uint32_t first_vertex, uint32_t count);
  Camera& edit_camera();
  Environment& edit_environment();
  // Marks a mesh whose vertices a deformer rewrites every frame (a skin,
  // morph targets): its BLAS is then built to be refit each frame rather
  // than with the spatial splits of static meshes (kMeshDeforms). Meant for
  // loaders, before the first compile; a later change rebuilds the mesh's
  // BLAS (kDirtyTopology).
  void set_mesh_deforms(uint32_t mesh, bool deforms = true);

  // Sets all of a mesh's vertices to `pose` (core/world/mesh_pose.h; its
  // vertex count is the mesh's), marking them edited as
  // edit_mesh_vertices(mesh) does. The Scene's own copy is written from the
  // pose only when something reads or edits the mesh's vertices through
  // this Scene (meshes(), mesh(), edit_mesh_vertices(), bounds()), once;
  // until then the compiler writes the pose straight into the kernel
  // arrays (compiled_pose()). A later pose replaces one not yet written.
  void pose_mesh(uint32_t mesh, std::shared_ptr<const MeshPose> pose);
  // Whether the mesh's copy still waits for its pose to be written.
  bool mesh_pose_unwritten(uint32_t mesh) const {
    return mesh < unwritten_poses_.size() && unwritten_poses_[mesh] != nullptr;
  }
  // The pose the mesh's vertices were last set to, when every vertex edit
  // since the last clear_dirty() was a pose_mesh(): the attributes a pose
  // does not write are then as the consumer of the dirty flags last took
  // them, so it may write this pose instead of copying the mesh. Null
  // otherwise.
  const MeshPose* compiled_pose(uint32_t mesh) const {
    return mesh < poses_since_clear_.size() ? poses_since_clear_[mesh].get() : nullptr;
  }

  // --- reading -------------------------------------------------------------
  const std::vector<Texture>& textures() const { return textures_; }
  const std::vector<Material>& materials() const { return materials_; }
  // Writes the unwritten poses first (pose_mesh()), so even these const
  // readers must not run concurrently with another call. mesh() writes
  // only that mesh's.
  const std::vector<Mesh>& meshes() const {
    if (unwritten_count_ != 0) write_unwritten_poses();
    return meshes_;
  }
  const Mesh& mesh(uint32_t mesh) const {
    write_unwritten_pose(mesh);
    return meshes_.at(mesh);
  }
  // What needs no vertex data: these never write a pose.
  size_t mesh_count() const { return meshes_.size(); }
  const std::string& mesh_name(uint32_t mesh) const { return meshes_.at(mesh).name; }
  size_t mesh_vertex_count(uint32_t mesh) const { return meshes_.at(mesh).positions.size(); }
  const std::vector<Instance>& instances() const { return instances_; }
  const std::vector<Light>& lights() const { return lights_; }
  const Camera& camera() const { return camera_; }
  const Environment& environment() const { return environment_; }
  bool has_camera() const { return has_camera_; }
  bool mesh_deforms(uint32_t mesh) const {
    return mesh < mesh_deforms_.size() && mesh_deforms_[mesh] != 0;
  }

  size_t triangle_count_unique() const;     // sum over meshes
  size_t triangle_count_instanced() const;  // sum over instances
  // World-space bounds of all instances, from per-mesh and per-instance
  // boxes cached across edits (scene_bounds.h): O(k log n) after k edits.
  // Like every Scene method it must not run concurrently with another call
  // on the same Scene.
  SceneBounds bounds() const;
  // Mesh `mesh`'s object-space box (finite says whether all its vertices
  // are), brought up to date as bounds() does.
  SceneBounds mesh_bounds(uint32_t mesh) const;

  // --- change tracking -------------------------------------------------------
  const std::vector<uint32_t>& texture_dirty() const { return textures_dirty_.mask; }
  const std::vector<uint32_t>& material_dirty() const { return materials_dirty_.mask; }
  const std::vector<uint32_t>& mesh_dirty() const { return meshes_dirty_.mask; }
  const std::vector<uint32_t>& instance_dirty() const { return instances_dirty_.mask; }
  const std::vector<uint32_t>& light_dirty() const { return lights_dirty_.mask; }
  bool camera_dirty() const { return camera_dirty_; }
  bool environment_dirty() const { return environment_dirty_; }
  // The indices whose mask above is non-zero, in the order they were first
  // marked: what the compiler walks, so k edits cost O(k), not O(scene).
  const std::vector<uint32_t>& dirty_textures() const { return textures_dirty_.list; }
  const std::vector<uint32_t>& dirty_materials() const { return materials_dirty_.list; }
  const std::vector<uint32_t>& dirty_meshes() const { return meshes_dirty_.list; }
  const std::vector<uint32_t>& dirty_instances() const { return instances_dirty_.list; }
  const std::vector<uint32_t>& dirty_lights() const { return lights_dirty_.list; }
  // The vertices of a mesh edited since the last compile: [begin, end), the
  // whole mesh for a new mesh or a whole-mesh edit, empty when it has no
  // kDirtyVertices.
  struct VertexRange {
    uint32_t begin = 0, end = 0;
    bool empty() const { return end <= begin; }
  };
  VertexRange mesh_dirty_vertices(uint32_t mesh) const;
  // Changes whenever the mesh's vertices may have been edited (every
  // edit_mesh_vertices call): unique across all scenes of the process, so a
  // writer that recorded it after its own edit knows, when it is unchanged,
  // that the mesh still holds what it wrote.
  uint64_t mesh_vertex_version(uint32_t mesh) const {
    return mesh < mesh_vertex_versions_.size() ? mesh_vertex_versions_[mesh] : 0;
  }
  bool any_dirty() const;
  void clear_dirty();

  // Optional description for `tandem info` (e.g. glTF generator, file name).
  std::string source;
  // The scene as messages name it: its source, or "the scene".
  std::string source_name() const { return source.empty() ? std::string("the scene") : source; }

 private:
  std::vector<Texture> textures_;
  std::vector<Material> materials_;
  // Mutable for the unwritten poses only: writing one brings into memory
  // what the mesh already holds as far as any reader can tell.
  mutable std::vector<Mesh> meshes_;
  std::vector<Instance> instances_;
  std::vector<Light> lights_;
  Camera camera_;
  Environment environment_;
  bool has_camera_ = false;

  // Per-object dirty masks and the list of the marked ones.
  struct DirtySet {
    std::vector<uint32_t> mask, list;
    uint32_t add(uint32_t bits);  // a new object; returns its index
    void mark(uint32_t index, uint32_t bits);
    // Drops the objects `removed` (by index, each 0 or 1) from the mask
    // and the list, renumbering the rest.
    void erase(const std::vector<uint8_t>& removed);
    void clear();
  };
  DirtySet textures_dirty_, materials_dirty_, meshes_dirty_, instances_dirty_, lights_dirty_;
  // Per mesh, its edited vertex range; valid where meshes_dirty_ has
  // kDirtyVertices, reset with the dirty list.
  std::vector<VertexRange> mesh_vertex_ranges_;
  std::vector<uint64_t> mesh_vertex_versions_;
  std::vector<uint8_t> mesh_deforms_;
  void mark_vertices(uint32_t mesh, uint32_t begin, uint32_t end);
  // Per mesh, the pose its copy still waits for (null: none), and how many
  // are not null; and compiled_pose().
  mutable std::vector<std::shared_ptr<const MeshPose>> unwritten_poses_;
  mutable uint32_t unwritten_count_ = 0;
  std::vector<std::shared_ptr<const MeshPose>> poses_since_clear_;
  void write_unwritten_poses() const;
  void write_unwritten_pose(uint32_t mesh) const;
  mutable SceneBoundsCache bounds_cache_;
  bool camera_dirty_ = true;
  bool environment_dirty_ = true;
};

// Places a camera that frames the scene bounds (used when a file has none).
Camera frame_bounds_camera(const SceneBounds& bounds, float yfov, float aspect);

}  // namespace tandem
