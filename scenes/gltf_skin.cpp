// glTF skins and morph targets -> MeshDeformations (mesh_deformer.h).
//
// The vertex order is decode_meshes()'s: the triangle primitives of a mesh
// concatenated in file order (points and lines are not part of the Mesh).
// Joint indices and weights are data, so they are checked here, while
// decoding, for every skinned mesh of the file (a broken skin makes the file
// invalid whether or not the chosen scene shows it).
//
// Weight fix-ups (glTF says weights of a vertex sum to one; exporters do not
// always manage):
//  - a sum that is not one is normalised, with one warning per file when it
//    is off by more than 1e-3 (less is float rounding of the exporter);
//  - all-zero weights (or a primitive without JOINTS_0/WEIGHTS_0 in a
//    skinned mesh) make the vertex follow the mesh node's own transform, as
//    if it were not skinned, with one warning per file.
#include <cmath>
#include <map>

#include <glm/gtc/type_ptr.hpp>

#include "scenes/gltf_internal.h"

namespace tandem::gltf {

namespace {

int attribute(const tinygltf::Primitive& p, const std::string& name) {
  const auto it = p.attributes.find(name);
  return it == p.attributes.end() ? -1 : it->second;
}

bool is_triangles(const tinygltf::Primitive& p) {
  return p.mode >= TINYGLTF_MODE_TRIANGLES;
}

// JOINTS_n/WEIGHTS_n sets of the mesh's triangle primitives: the largest n + 1.
uint32_t influence_sets(const Context& ctx, const tinygltf::Mesh& mesh, const std::string& who) {
  uint32_t sets = 0;
  for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
    const tinygltf::Primitive& p = mesh.primitives[pi];
    for (uint32_t s = 0;; ++s) {
      const bool j = attribute(p, "JOINTS_" + std::to_string(s)) >= 0;
      const bool w = attribute(p, "WEIGHTS_" + std::to_string(s)) >= 0;
      if (j != w) {
        ctx.fail(who + " primitive " + std::to_string(pi) + " has " + (j ? "JOINTS_" : "WEIGHTS_") +
                 std::to_string(s) + " without " + (j ? "WEIGHTS_" : "JOINTS_") +
                 std::to_string(s));
      }
      if (!j) break;
      if (is_triangles(p)) sets = std::max(sets, s + 1);
    }
  }
  return sets;
}

// Decodes, checks and fixes up the influences of mesh `mi` under a skin of
// `joint_count` joints. With `d` null only checks.
void decode_influences(Context& ctx, AccessorCache& cache, int mi, int skin, size_t joint_count,
                       MeshDeformation* d) {
  const tinygltf::Mesh& mesh = ctx.model.meshes[size_t(mi)];
  const std::string mwho = "mesh " + std::to_string(mi);
  const uint32_t sets = influence_sets(ctx, mesh, mwho);
  const uint32_t influences = 4 * std::max(sets, 1u);
  const uint16_t fallback = uint16_t(joint_count);  // the node's own transform
  size_t first = 0;
  for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
    const tinygltf::Primitive& p = mesh.primitives[pi];
    if (!is_triangles(p)) continue;
    const std::string who = mwho + " primitive " + std::to_string(pi);
    const size_t count = ctx.model.accessors[size_t(attribute(p, "POSITION"))].count;
    std::vector<const std::vector<float>*> joints, weights;
    for (uint32_t s = 0; attribute(p, "JOINTS_" + std::to_string(s)) >= 0; ++s) {
      const std::string js = "JOINTS_" + std::to_string(s), ws = "WEIGHTS_" + std::to_string(s);
      joints.push_back(&cache.floats(attribute(p, js), who + " " + js));
      weights.push_back(&cache.floats(attribute(p, ws), who + " " + ws));
    }
    if (joints.empty()) {
      ctx.warn_once("skin-no-joints", who +
                                          " (and any others like it) of a skinned mesh has no "
                                          "JOINTS_0/WEIGHTS_0; its vertices follow the node as "
                                          "if unskinned");
    }
    for (size_t v = 0; v < count; ++v) {
      uint16_t* dj = d ? &d->joints[(first + v) * influences] : nullptr;
      float* dw = d ? &d->weights[(first + v) * influences] : nullptr;
      double sum = 0.0;
      for (size_t s = 0; s < joints.size(); ++s) {
        for (int c = 0; c < 4; ++c) {
          const float j = (*joints[s])[4 * v + size_t(c)];
          const float w = (*weights[s])[4 * v + size_t(c)];
          const std::string where = who + " vertex " + std::to_string(v);
          if (j >= float(joint_count)) {
            ctx.fail(where + " JOINTS_" + std::to_string(s) + " names joint " +
                     std::to_string(uint64_t(j)) + ", but skin " + std::to_string(skin) + " has " +
                     std::to_string(joint_count) + " joints");
          }
          if (w < 0.0f) {
            ctx.fail(where + " WEIGHTS_" + std::to_string(s) + " has a negative weight (" +
                     std::to_string(w) + ")");
          }
          sum += w;
          if (dj) {
            dj[4 * s + size_t(c)] = uint16_t(j);
            dw[4 * s + size_t(c)] = w;
          }
        }
      }
      if (!(sum > 0.0)) {
        if (!joints.empty()) {
          ctx.warn_once("skin-zero-weights",
                        who + " vertex " + std::to_string(v) +
                            " (and any others like it) has all joint weights zero; such vertices "
                            "follow the node as if unskinned");
        }
        if (dj) {
          dj[0] = fallback;
          dw[0] = 1.0f;
        }
        continue;
      }
      if (std::fabs(sum - 1.0) > 1e-3) {
        ctx.warn_once("skin-weight-sum", who + " vertex " + std::to_string(v) +
                                             " (and any others like it) has joint weights "
                                             "summing to " +
                                             std::to_string(sum) + ", not 1; they are normalised");
      }
      if (dw) {
        for (uint32_t i = 0; i < influences; ++i)
          dw[i] = float(dw[i] / sum);
      }
    }
    first += count;
  }
}

