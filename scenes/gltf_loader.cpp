// glTF entry point: reads the file, runs tinygltf, validates, converts, and
// walks the chosen scene's node tree into instances, camera and lights.
#include "scenes/gltf_loader.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "core/util/errors.h"
#include "core/util/log.h"
#include "core/world/kernel_conversions.h"
#include "core/world/scene_ranges.h"
#include "scenes/gltf_internal.h"
#include "scenes/gltf_validate.h"

namespace tandem {

namespace gltf {

void Context::fail(const std::string& reason) const {
  throw InputError(path_ + ": " + reason);
}
void Context::warn(const std::string& message) const {
  log_warning(path_ + ": " + message);
}
void Context::warn_once(const std::string& key, const std::string& message) {
  if (warned_.insert(key).second) warn(message);
}

}  // namespace gltf

namespace {

using gltf::Context;

[[noreturn]] void fail(const std::string& label, const std::string& reason) {
  throw InputError(label + ": " + reason);
}

std::vector<unsigned char> read_file(const std::filesystem::path& path, const std::string& label) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) fail(label, "the file does not exist");
  if (!std::filesystem::is_regular_file(path, ec)) fail(label, "not a regular file");
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) fail(label, "cannot read the file size (" + ec.message() + ")");
  if (size == 0) fail(label, "the file is empty");
  if (size > gltf::kMaxFileBytes) fail(label, "the file is larger than 4 GiB");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) fail(label, std::string("cannot open the file (") + std::strerror(errno) + ")");
  std::vector<unsigned char> data(static_cast<size_t>(size));
  const size_t got = std::fread(data.data(), 1, data.size(), f);
  std::fclose(f);
  if (got != data.size()) fail(label, "cannot read the whole file");
  return data;
}

// tinygltf's messages can span lines and end in "\n"; keep the first line.
std::string first_line(const std::string& text) {
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back())))
      line.pop_back();
    if (!line.empty()) return line;
    start = end + 1;
  }
  return "";
}

// tinygltf's image-loader callback. It never decodes:
//  - for images in a bufferView, `bytes` points into a view tinygltf has not
//    range-checked, so it must not be read before validate_model();
//  - a file that is present but not decodable must only cost that texture
//    (tinygltf's own loader would fail the whole load);
//  - decoding later lets us skip unused images and use all cores.
bool keep_encoded_image(tinygltf::Image* image, const int index, std::string*, std::string*, int,
                        int, const unsigned char* bytes, int size, void* user) {
  if (image->bufferView >= 0) return true;
  auto* encoded = static_cast<gltf::EncodedImages*>(user);
  if (bytes != nullptr && size > 0) encoded->keep(index, bytes, size_t(size));
  return true;
}

// tinygltf reads external buffers and images through these. Only regular
// files: a URI naming a FIFO or device would otherwise block or stream
// forever.
// tinygltf reads external buffers and images through these. Only regular
// files inside the scene's folder (UriPolicy): a URI naming a FIFO or device
// would otherwise block or stream forever, and one naming "../../x" would
// read (and, through tinygltf's size-mismatch message, describe) any file.
bool regular_file_exists(const std::string& path, void* user) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  return user == nullptr || static_cast<gltf::UriPolicy*>(user)->permits(path);
}

bool read_regular_file(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                       void* user) {
  if (!regular_file_exists(path, user)) {
    if (err != nullptr) *err += "Not a regular file : " + path + "\n";
    return false;
  }
  return tinygltf::ReadWholeFile(out, err, path, nullptr);
}

// No expansion of "~" or variables: a URI is a path relative to the file.
std::string keep_file_path(const std::string& path, void*) {
  return path;
}

glm::dmat4 local_transform(const tinygltf::Node& node) {
  if (node.matrix.size() == 16) return glm::make_mat4(node.matrix.data());  // column-major, as glTF
  glm::dmat4 m(1.0);
  if (node.translation.size() == 3) {
    m = glm::translate(m,
                       glm::dvec3(node.translation[0], node.translation[1], node.translation[2]));
  }
  if (node.rotation.size() == 4) {
    // glTF stores x, y, z, w; glm's constructor takes w first.
    const glm::dquat q = glm::normalize(
        glm::dquat(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]));
    m *= glm::mat4_cast(q);
  }
  if (node.scale.size() == 3)
    m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
  return m;
}

bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r])) return false;
    }
  }
  return true;
}

class SceneBuilder {
 public:
  SceneBuilder(Context& ctx, gltf::AccessorCache& cache, gltf::DecodedMeshes& meshes,
               const std::vector<Material>& materials)
      : ctx_(ctx),
        cache_(cache),
        meshes_(meshes),
        materials_(materials),
        mesh_ids_(meshes.meshes.size(), kNotAdded),
        deformed_use_(meshes.meshes.size(), false) {
    // Meshes that some node deforms are copied, never moved, out of the
    // decoded list: every deforming node gets a copy of its own.
    for (const tinygltf::Node& n : ctx.model.nodes) {
      if (n.mesh >= 0 && deforms(n)) deformed_use_[size_t(n.mesh)] = true;
    }
  }

  // Walks the tree under each root depth-first, children in file order (so
  // "the first camera" is the first in that order). Iterative: a hostile
  // file can nest nodes deeply enough to overflow a recursive walk.
  void walk(const std::vector<int>& roots) {
    struct Item {
      int node;
      glm::dmat4 parent;
      int parent_node;
    };
    std::vector<Item> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it)
      stack.push_back({*it, glm::dmat4(1.0), -1});
    while (!stack.empty()) {
      const Item item = stack.back();
      stack.pop_back();
      const tinygltf::Node& node = ctx_.model.nodes[size_t(item.node)];
      const glm::dmat4 world = item.parent * local_transform(node);
      walked_.push_back({item.node, item.parent_node});  // for the animation player
      visit(item.node, node, world);
      for (auto it = node.children.rbegin(); it != node.children.rend(); ++it) {
        stack.push_back({*it, world, item.node});
      }
    }
  }

  bool needs_default_material() const { return needs_default_material_; }
  const std::vector<Instance>& instances() const { return instances_; }
  std::vector<Mesh>& new_meshes() { return new_meshes_; }
  const std::vector<Light>& lights() const { return lights_; }
  // The cameras of the scene's nodes in walk order (degenerate ones left
  // out), and a line about each for `tandem info`.
  const std::vector<Camera>& cameras() const { return cameras_; }
  const std::vector<std::string>& camera_names() const { return camera_names_; }
  const std::vector<gltf::WalkedNode>& walked() const { return walked_; }
  const std::vector<GltfInstanceBinding>& bindings() const { return bindings_; }
  const std::vector<gltf::DeformedNode>& deformed() const { return deformed_; }

 private:
  static constexpr int kNotAdded = -2;

  // Names are for people: a longer one is cut (it is copied to every
  // instance of the node, and EXT_mesh_gpu_instancing makes many).
  static constexpr size_t kMaxNameBytes = 256;
  static constexpr size_t kMaxCameraNames = 100;
  std::string node_name(int index, const tinygltf::Node& node) const {
    if (node.name.empty()) return "node " + std::to_string(index);
    if (node.name.size() <= kMaxNameBytes) return node.name;
    return node.name.substr(0, kMaxNameBytes - 3) + "...";
  }

  // Emissive triangles of tandem mesh `id`: each becomes a light record,
  // once for all the instances of it.
  uint64_t emissive_triangles(int id) {
    if (emissive_counts_.size() <= size_t(id)) emissive_counts_.resize(size_t(id) + 1, -1);
    int64_t& n = emissive_counts_[size_t(id)];
    if (n >= 0) return uint64_t(n);
    n = 0;
    for (uint32_t m : new_meshes_[size_t(id)].triangle_materials)
      n += m < materials_.size() && material_emits(materials_[m]) ? 1 : 0;
    return uint64_t(n);
  }

  // Charges `count` instances of tandem mesh `mesh` named `name` (with a
  // suffix of up to `suffix` bytes each) to the name and light budgets,
  // before any is made.
  void charge_instances(uint64_t count, int mesh, const std::string& name, size_t suffix,
                        const std::string& who) {
    // std::string keeps up to 15 bytes inline.
    const uint64_t name_bytes = name.size() + suffix > 15 ? name.size() + suffix + 1 : 0;
    ctx_.charge(gltf::Budget::kNameBytes, count * name_bytes,
                who + " (" + std::to_string(count) + " instance" + (count == 1 ? "" : "s") +
                    " named '" + name.substr(0, 40) + (name.size() > 40 ? "...'" : "'") + ")");
    const uint64_t lights = emissive_triangles(mesh);
    if (lights > 0) {
      // The mesh's triangles the first time it is placed, a light for
      // each instance every time.
      if (emissive_charged_.size() <= size_t(mesh)) emissive_charged_.resize(size_t(mesh) + 1, 0);
      const uint64_t once = emissive_charged_[size_t(mesh)] ? 0 : lights;
      emissive_charged_[size_t(mesh)] = 1;
      ctx_.charge(gltf::Budget::kEmissiveLights, once + count,
                  who + " (" + std::to_string(count) + " instance" + (count == 1 ? "" : "s") +
                      " of mesh '" + new_meshes_[size_t(mesh)].name.substr(0, 40) + "' with " +
                      std::to_string(lights) + " emissive triangles)");
    }
  }
  // "node 3 ('arm')" for messages.
  std::string node_label(int index) const {
    const std::string& name = ctx_.model.nodes[size_t(index)].name;
    return "node " + std::to_string(index) +
           (name.empty() ? ""
                         : " ('" + name.substr(0, 80) + (name.size() > 80 ? "...'" : "'") + ")");
  }

  // A node whose mesh changes shape over time: skinned, or morph targets.
  bool deforms(const tinygltf::Node& n) const {
    return n.skin >= 0 ||
           (n.mesh >= 0 && !ctx_.model.meshes[size_t(n.mesh)].primitives.front().targets.empty());
  }

  // Tandem mesh for glTF mesh `mi`; -1 if it has no triangles. glTF meshes
  // with identical primitives (same accessors and materials) share one.
  int mesh_id(int mi) {
    int& id = mesh_ids_[size_t(mi)];
    if (id != kNotAdded) return id;
    Mesh& mesh = meshes_.meshes[size_t(mi)];
    if (mesh.triangles.empty()) {
      ctx_.warn("mesh " + std::to_string(mi) + " has no triangles and is not shown");
      return id = -1;
    }
    const auto [it, inserted] =
        mesh_by_key_.emplace(meshes_.keys[size_t(mi)], int(new_meshes_.size()));
    if (inserted) {
      new_meshes_.push_back(deformed_use_[size_t(mi)] ? mesh : std::move(mesh));
      if (meshes_.uses_default_material[size_t(mi)]) needs_default_material_ = true;
    }
    return id = it->second;
  }

  // A copy of glTF mesh `mi` for deforming node `node` alone; -1 if the
  // mesh has no triangles.
  int deformed_mesh_id(int mi, int node) {
    const Mesh& mesh = meshes_.meshes[size_t(mi)];
    if (mesh.triangles.empty()) {
      ctx_.warn_once("no-triangles" + std::to_string(mi),
                     "mesh " + std::to_string(mi) + " has no triangles and is not shown");
      return -1;
    }
    constexpr uint64_t kVertexBytes =
        sizeof(glm::vec3) * 2 + sizeof(glm::vec4) + sizeof(glm::vec2) * 2;
    ctx_.charge(
        gltf::Budget::kGeometryBytes,
        uint64_t(mesh.positions.size()) * kVertexBytes * 2 +
            uint64_t(mesh.triangles.size()) * (sizeof(glm::uvec3) + sizeof(uint32_t)),
        "deforming copy of mesh " + std::to_string(mi) + " for node " + std::to_string(node));
    const int id = int(new_meshes_.size());
    new_meshes_.push_back(mesh);
    if (meshes_.uses_default_material[size_t(mi)]) needs_default_material_ = true;
    deformed_.push_back({node, uint32_t(id)});
    return id;
  }

  // `local`: an EXT_mesh_gpu_instancing entry's transform under the node.
  // A skinned node's instance has no `world`: its joints place it.
  void add_instance(const std::string& name, int mesh, const glm::dmat4& world, int node_index,
                    const glm::dmat4& local = glm::dmat4(1.0), bool charge = true) {
    if (charge) {
      ctx_.charge(gltf::Budget::kInstances, 1, "node " + std::to_string(node_index) + " instance");
      charge_instances(1, mesh, name, 0, node_label(node_index));
    }
    const bool skinned = ctx_.model.nodes[size_t(node_index)].skin >= 0;
    const glm::mat4 transform(skinned ? local : world * local);
    bindings_.push_back(
        {uint32_t(instances_.size()), uint32_t(node_index), glm::mat4(local), skinned});
    if (!finite(transform)) {
      ctx_.fail(node_label(node_index) +
                " has a world transform that is not finite (its scales or translations, "
                "multiplied along its parents, overflow float)");
    }
    instances_.push_back(Instance{name, uint32_t(mesh), transform});
  }

  void visit(int index, const tinygltf::Node& node, const glm::dmat4& world) {
    if (node.mesh >= 0) {
      const int mesh = deforms(node) ? deformed_mesh_id(node.mesh, index) : mesh_id(node.mesh);
      const auto gpu = node.extensions.find("EXT_mesh_gpu_instancing");
      if (mesh < 0) {
        // nothing to show
      } else if (gpu != node.extensions.end()) {
        add_gpu_instances(index, node, gpu->second, mesh, world);
      } else {
        add_instance(node_name(index, node), mesh, world, index);
      }
    }
    if (node.camera >= 0) add_camera(index, node, world);
    const auto light = node.extensions.find("KHR_lights_punctual");
    if (light != node.extensions.end())
      add_light(index, light->second.Get("light").Get<int>(), world);
  }

  // EXT_mesh_gpu_instancing: one instance per entry, node_world * T * R * S.
  void add_gpu_instances(int index, const tinygltf::Node& node, const tinygltf::Value& ext,
                         int mesh, const glm::dmat4& world) {
    const std::string who = "node " + std::to_string(index) + " EXT_mesh_gpu_instancing";
    const tinygltf::Value& attrs = ext.Get("attributes");
    auto read = [&](const char* name) -> const std::vector<float>* {
      if (!attrs.Has(name)) return nullptr;
      return &cache_.floats(attrs.Get(name).Get<int>(), who + " " + name);
    };
    const std::vector<float>* t = read("TRANSLATION");
    const std::vector<float>* r = read("ROTATION");
    const std::vector<float>* s = read("SCALE");
    size_t count = 0;
    for (const std::string& name : attrs.Keys()) {
      count = ctx_.model.accessors[size_t(attrs.Get(name).Get<int>())].count;
    }
    if (t == nullptr && r == nullptr && s == nullptr) {
      ctx_.warn(who + " has no TRANSLATION, ROTATION or SCALE; the node is shown once");
      add_instance(node_name(index, node), mesh, world, index);
      return;
    }
    const std::string base = node_name(index, node);
    // Charged up front so a huge count fails before any instance is made.
    ctx_.charge(gltf::Budget::kInstances, count, who + " (" + std::to_string(count) + " entries)");
    charge_instances(count, mesh, base, 2 + std::to_string(count).size(), who);
    for (size_t i = 0; i < count; ++i) {
      glm::dmat4 m(1.0);
      if (t) m = glm::translate(m, glm::dvec3((*t)[3 * i], (*t)[3 * i + 1], (*t)[3 * i + 2]));
      if (r) {
        const glm::dquat q((*r)[4 * i + 3], (*r)[4 * i], (*r)[4 * i + 1], (*r)[4 * i + 2]);
        const double len = glm::length(q);
        if (!(len > 1e-6))
          ctx_.fail(who + " ROTATION " + std::to_string(i) + " is a zero quaternion");
        m *= glm::mat4_cast(q / len);
      }
      if (s) m = glm::scale(m, glm::dvec3((*s)[3 * i], (*s)[3 * i + 1], (*s)[3 * i + 2]));
      add_instance(base + "[" + std::to_string(i) + "]", mesh, world, index, m, false);
    }
  }

  // Unit vector of `world` applied to direction `d`, or false if degenerate.
  static bool direction(const glm::dmat4& world, const glm::dvec3& d, glm::vec3& out) {
    const glm::dvec3 v(world * glm::dvec4(d, 0.0));
    const double len = glm::length(v);
    if (!(len > 1e-30) || !std::isfinite(len)) return false;
    out = glm::vec3(v / len);
    return true;
  }

  void add_camera(int index, const tinygltf::Node& node, const glm::dmat4& world) {
    const tinygltf::Camera& gc = ctx_.model.cameras[size_t(node.camera)];
    Camera cam;
    // glTF cameras look down their local -Z with +Y up.
    glm::vec3 forward, up;
    const glm::vec3 position(world[3]);
    if (!direction(world, {0, 0, -1}, forward) || !direction(world, {0, 1, 0}, up) ||
        !std::isfinite(position.x) || !std::isfinite(position.y) || !std::isfinite(position.z)) {
      ctx_.warn("camera on node " + std::to_string(index) +
                " has a degenerate transform; it is ignored");
      return;
    }
    up -= forward * glm::dot(up, forward);  // orthogonalize (non-uniform scale can skew it)
    if (!(glm::length(up) > 1e-6f)) {
      ctx_.warn("camera on node " + std::to_string(index) +
                " has no usable up vector; it is ignored");
      return;
    }
    cam.position = position;
    cam.forward = forward;
    cam.up = glm::normalize(up);
    if (gc.type == "orthographic") {
      cam.type = CameraType::kOrthographic;
      cam.ortho_half_height = float(std::fabs(gc.orthographic.ymag));
      if (gc.orthographic.ymag != 0.0) {
        cam.aspect_ratio = float(std::fabs(gc.orthographic.xmag / gc.orthographic.ymag));
      }
    } else {
      cam.type = CameraType::kPerspective;
      cam.yfov = float(gc.perspective.yfov);
      // Optional in glTF; used to pick the image shape when only one of
      // --width/--height is given.
      if (gc.perspective.aspectRatio > 0.0 && std::isfinite(gc.perspective.aspectRatio)) {
        cam.aspect_ratio = float(gc.perspective.aspectRatio);
      }
    }
    if (!(cam.aspect_ratio > 0.0f) || !std::isfinite(cam.aspect_ratio) ||
        cam.aspect_ratio > 100.0f) {
      cam.aspect_ratio = 0.0f;
    }
    cameras_.push_back(cam);
    if (camera_names_.size() >= kMaxCameraNames) return;  // a hostile file's millions
    char fov[32];
    std::snprintf(fov, sizeof(fov), "%.1f", double(cam.yfov) * 180.0 / 3.141592653589793);
    camera_names_.push_back(node_name(index, node) +
                            (cam.type == CameraType::kOrthographic
                                 ? std::string(", orthographic")
                                 : ", perspective, " + std::string(fov) + " degrees vertical"));
  }

  void add_light(int index, int light_index, const glm::dmat4& world) {
    const tinygltf::Light& gl = ctx_.model.lights[size_t(light_index)];
    Light l;
    l.name = gl.name.empty() ? "light " + std::to_string(light_index) : gl.name;
    l.type = gl.type == "spot"          ? LightType::kSpot
             : gl.type == "directional" ? LightType::kDirectional
                                        : LightType::kPoint;
    if (gl.color.size() == 3)
      l.color = glm::vec3(float(gl.color[0]), float(gl.color[1]), float(gl.color[2]));
    l.intensity = float(gl.intensity);
    l.position = glm::vec3(world[3]);
    if (!direction(world, {0, 0, -1}, l.direction) && l.type != LightType::kPoint) {
      ctx_.warn("light on node " + std::to_string(index) +
                " has a degenerate transform; it is ignored");
      return;
    }
    if (!std::isfinite(l.position.x) || !std::isfinite(l.position.y) ||
        !std::isfinite(l.position.z)) {
      ctx_.fail("the light on " + node_label(index) +
                " has a world position that is not finite (its parents' transforms overflow "
                "float)");
    }
    l.inner_cone_angle = float(gl.spot.innerConeAngle);
    l.outer_cone_angle = float(gl.spot.outerConeAngle);
    lights_.push_back(l);
  }

  Context& ctx_;
  gltf::AccessorCache& cache_;
  gltf::DecodedMeshes& meshes_;
  const std::vector<Material>& materials_;
  std::vector<int64_t> emissive_counts_;  // by tandem mesh; -1: not counted yet
  std::vector<int> mesh_ids_;
  std::vector<uint8_t> emissive_charged_;  // charge_instances: the mesh's lights charged
  std::vector<bool> deformed_use_;         // by glTF mesh: some node deforms it
  std::vector<gltf::DeformedNode> deformed_;
  std::map<std::string, int> mesh_by_key_;
  std::vector<Mesh> new_meshes_;
  std::vector<Instance> instances_;
  std::vector<Light> lights_;
  std::vector<Camera> cameras_;
  std::vector<std::string> camera_names_;
  bool needs_default_material_ = false;
  std::vector<gltf::WalkedNode> walked_;
  std::vector<GltfInstanceBinding> bindings_;  // one per instance, in order
};

