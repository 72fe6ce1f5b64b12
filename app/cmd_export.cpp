// `tandem export SCENE --output FILE.gltf`: a scene as Tandem holds it
// (a glTF file as loaded, or a built-in scene) written as one self-contained
// glTF 2.0 file, so that another renderer (Blender Cycles, for the
// comparisons in tools/compare) draws the same geometry, materials, lights
// and camera. Each Tandem mesh becomes a glTF mesh of one primitive per
// material, each instance a node with its matrix, each light a
// KHR_lights_punctual light (its intensity radiometric, as Tandem reads it),
// the camera a camera node. Textures, skins, morph targets, animations and
// the environment are not written (a warning says which the scene had).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/commands.h"
#include "app/json_writer.h"
#include "app/scene_setup.h"
#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/log.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& export_options() {
  static const std::vector<OptionSpec> own = {
      {"output", true, "the .gltf file to write (required)", "FILE"},
  };
  static const std::vector<OptionSpec> specs =
      compose_options({scene_options(), own, help_options()});
  return specs;
}

std::string base64(const std::vector<uint8_t>& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const uint32_t b0 = bytes[i], b1 = i + 1 < bytes.size() ? bytes[i + 1] : 0,
                   b2 = i + 2 < bytes.size() ? bytes[i + 2] : 0;
    const uint32_t v = (b0 << 16) | (b1 << 8) | b2;
    out += digits[(v >> 18) & 63];
    out += digits[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? digits[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? digits[v & 63] : '=';
  }
  return out;
}

JsonValue numbers(const float* v, int n) {
  JsonValue a = JsonValue::array();
  for (int i = 0; i < n; ++i)
    a.push(double(v[i]));
  return a;
}

// The glTF document being written: one buffer, a view and an accessor per
// array.
class GltfDocument {
 public:
  // Appends `count` elements of `type` ("VEC3", "SCALAR", ...) of
  // component type `component` (5126 float, 5125 uint32); returns the
  // accessor. With `lo`/`hi` (POSITION), their bounds.
  int accessor(const void* data, size_t bytes, size_t count, const char* type, int component,
               const JsonValue* lo = nullptr, const JsonValue* hi = nullptr) {
    while (buffer_.size() % 4)
      buffer_.push_back(0);
    const size_t offset = buffer_.size();
    buffer_.resize(offset + bytes);
    std::memcpy(buffer_.data() + offset, data, bytes);
    views_.push(JsonValue::object()
                    .set("buffer", 0)
                    .set("byteOffset", uint64_t(offset))
                    .set("byteLength", uint64_t(bytes)));
    JsonValue a = JsonValue::object()
                      .set("bufferView", view_count_++)
                      .set("componentType", component)
                      .set("count", uint64_t(count))
                      .set("type", type);
    if (lo) a.set("min", *lo).set("max", *hi);
    accessors_.push(std::move(a));
    return accessor_count_++;
  }
  JsonValue finish(JsonValue doc) {
    doc.set("buffers",
            JsonValue::array().push(
                JsonValue::object()
                    .set("byteLength", uint64_t(buffer_.size()))
                    .set("uri", "data:application/octet-stream;base64," + base64(buffer_))));
    doc.set("bufferViews", std::move(views_));
    doc.set("accessors", std::move(accessors_));
    return doc;
  }

 private:
  std::vector<uint8_t> buffer_;
  JsonValue views_ = JsonValue::array(), accessors_ = JsonValue::array();
  int view_count_ = 0, accessor_count_ = 0;
};

JsonValue material_json(const Material& m) {
  JsonValue pbr = JsonValue::object()
                      .set("baseColorFactor", numbers(&m.base_color.x, 4))
                      .set("metallicFactor", double(m.metallic))
                      .set("roughnessFactor", double(m.roughness));
  JsonValue j = JsonValue::object().set("name", m.name).set("pbrMetallicRoughness", pbr);
  // glTF keeps emissiveFactor within [0, 1]: the rest goes to the strength.
  const float peak = std::max({m.emissive.x, m.emissive.y, m.emissive.z});
  if (peak > 0.0f && m.emissive_strength > 0.0f) {
    const glm::vec3 factor = peak > 1.0f ? m.emissive / peak : m.emissive;
    const float strength = m.emissive_strength * std::max(peak, 1.0f);
    j.set("emissiveFactor", numbers(&factor.x, 3));
    if (strength != 1.0f) {
      j.set("extensions",
            JsonValue::object().set("KHR_materials_emissive_strength",
                                    JsonValue::object().set("emissiveStrength", double(strength))));
    }
  }
  if (m.double_sided) j.set("doubleSided", true);
  if (m.alpha_mode == AlphaMode::kMask) {
    j.set("alphaMode", "MASK").set("alphaCutoff", double(m.alpha_cutoff));
  } else if (m.alpha_mode == AlphaMode::kBlend) {
    j.set("alphaMode", "BLEND");
  }
  return j;
}

// A node's rotation turning -z (where glTF lights and cameras look) into
// `dir`, as [x, y, z, w].
JsonValue rotation_towards(glm::vec3 dir) {
  const glm::vec3 from(0.0f, 0.0f, -1.0f), to = glm::normalize(dir);
  const float c = glm::dot(from, to);
  // Half the angle: (1 + cos, sin axis) normalised; opposite ways turn
  // about x.
  const glm::vec3 axis = glm::cross(from, to);
  glm::vec4 q = c < -0.999999f ? glm::vec4(1.0f, 0.0f, 0.0f, 0.0f)
                               : glm::normalize(glm::vec4(axis, 1.0f + c));
  return numbers(&q.x, 4);
}

JsonValue light_json(const Light& l) {
  JsonValue j = JsonValue::object()
                    .set("name", l.name)
                    .set("color", numbers(&l.color.x, 3))
                    .set("intensity", double(l.intensity));
  switch (l.type) {
    case LightType::kPoint:
      j.set("type", "point");
      break;
    case LightType::kSpot:
      j.set("type", "spot")
          .set("spot", JsonValue::object()
                           .set("innerConeAngle", double(l.inner_cone_angle))
                           .set("outerConeAngle", double(l.outer_cone_angle)));
      break;
    case LightType::kDirectional:
      j.set("type", "directional");
      break;
  }
  return j;
}

std::string export_gltf(const Scene& scene) {
  GltfDocument doc;
  JsonValue meshes = JsonValue::array(), nodes = JsonValue::array(), roots = JsonValue::array();
  std::map<uint32_t, int> gltf_mesh;  // Tandem mesh -> glTF mesh (those with triangles)
  for (uint32_t m = 0; m < scene.mesh_count(); ++m) {
    const Mesh& mesh = scene.mesh(m);
    if (mesh.triangles.empty()) continue;
    // One primitive per material, of the vertices its triangles use (a
    // loader that merges primitives would otherwise copy every vertex into
    // each).
    std::map<uint32_t, std::vector<uint32_t>> by_material;  // material -> its triangles
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t)
      by_material[mesh.triangle_materials[t]].push_back(t);
    const bool normals = mesh.normals.size() == mesh.positions.size();
    const bool uvs = mesh.uv0.size() == mesh.positions.size();
    JsonValue primitives = JsonValue::array();
    for (const auto& [material, triangles] : by_material) {
      std::map<uint32_t, uint32_t> local;  // mesh vertex -> primitive vertex
      std::vector<uint32_t> indices, used;
      for (uint32_t t : triangles) {
        for (int k = 0; k < 3; ++k) {
          const uint32_t v = mesh.triangles[t][k];
          const auto [at, added] = local.emplace(v, uint32_t(used.size()));
          if (added) used.push_back(v);
          indices.push_back(at->second);
        }
      }
      std::vector<glm::vec3> p, n;
      std::vector<glm::vec2> uv;
      glm::vec3 lo(INFINITY), hi(-INFINITY);
      for (uint32_t v : used) {
        p.push_back(mesh.positions[v]);
        lo = glm::min(lo, p.back());
        hi = glm::max(hi, p.back());
        if (normals) n.push_back(mesh.normals[v]);
        if (uvs) uv.push_back(mesh.uv0[v]);
      }
      const JsonValue jlo = numbers(&lo.x, 3), jhi = numbers(&hi.x, 3);
      JsonValue attributes = JsonValue::object().set(
          "POSITION", doc.accessor(p.data(), p.size() * 12, p.size(), "VEC3", 5126, &jlo, &jhi));
      if (normals)
        attributes.set("NORMAL", doc.accessor(n.data(), n.size() * 12, n.size(), "VEC3", 5126));
      if (uvs)
        attributes.set("TEXCOORD_0",
                       doc.accessor(uv.data(), uv.size() * 8, uv.size(), "VEC2", 5126));
      JsonValue prim = JsonValue::object()
                           .set("attributes", std::move(attributes))
                           .set("indices", doc.accessor(indices.data(), indices.size() * 4,
                                                        indices.size(), "SCALAR", 5125));
      if (material < scene.materials().size()) prim.set("material", material);
      primitives.push(std::move(prim));
    }
    gltf_mesh[m] = int(gltf_mesh.size());
    meshes.push(
        JsonValue::object().set("name", mesh.name).set("primitives", std::move(primitives)));
  }
  int node_count = 0;
  for (const Instance& inst : scene.instances()) {
    if (inst.hidden || !gltf_mesh.count(inst.mesh)) continue;
    nodes.push(JsonValue::object()
                   .set("name", inst.name)
                   .set("mesh", gltf_mesh[inst.mesh])
                   .set("matrix", numbers(&inst.transform[0][0], 16)));
    roots.push(node_count++);
  }
  JsonValue lights = JsonValue::array();
  for (size_t i = 0; i < scene.lights().size(); ++i) {
    const Light& l = scene.lights()[i];
    lights.push(light_json(l));
    JsonValue node = JsonValue::object()
                         .set("name", l.name)
                         .set("extensions", JsonValue::object().set(
                                                "KHR_lights_punctual",
                                                JsonValue::object().set("light", uint64_t(i))));
    if (l.type != LightType::kDirectional) node.set("translation", numbers(&l.position.x, 3));
    if (l.type != LightType::kPoint) node.set("rotation", rotation_towards(l.direction));
    nodes.push(std::move(node));
    roots.push(node_count++);
  }
  JsonValue cameras = JsonValue::array();
  if (scene.has_camera()) {
    const Camera& c = scene.camera();
    JsonValue camera = JsonValue::object();
    if (c.type == CameraType::kPerspective) {
      JsonValue p = JsonValue::object().set("yfov", double(c.yfov)).set("znear", 1e-3);
      if (c.aspect_ratio > 0.0f) p.set("aspectRatio", double(c.aspect_ratio));
      camera.set("type", "perspective").set("perspective", p);
    } else {
      camera.set("type", "orthographic")
          .set("orthographic", JsonValue::object()
                                   .set("xmag", double(c.ortho_half_height))
                                   .set("ymag", double(c.ortho_half_height))
                                   .set("znear", 0.0)
                                   .set("zfar", 1e6));
    }
    cameras.push(std::move(camera));
    const glm::vec3 right = glm::normalize(glm::cross(c.forward, c.up));
    const glm::mat4 frame(glm::vec4(right, 0.0f), glm::vec4(c.up, 0.0f),
                          glm::vec4(-c.forward, 0.0f), glm::vec4(c.position, 1.0f));
    nodes.push(JsonValue::object().set("camera", 0).set("matrix", numbers(&frame[0][0], 16)));
    roots.push(node_count++);
  }
  JsonValue materials = JsonValue::array();
  for (const Material& m : scene.materials())
    materials.push(material_json(m));

  JsonValue j = JsonValue::object().set(
      "asset", JsonValue::object().set("version", "2.0").set("generator", "tandem export"));
  JsonValue used = JsonValue::array().push("KHR_materials_emissive_strength");
  if (!scene.lights().empty()) used.push("KHR_lights_punctual");
  j.set("extensionsUsed", std::move(used));
  j.set("scene", 0).set("scenes", JsonValue::array().push(JsonValue::object().set("nodes", roots)));
  j.set("nodes", std::move(nodes)).set("meshes", std::move(meshes));
  j.set("materials", std::move(materials));
  if (scene.has_camera()) j.set("cameras", std::move(cameras));
  if (!scene.lights().empty()) {
    j.set("extensions", JsonValue::object().set("KHR_lights_punctual",
                                                JsonValue::object().set("lights", lights)));
  }
  return doc.finish(std::move(j)).dump();
}

}  // namespace