// Morph-target deltas of mesh `mi` into `d` (vertex order as decode_meshes).
void decode_targets(Context& ctx, AccessorCache& cache, int mi, MeshDeformation& d) {
  const tinygltf::Mesh& mesh = ctx.model.meshes[size_t(mi)];
  const size_t vertices = d.vertex_count();
  d.targets = uint32_t(mesh.primitives.front().targets.size());
  struct Attr {
    const char* name;
    std::vector<glm::vec3>* deltas;
  };
  const Attr attrs[] = {{"POSITION", &d.position_deltas},
                        {"NORMAL", &d.normal_deltas},
                        {"TANGENT", &d.tangent_deltas}};
  for (const Attr& a : attrs) {
    bool any = false;
    for (const tinygltf::Primitive& p : mesh.primitives) {
      for (const auto& target : p.targets)
        any = any || (is_triangles(p) && target.count(a.name));
    }
    if (!any) continue;
    const uint64_t bytes = uint64_t(d.targets) * vertices * sizeof(glm::vec3);
    ctx.charge(Budget::kGeometryBytes, bytes,
               "mesh " + std::to_string(mi) + " morph targets " + a.name);
    a.deltas->assign(size_t(d.targets) * vertices, glm::vec3(0.0f));
    size_t first = 0;
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& p = mesh.primitives[pi];
      if (!is_triangles(p)) continue;
      const size_t count = ctx.model.accessors[size_t(attribute(p, "POSITION"))].count;
      for (size_t k = 0; k < p.targets.size(); ++k) {
        const auto it = p.targets[k].find(a.name);
        if (it == p.targets[k].end()) continue;
        const std::vector<float>& f = cache.floats(
            it->second, "mesh " + std::to_string(mi) + " primitive " + std::to_string(pi) +
                            " morph target " + std::to_string(k) + " " + a.name);
        for (size_t v = 0; v < count; ++v)
          (*a.deltas)[k * vertices + first + v] = {f[3 * v], f[3 * v + 1], f[3 * v + 2]};
      }
      first += count;
    }
  }
}

}  // namespace

void load_deformers(Context& ctx, AccessorCache& cache, const std::vector<DeformedNode>& nodes,
                    const std::vector<Mesh>& scene_meshes, GltfAnimations& out) {
  const tinygltf::Model& m = ctx.model;
  // Every skinned mesh of the file is checked, shown or not.
  for (const tinygltf::Node& n : m.nodes) {
    if (n.skin >= 0 && n.mesh >= 0)
      decode_influences(ctx, cache, n.mesh, n.skin, m.skins[size_t(n.skin)].joints.size(), nullptr);
  }
  std::map<int, int> skin_slot;  // glTF skin -> index in out.skins
  for (const DeformedNode& dn : nodes) {
    const tinygltf::Node& node = m.nodes[size_t(dn.node)];
    const Mesh& mesh = scene_meshes[dn.scene_mesh];
    GltfDeformedMesh dm;
    dm.node = uint32_t(dn.node);
    auto deformation = std::make_shared<MeshDeformation>();
    MeshDeformation& d = *deformation;
    d.mesh = dn.scene_mesh;
    d.base_positions = mesh.positions;
    d.base_normals = mesh.normals;
    d.base_tangents = mesh.tangents;
    const size_t vertices = mesh.positions.size();
    if (node.skin >= 0) {
      const tinygltf::Skin& gs = m.skins[size_t(node.skin)];
      auto [it, inserted] = skin_slot.emplace(node.skin, int(out.skins.size()));
      if (inserted) {
        GltfSkin skin;
        for (int j : gs.joints) {
          skin.joints.push_back(uint32_t(j));
          if (!out.nodes[size_t(j)].visited) {
            ctx.warn_once("skin-joint-outside",
                          "skin " + std::to_string(node.skin) + " joint node " + std::to_string(j) +
                              " (and any others like it) is not part of the loaded scene; it "
                              "stays at the origin");
          }
        }
        skin.inverse_bind.assign(gs.joints.size(), glm::mat4(1.0f));
        if (gs.inverseBindMatrices >= 0) {
          const std::vector<float>& f = cache.floats(
              gs.inverseBindMatrices, "skin " + std::to_string(node.skin) + " inverseBindMatrices");
          for (size_t j = 0; j < gs.joints.size(); ++j)
            skin.inverse_bind[j] = glm::make_mat4(&f[16 * j]);
        }
        out.skins.push_back(std::move(skin));
      }
      dm.skin = it->second;
      const uint32_t sets =
          influence_sets(ctx, m.meshes[size_t(node.mesh)], "mesh " + std::to_string(node.mesh));
      d.influences = 4 * std::max(sets, 1u);
      d.palette_size = uint32_t(gs.joints.size()) + 1;
      ctx.charge(Budget::kGeometryBytes,
                 uint64_t(vertices) * d.influences * (sizeof(uint16_t) + sizeof(float)),
                 "skin influences of node " + std::to_string(dn.node));
      d.joints.assign(vertices * d.influences, 0);
      d.weights.assign(vertices * d.influences, 0.0f);
      decode_influences(ctx, cache, node.mesh, node.skin, gs.joints.size(), &d);
    }
    if (!m.meshes[size_t(node.mesh)].primitives.front().targets.empty())
      decode_targets(ctx, cache, node.mesh, d);
    dm.deformation = std::move(deformation);
    out.deformed.push_back(std::move(dm));
  }
}

}  // namespace tandem::gltf