// Animations need no word: the commands that play them load them, the
// others show the rest pose as any single frame would.
void warn_about_extensions(Context& ctx) {
  for (const std::string& ext : ctx.model.extensionsUsed) {
    if (gltf::extension_supported(ext) || ext == "KHR_xmp" || ext == "KHR_xmp_json_ld") continue;
    ctx.warn("extension " + ext + " is not supported; its data is ignored");
  }
}

}  // namespace

namespace {

// Refuses JSON nested deeper than the limit, and values the schema forbids
// (which tinygltf would read as absent), before tinygltf parses it.
void check_json_nesting(const std::string& label, const unsigned char* data, size_t size,
                        bool binary, uint32_t limit) {
  const char* json = reinterpret_cast<const char*>(data);
  size_t json_size = size;
  if (binary && !gltf::glb_json_chunk(data, size, &json, &json_size)) return;  // tinygltf explains
  size_t where = 0;
  if (gltf::json_nesting_depth(json, json_size, limit, &where) > limit) {
    fail(label, "the JSON is nested more than " + std::to_string(limit) + " levels deep (at byte " +
                    std::to_string(where + (binary ? 20 : 0)) + "); refusing to parse it");
  }
  gltf::check_schema_ranges(json, json_size, label);
}

Scene load_parsed(const std::string& label, tinygltf::Model& model, gltf::EncodedImages& encoded,
                  const GltfOptions& options, GltfSummary* summary, std::string& stage);

}  // namespace