int run_export(const std::vector<std::string>& argv) {
  const ParsedArgs args("export", export_options(), argv);
  if (args.has("help")) {
    std::printf(
        "usage: tandem export SCENE --output FILE.gltf [options]\n\n"
        "Writes SCENE (a .gltf/.glb file or builtin:NAME) as one self-contained glTF file: its\n"
        "meshes, materials (factors), instances, punctual lights and camera. Textures, skins,\n"
        "morph targets, animations and the environment are not written.\n\n%s",
        format_options_help(export_options()).c_str());
    return 0;
  }
  if (args.positionals().size() != 1) {
    throw UsageError("export: expected exactly one SCENE argument");
  }
  if (!args.has("output")) throw UsageError("export: --output FILE.gltf is required");
  const std::string output = args.get_string("output", "");
  if (output.size() < 5 || output.compare(output.size() - 5, 5, ".gltf") != 0) {
    throw UsageError("export: --output must name a .gltf file, not '" + output + "'");
  }
  SceneRequest request = parse_scene_request(args, args.positionals()[0]);
  request.default_environment = false;
  const Scene scene = load_requested_scene(request, "tandem");
  const bool textured = !scene.textures().empty();
  const bool environment =
      !scene.environment().texels.empty() || glm::length(scene.environment().color) > 0.0f;
  if (textured) log_warning("export: the scene's textures are not written (factors only)");
  if (environment) log_warning("export: the scene's environment is not written (glTF has none)");
  const std::string text = export_gltf(scene);
  write_file_atomically(output, std::vector<uint8_t>(text.begin(), text.end()));
  std::printf("wrote %s: %zu meshes, %zu instances, %zu lights%s\n", output.c_str(),
              scene.mesh_count(), scene.instances().size(), scene.lights().size(),
              scene.has_camera() ? ", a camera" : "");
  return 0;
}

}  // namespace tandem