Scene load_gltf(const std::filesystem::path& path, const GltfOptions& options,
                GltfSummary* summary) {
  const std::string label = path.string();
  std::vector<unsigned char> data;
  try {
    data = read_file(path, label);
  } catch (const std::bad_alloc&) {
    fail(label, "not enough memory to read the file");
  }
  return load_gltf_from_memory(data.data(), data.size(), label,
                               path.has_parent_path() ? path.parent_path() : ".", options, summary);
}

Scene load_gltf_from_memory(const unsigned char* data, size_t size, const std::string& label,
                            const std::filesystem::path& base_dir, const GltfOptions& options,
                            GltfSummary* summary) {
  if (size == 0) fail(label, "the file is empty");
  if (size > gltf::kMaxFileBytes) fail(label, "the file is larger than 4 GiB");
  std::string ext = std::filesystem::path(label).extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool magic = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const bool binary = magic || ext == ".glb";  // .glb without magic: let tinygltf explain
  if (!binary && size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) {
    fail(label, "the file starts with a UTF-8 byte order mark, which glTF forbids");
  }
  check_json_nesting(label, data, size, binary, options.limits.max_json_depth);
  if (const std::string problem = gltf::glb_bin_chunk_problem(data, size); !problem.empty()) {
    fail(label, problem);
  }

  // Whatever runs out of memory, the message names the file and the stage
  // (InputErrors, budgets included, pass through unchanged).
  std::string stage = "parsing the JSON";
  try {
    tinygltf::Model model;
    gltf::EncodedImages encoded;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&keep_encoded_image, &encoded);
    gltf::UriPolicy policy;
    policy.allow_outside = options.allow_outside_uris;
    policy.joined_base = base_dir.string();
    std::error_code ec;
    policy.base_dir = std::filesystem::canonical(base_dir, ec);
    loader.SetFsCallbacks({&regular_file_exists, &keep_file_path, &read_regular_file,
                           &tinygltf::WriteWholeFile, &policy});
    std::string err, warn;
    bool ok = false;
    try {
      ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, data, unsigned(size),
                                                base_dir.string())
                  : loader.LoadASCIIFromString(&model, &err, &warn,
                                               reinterpret_cast<const char*>(data), unsigned(size),
                                               base_dir.string());
    } catch (const std::bad_alloc&) {
      throw;
    } catch (const std::exception& e) {
      // tinygltf catches JSON errors but not, e.g., std::vector::at on odd input.
      fail(label, std::string("invalid glTF: ") + e.what());
    }
    if (!ok) {
      if (!policy.refused.empty()) fail(label, policy.refused);
      const std::string reason = first_line(err);
      fail(label,
           "invalid glTF: " + (reason.empty() ? "tinygltf could not parse the file" : reason));
    }
    // tinygltf reports missing required properties in `err` but carries on
    // without the object (e.g. drops a primitive with no "attributes").
    if (!first_line(err).empty()) fail(label, "invalid glTF: " + first_line(err));
    // Its warnings are about images, which we report ourselves, by name.
    if (!warn.empty()) log_debug(label + ": tinygltf: " + first_line(warn));
    // Images tinygltf could not read because the policy refused them.
    for (size_t i = 0; i < model.images.size(); ++i) {
      const tinygltf::Image& img = model.images[i];
      if (img.bufferView >= 0 || img.uri.empty() || img.uri.rfind("data:", 0) == 0) continue;
      if (encoded.has(int(i))) continue;
      gltf::UriPolicy probe = policy;
      probe.refused.clear();
      if (!probe.permits(policy.joined_base + "/" + img.uri))
        encoded.errors[int(i)] = probe.refused;
    }
    return load_parsed(label, model, encoded, options, summary, stage);
  } catch (const std::bad_alloc&) {
    fail(label,
         "ran out of memory while " + stage + " (the file needs more memory than is available)");
  } catch (const std::length_error&) {
    fail(label, "an array became too large to allocate while " + stage);
  }
}

namespace {

Scene load_parsed(const std::string& label, tinygltf::Model& model, gltf::EncodedImages& encoded,
                  const GltfOptions& options, GltfSummary* summary, std::string& stage) {
  stage = "validating the file";
  Context ctx(label, model, options.limits);
  gltf::validate_model(ctx);
  warn_about_extensions(ctx);

  int scene_index = options.scene_index;
  if (scene_index < -1) fail(label, "scene index " + std::to_string(scene_index) + " is invalid");
  if (scene_index == -1) {
    scene_index = model.defaultScene >= 0 ? model.defaultScene : model.scenes.empty() ? -1 : 0;
  } else if (size_t(scene_index) >= model.scenes.size()) {
    fail(label, "scene index " + std::to_string(scene_index) + " is out of range (the file has " +
                    std::to_string(model.scenes.size()) + " scene" +
                    (model.scenes.size() == 1 ? "" : "s") + ")");
  }

  gltf::AccessorCache cache(ctx);
  const uint32_t default_material = uint32_t(model.materials.size());
  stage = "decoding meshes";
  gltf::DecodedMeshes meshes = gltf::decode_meshes(ctx, cache, default_material);
  {
    // Within the budget a small file can still decode to far more than it
    // holds (one accessor drawn by many primitives, zero-filled ones): it
    // says so, as the textures do.
    uint64_t buffer_bytes = 0;
    for (const tinygltf::Buffer& b : model.buffers)
      buffer_bytes += b.data.size();
    const uint64_t geometry = ctx.used(gltf::Budget::kGeometryBytes);
    if (geometry > (uint64_t(512) << 20) && geometry > 64 * buffer_bytes) {
      ctx.warn("its " + gltf::format_bytes(buffer_bytes) + " of buffers decode to " +
               gltf::format_bytes(geometry) + " of mesh geometry");
    }
  }
  stage = "decoding textures";
  gltf::MaterialResult materials = gltf::convert_materials(ctx, encoded);
  stage = "building the scene";

  std::vector<int> roots;
  if (scene_index >= 0) {
    roots = model.scenes[size_t(scene_index)].nodes;
  } else {
    // No scenes: show every root node rather than nothing.
    std::vector<bool> is_child(model.nodes.size(), false);
    for (const tinygltf::Node& n : model.nodes) {
      for (int c : n.children)
        is_child[size_t(c)] = true;
    }
    for (size_t i = 0; i < model.nodes.size(); ++i) {
      if (!is_child[i]) roots.push_back(int(i));
    }
    if (!roots.empty()) ctx.warn("the file has no scenes; showing all root nodes");
  }
  SceneBuilder builder(ctx, cache, meshes, materials.materials);
  builder.walk(roots);
  // The hierarchy is needed to pose skins and morphs even when the caller
  // does not play animations: the static scene shows their rest pose.
  GltfAnimations local_animations;
  GltfAnimations& animations =
      options.animations != nullptr ? *options.animations : local_animations;
  if (options.animations != nullptr || !builder.deformed().empty()) {
    gltf::load_animations(ctx, cache, builder.walked(), builder.bindings(), animations,
                          options.animations != nullptr);
    gltf::load_deformers(ctx, cache, builder.deformed(), builder.new_meshes(), animations);
  }

  Scene scene;
  for (Texture& t : materials.textures)
    scene.add_texture(std::move(t));
  for (Material& m : materials.materials)
    scene.add_material(std::move(m));
  if (builder.needs_default_material()) {
    Material m;  // glTF's default material: white, metallic 1, roughness 1
    m.name = "default";
    scene.add_material(m);
  }
  for (Mesh& m : builder.new_meshes())
    scene.add_mesh(std::move(m));
  // Meshes that the animations will deform every frame.
  if (options.animations != nullptr) {
    for (const GltfDeformedMesh& d : animations.deformed)
      scene.set_mesh_deforms(d.deformation->mesh);
  }
  for (const Instance& i : builder.instances())
    scene.add_instance(i);
  for (const Light& l : builder.lights())
    scene.add_light(l);
  if (!animations.deformed.empty()) {
    deform_gltf_meshes(animations, animations.nodes,
                       gltf_world_transforms(animations, animations.nodes), scene);
  }
  const std::vector<Camera>& cameras = builder.cameras();
  if (options.camera >= 0 && size_t(options.camera) >= cameras.size()) {
    fail(label, "camera " + std::to_string(options.camera) + " was asked for, but the scene has " +
                    std::to_string(cameras.size()) + " camera" + (cameras.size() == 1 ? "" : "s") +
                    (cameras.empty() ? "" : " (0 to " + std::to_string(cameras.size() - 1) + ")"));
  }
  if (!cameras.empty()) {
    Camera cam = cameras[size_t(std::max(options.camera, 0))];
    const SceneBounds bounds = scene.bounds();
    if (!bounds.empty) {
      // Focus on the plane through the scene's centre; if that is behind the
      // camera, at the centre's distance.
      const glm::vec3 to_center = bounds.center() - cam.position;
      const float along = glm::dot(to_center, cam.forward);
      const float distance = along > 1e-6f ? along : glm::length(to_center);
      if (std::isfinite(distance) && distance > 0.0f) cam.focus_distance = distance;
    }
    scene.set_camera(cam);
  }
  if (scene.triangle_count_instanced() == 0) ctx.warn("the scene has no triangles");
  // Positions that overflow float after the products (scale, skinning,
  // morph targets), the camera, lights and emission the tracers cannot
  // take: refused here, naming the file and the object.
  check_scene_traceable(scene, label);
  scene.source =
      std::filesystem::path(label).filename().string() +
      (model.asset.generator.empty() ? "" : " (generator: " + model.asset.generator + ")");

  if (summary != nullptr) {
    GltfSummary& s = *summary;
    s = GltfSummary{};
    s.generator = model.asset.generator;
    s.scenes = model.scenes.size();
    s.scene_loaded = scene_index;
    s.nodes = model.nodes.size();
    s.meshes = model.meshes.size();
    s.primitives = meshes.primitives;
    s.file_triangles = meshes.file_triangles;
    s.degenerate_triangles_dropped = meshes.dropped_degenerate;
    s.materials = model.materials.size();
    s.textures = model.textures.size();
    s.images = model.images.size();
    s.images_unavailable = materials.images_unavailable;
    s.samplers = model.samplers.size();
    s.cameras = model.cameras.size();
    s.scene_cameras = builder.cameras().size();
    s.camera_names = builder.camera_names();
    s.camera_list.assign(
        builder.cameras().begin(),
        builder.cameras().begin() +
            std::ptrdiff_t(std::min(builder.cameras().size(), s.camera_names.size())));
    s.lights = model.lights.size();
    s.animations = model.animations.size();
    s.skins = model.skins.size();
    s.extensions_used = model.extensionsUsed;
    s.extensions_required = model.extensionsRequired;
    gltf::describe_file_contents(model, s);
  }
  return scene;
}

}  // namespace

}  // namespace tandem
