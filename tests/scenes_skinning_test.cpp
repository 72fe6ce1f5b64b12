// Skinned and morphing glTF meshes: the loader's deformed vertices against
// an independent reference computed here in double precision straight from
// the tinygltf model (own accessor reader, node hierarchy, animation
// sampling and skinning; nothing of the loader's), plus the validation of
// bad skins and morph targets, built as small glTF files in memory.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "core/kernel/host_isa.h"
#include "core/util/errors.h"
#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_animation.h"
#include "scenes/gltf_loader.h"
#include "scenes/mesh_deformer.h"
#include "scenes/procedural_rigs.h"
#include "scenes/scene_animator.h"
#include "tests/scenes_gltf_test_file.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

fs::path skinned(const std::string& name) {
  return fs::path(TANDEM_SHARED_DIR) / "scenes/skinned" / name / "glTF-Embedded" / (name + ".gltf");
}

// --- the reference ------------------------------------------------------------

std::vector<double> read_accessor(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors[size_t(index)];
  const tinygltf::BufferView& v = m.bufferViews[size_t(a.bufferView)];
  const unsigned char* base = m.buffers[size_t(v.buffer)].data.data() + v.byteOffset + a.byteOffset;
  const int n = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  const int cs = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  const size_t stride = v.byteStride ? v.byteStride : size_t(n * cs);
  std::vector<double> out;
  for (size_t i = 0; i < a.count; ++i) {
    for (int c = 0; c < n; ++c) {
      const unsigned char* p = base + i * stride + size_t(c * cs);
      double x = 0.0;
      switch (a.componentType) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
          float f;
          std::memcpy(&f, p, 4);
          x = f;
          break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
          x = a.normalized ? p[0] / 255.0 : p[0];
          break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
          uint16_t u;
          std::memcpy(&u, p, 2);
          x = a.normalized ? u / 65535.0 : u;
          break;
        }
        default:
          ADD_FAILURE() << "component type " << a.componentType << " not in the test files";
      }
      out.push_back(x);
    }
  }
  return out;
}

struct RefTrs {
  glm::dvec3 t{0.0}, s{1.0};
  glm::dquat r{1.0, 0.0, 0.0, 0.0};
  bool matrix = false;
  glm::dmat4 m{1.0};
  std::vector<double> weights;
};

glm::dquat ref_slerp(glm::dquat a, glm::dquat b, double s) {
  double d = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
  if (d < 0.0) b = -b, d = -d;
  if (d > 0.9999995) return glm::normalize(a * (1.0 - s) + b * s);
  const double th = std::acos(d);
  return glm::normalize(a * (std::sin((1.0 - s) * th) / std::sin(th)) +
                        b * (std::sin(s * th) / std::sin(th)));
}

// Node poses at time t with every animation (looped over its duration).
struct RefPose {
  std::vector<RefTrs> local;
  std::vector<glm::dmat4> world;
};

RefPose ref_pose(const tinygltf::Model& m, double t) {
  RefPose pose;
  pose.local.resize(m.nodes.size());
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    const tinygltf::Node& n = m.nodes[i];
    RefTrs& r = pose.local[i];
    if (n.matrix.size() == 16) r.matrix = true, r.m = glm::make_mat4(n.matrix.data());
    if (n.translation.size() == 3) r.t = glm::make_vec3(n.translation.data());
    if (n.rotation.size() == 4)
      r.r = glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
    if (n.scale.size() == 3) r.s = glm::make_vec3(n.scale.data());
    if (n.mesh >= 0) {
      r.weights = !n.weights.empty() ? n.weights : m.meshes[size_t(n.mesh)].weights;
      r.weights.resize(m.meshes[size_t(n.mesh)].primitives[0].targets.size(), 0.0);
    }
  }
  for (const tinygltf::Animation& a : m.animations) {
    double duration = 0.0;
    for (const tinygltf::AnimationSampler& s : a.samplers)
      duration = std::max(duration, read_accessor(m, s.input).back());
    const double lt = std::fmod(t, duration);
    for (const tinygltf::AnimationChannel& c : a.channels) {
      const tinygltf::AnimationSampler& s = a.samplers[size_t(c.sampler)];
      EXPECT_TRUE(s.interpolation == "LINEAR" || s.interpolation == "STEP");
      const std::vector<double> times = read_accessor(m, s.input),
                                values = read_accessor(m, s.output);
      const size_t n = values.size() / times.size();
      size_t k = 0;
      while (k + 1 < times.size() && times[k + 1] <= lt)
        ++k;
      const size_t k1 = std::min(k + 1, times.size() - 1);
      double f = k1 == k || lt <= times[k] ? 0.0 : (lt - times[k]) / (times[k1] - times[k]);
      if (s.interpolation == "STEP") f = 0.0;
      const double *a0 = &values[k * n], *a1 = &values[k1 * n];
      RefTrs& r = pose.local[size_t(c.target_node)];
      if (c.target_path == "rotation") {
        r.r = ref_slerp({a0[3], a0[0], a0[1], a0[2]}, {a1[3], a1[0], a1[1], a1[2]}, f);
      } else {
        std::vector<double> v(n);
        for (size_t i = 0; i < n; ++i)
          v[i] = a0[i] + (a1[i] - a0[i]) * f;
        if (c.target_path == "translation") r.t = {v[0], v[1], v[2]};
        if (c.target_path == "scale") r.s = {v[0], v[1], v[2]};
        if (c.target_path == "weights") r.weights = v;
      }
    }
  }
  std::vector<int> parent(m.nodes.size(), -1);
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    for (int c : m.nodes[i].children)
      parent[size_t(c)] = int(i);
  }
  pose.world.assign(m.nodes.size(), glm::dmat4(1.0));
  std::function<glm::dmat4(int)> world = [&](int i) -> glm::dmat4 {
    const RefTrs& r = pose.local[size_t(i)];
    const glm::dmat4 local = r.matrix ? r.m
                                      : glm::translate(glm::dmat4(1.0), r.t) *
                                            glm::mat4_cast(glm::normalize(r.r)) *
                                            glm::scale(glm::dmat4(1.0), r.s);
    return parent[size_t(i)] >= 0 ? world(parent[size_t(i)]) * local : local;
  };
  for (size_t i = 0; i < m.nodes.size(); ++i)
    pose.world[i] = world(int(i));
  return pose;
}

struct RefVertices {
  std::vector<glm::dvec3> positions, normals;  // world space
};

// World-space vertices of node `node`'s mesh (triangle primitives in order).
RefVertices ref_vertices(const tinygltf::Model& m, int node, double t) {
  const RefPose pose = ref_pose(m, t);
  const tinygltf::Node& n = m.nodes[size_t(node)];
  RefVertices out;
  for (const tinygltf::Primitive& p : m.meshes[size_t(n.mesh)].primitives) {
    const std::vector<double> pos = read_accessor(m, p.attributes.at("POSITION"));
    std::vector<double> nrm;
    if (p.attributes.count("NORMAL")) nrm = read_accessor(m, p.attributes.at("NORMAL"));
    std::vector<glm::dvec3> vp, vn;
    for (size_t v = 0; v < pos.size() / 3; ++v) {
      vp.push_back({pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]});
      vn.push_back(nrm.empty() ? glm::dvec3(0.0)
                               : glm::dvec3(nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]));
    }
    const std::vector<double>& w = pose.local[size_t(node)].weights;
    for (size_t k = 0; k < p.targets.size(); ++k) {
      const auto it = p.targets[k].find("POSITION");
      if (it == p.targets[k].end()) continue;
      const std::vector<double> d = read_accessor(m, it->second);
      for (size_t v = 0; v < vp.size(); ++v)
        vp[v] += w[k] * glm::dvec3(d[3 * v], d[3 * v + 1], d[3 * v + 2]);
    }
    std::vector<glm::dmat4> skin_matrix(vp.size(), pose.world[size_t(node)]);
    if (n.skin >= 0) {
      const tinygltf::Skin& skin = m.skins[size_t(n.skin)];
      const std::vector<double> ibm = read_accessor(m, skin.inverseBindMatrices);
      const std::vector<double> j = read_accessor(m, p.attributes.at("JOINTS_0"));
      const std::vector<double> wt = read_accessor(m, p.attributes.at("WEIGHTS_0"));
      for (size_t v = 0; v < vp.size(); ++v) {
        glm::dmat4 sum(0.0);
        double total = 0.0;
        for (int c = 0; c < 4; ++c) {
          const size_t joint = size_t(j[4 * v + size_t(c)]);
          const double weight = wt[4 * v + size_t(c)];
          sum +=
              weight * (pose.world[size_t(skin.joints[joint])] * glm::make_mat4(&ibm[16 * joint]));
          total += weight;
        }
        skin_matrix[v] = sum / total;
      }
    }
    for (size_t v = 0; v < vp.size(); ++v) {
      out.positions.push_back(glm::dvec3(skin_matrix[v] * glm::dvec4(vp[v], 1.0)));
      const glm::dmat3 it = glm::transpose(glm::inverse(glm::dmat3(skin_matrix[v])));
      out.normals.push_back(glm::normalize(it * vn[v]));
    }
  }
  return out;
}

int node_named(const tinygltf::Model& m, const std::string& name) {
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    if (m.nodes[i].name == name) return int(i);
  }
  return -1;
}

tinygltf::Model parse(const fs::path& file) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  EXPECT_TRUE(loader.LoadASCIIFromFile(&model, &err, &warn, file.string())) << err;
  return model;
}

const Instance* instance_named(const Scene& s, const std::string& name) {
  for (const Instance& i : s.instances()) {
    if (i.name == name) return &i;
  }
  return nullptr;
}

// The loaded scene posed at each time against the reference.
void expect_matches_reference(const std::string& name, const std::string& node_name,
                              const std::vector<double>& times, double tolerance) {
  const fs::path file = skinned(name);
  const tinygltf::Model model = parse(file);
  const int node = node_name.empty() ? 0 : node_named(model, node_name);
  ASSERT_GE(node, 0);
  GltfAnimations anims;
  GltfOptions options;
  options.animations = &anims;
  Scene scene = load_gltf(file, options);
  std::unique_ptr<SceneAnimator> animator = make_scene_animator(scene, std::move(anims));
  ASSERT_TRUE(animator->animated());
  const Instance* inst = instance_named(scene, node_name.empty() ? "node 0" : node_name);
  ASSERT_NE(inst, nullptr);
  for (double t : times) {
    animator->pose(t, scene);
    const Mesh& mesh = scene.meshes()[inst->mesh];
    const RefVertices ref = ref_vertices(model, node, t);
    ASSERT_EQ(mesh.positions.size(), ref.positions.size());
    double worst = 0.0, worst_normal = 0.0;
    for (size_t v = 0; v < ref.positions.size(); ++v) {
      const glm::dvec3 p(inst->transform * glm::vec4(mesh.positions[v], 1.0f));
      worst = std::max(worst, glm::length(p - ref.positions[v]));
      if (!mesh.normals.empty()) {
        const glm::dvec3 n =
            glm::normalize(glm::dvec3(glm::mat3(inst->transform) * mesh.normals[v]));
        EXPECT_NEAR(glm::length(glm::dvec3(mesh.normals[v])), 1.0, 1e-5) << name << " t " << t;
        worst_normal = std::max(worst_normal, glm::length(n - ref.normals[v]));
      }
    }
    EXPECT_LT(worst, tolerance) << name << " at t = " << t;
    EXPECT_LT(worst_normal, 1e-3) << name << " at t = " << t;
  }
}

TEST(GltfSkinning, RiggedSimpleMatchesReference) {
  // Its bone bends the cylinder far out of the bind pose: 2.08 s loop.
  expect_matches_reference("RiggedSimple", "Cylinder", {0.0, 0.4, 0.93, 1.5, 2.0, 2.9}, 2e-4);
}

TEST(GltfSkinning, RiggedFigureMatchesReference) {
  expect_matches_reference("RiggedFigure", "Proxy", {0.0, 0.21, 0.5, 0.77, 1.2}, 2e-4);
}

TEST(GltfMorph, SimpleMorphMatchesReference) {
  expect_matches_reference("SimpleMorph", "", {0.0, 0.5, 1.3, 2.0, 3.1, 3.99}, 1e-5);
}

TEST(GltfSkinning, PosingMovesTheSkinnedMeshAndMarksItDirty) {
  GltfAnimations anims;
  GltfOptions options;
  options.animations = &anims;
  Scene scene = load_gltf(skinned("RiggedSimple"), options);
  ASSERT_EQ(anims.deformed.size(), 1u);
  EXPECT_EQ(anims.deformed[0].skin, 0);
  const uint32_t mesh = anims.deformed[0].deformation->mesh;
  auto animator = make_scene_animator(scene, std::move(anims));
  scene.clear_dirty();
  animator->pose(0.0, scene);
  const std::vector<glm::vec3> at0 = scene.meshes()[mesh].positions;
  EXPECT_TRUE(scene.mesh_dirty()[mesh] & kDirtyVertices);
  scene.clear_dirty();
  animator->pose(1.0, scene);
  EXPECT_TRUE(scene.mesh_dirty()[mesh] & kDirtyVertices);
  EXPECT_NE(scene.meshes()[mesh].positions, at0);
  animator->pose(0.0, scene);  // a pure function of t
  EXPECT_EQ(scene.meshes()[mesh].positions, at0);
}

TEST(GltfSkinning, StaticLoadShowsTheRestPoseSkinned) {
  // Without animations the skin still places the vertices (the node's own
  // transform is ignored): the same as the animated load before posing.
  const Scene s = load_gltf(skinned("RiggedFigure"));
  const tinygltf::Model model = parse(skinned("RiggedFigure"));
  // Rest pose: every node at its own TRS; t beyond no animation = use a
  // copy without animations.
  tinygltf::Model rest = model;
  rest.animations.clear();
  const RefVertices ref = ref_vertices(rest, node_named(model, "Proxy"), 0.0);
  const Instance* inst = instance_named(s, "Proxy");
  ASSERT_NE(inst, nullptr);
  EXPECT_EQ(inst->transform, glm::mat4(1.0f));
  const Mesh& mesh = s.meshes()[inst->mesh];
  ASSERT_EQ(mesh.positions.size(), ref.positions.size());
  for (size_t v = 0; v < ref.positions.size(); ++v)
    EXPECT_LT(glm::length(glm::dvec3(mesh.positions[v]) - ref.positions[v]), 2e-4) << v;
}

// --- small files built in memory ----------------------------------------------

Scene load_text(const std::string& json, GltfAnimations* anims = nullptr) {
  GltfOptions options;
  options.animations = anims;
  return load_gltf_from_memory(reinterpret_cast<const unsigned char*>(json.data()), json.size(),
                               "test.gltf", ".", options);
}

std::string load_error(const std::string& json) {
  try {
    load_text(json);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded)";
}

using test::kTriangle;

// A triangle skinned to two joints (node 1 at the origin, node 2 at x = 2).
struct SkinCase {
  std::vector<uint8_t> joints = {0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0};
  std::vector<float> weights = {1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0};
  size_t ibm_count = 2;
  bool u16_weights = false;  // WEIGHTS_0 as normalized UNSIGNED_SHORT, JOINTS_0 as UNSIGNED_SHORT
  // A second set (JOINTS_1/WEIGHTS_1) when non-empty.
  std::vector<uint8_t> joints1;
  std::vector<float> weights1;
  std::string build() const {
    test::GltfTestFile f;
    const int pos = f.add(kTriangle, 5126, "VEC3", 3);
    int j = 0, w = 0;
    if (u16_weights) {
      j = f.add(std::vector<uint16_t>(joints.begin(), joints.end()), 5123, "VEC4", 3);
      std::vector<uint16_t> q;
      for (float x : weights)
        q.push_back(uint16_t(std::lround(x * 65535.0f)));
      w = f.add(q, 5123, "VEC4", 3, true);
    } else {
      j = f.add(joints, 5121, "VEC4", 3);
      w = f.add(weights, 5126, "VEC4", 3);
    }
    std::string second;
    if (!joints1.empty()) {
      second = R"(,"JOINTS_1":)" + std::to_string(f.add(joints1, 5121, "VEC4", 3)) +
               R"(,"WEIGHTS_1":)" + std::to_string(f.add(weights1, 5126, "VEC4", 3));
    }
    std::vector<float> ibm;
    for (size_t i = 0; i < ibm_count; ++i) {
      const glm::mat4 m = glm::translate(glm::mat4(1.0f), glm::vec3(i == 1 ? -2.0f : 0.0f, 0, 0));
      ibm.insert(ibm.end(), glm::value_ptr(m), glm::value_ptr(m) + 16);
    }
    const int b = f.add(ibm, 5126, "MAT4", ibm_count);
    return f.file(R"("meshes":[{"primitives":[{"attributes":{"POSITION":)" + std::to_string(pos) +
                  R"(,"JOINTS_0":)" + std::to_string(j) + R"(,"WEIGHTS_0":)" + std::to_string(w) +
                  second + R"(}}]}],"skins":[{"joints":[1,2],"inverseBindMatrices":)" +
                  std::to_string(b) +
                  R"(}],"nodes":[{"mesh":0,"skin":0,"translation":[0,0,7]},{},)" +
                  R"({"translation":[2,1,0]}],"scenes":[{"nodes":[0,1,2]}])");
  }
};

TEST(GltfSkinning, SmallSkinIsPosedByItsJoints) {
  SkinCase c;
  const Scene s = load_text(c.build());
  ASSERT_EQ(s.meshes().size(), 1u);
  const std::vector<glm::vec3>& p = s.meshes()[0].positions;
  // Vertex 0 on joint 0 (identity): stays; vertex 2 on joint 1 (moved up
  // by 1 from its bind place): up by 1; vertex 1 half and half. The mesh
  // node's translation (z = 7) is ignored.
  EXPECT_NEAR(glm::length(p[0] - glm::vec3(0, 0, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(p[1] - glm::vec3(1, 0.5f, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(p[2] - glm::vec3(0, 2, 0)), 0.0f, 1e-6f);
}

TEST(GltfSkinning, SixteenBitJointsAndNormalizedWeights) {
  SkinCase c;
  c.u16_weights = true;
  const Scene s = load_text(c.build());
  const std::vector<glm::vec3>& p = s.meshes()[0].positions;
  EXPECT_NEAR(glm::length(p[1] - glm::vec3(1, 0.5f, 0)), 0.0f, 1e-4f);
  EXPECT_NEAR(glm::length(p[2] - glm::vec3(0, 2, 0)), 0.0f, 1e-6f);
}

TEST(GltfSkinning, EverySetOfJointsAndWeightsCounts) {
  // Vertex 2's only influence is in the second set: joint 1 (up by 1).
  SkinCase c;
  c.weights = {1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 0, 0, 0, 0};
  c.joints1 = {0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0};
  c.weights1 = {0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0};
  const Scene s = load_text(c.build());
  EXPECT_NEAR(glm::length(s.meshes()[0].positions[2] - glm::vec3(0, 2, 0)), 0.0f, 1e-6f);
}

TEST(GltfSkinningBadInput, JointIndexOutOfRange) {
  SkinCase c;
  c.joints[4] = 2;  // the skin has joints 0 and 1
  const std::string e = load_error(c.build());
  EXPECT_EQ(e.rfind("test.gltf: ", 0), 0u) << e;
  EXPECT_NE(e.find("names joint 2, but skin 0 has 2 joints"), std::string::npos) << e;
}

TEST(GltfSkinningBadInput, NegativeWeight) {
  SkinCase c;
  c.weights[0] = -0.5f;
  const std::string e = load_error(c.build());
  EXPECT_NE(e.find("negative weight"), std::string::npos) << e;
}

TEST(GltfSkinningBadInput, InverseBindMatrixCountDiffersFromJoints) {
  SkinCase c;
  c.ibm_count = 3;
  const std::string e = load_error(c.build());
  EXPECT_NE(e.find("skin 0 has 3 inverse bind matrices for 2 joints"), std::string::npos) << e;
}

TEST(GltfSkinning, ZeroWeightsFollowTheNodeAndSumsAreNormalised) {
  SkinCase c;
  // Vertex 0: no weight at all: drawn as unskinned under the node (z = 7).
  // Vertex 2: weight 4 on joint 1: normalised to 1.
  c.weights = {0, 0, 0, 0, 0.5f, 0.5f, 0, 0, 4, 0, 0, 0};
  const Scene s = load_text(c.build());
  const std::vector<glm::vec3>& p = s.meshes()[0].positions;
  EXPECT_NEAR(glm::length(p[0] - glm::vec3(0, 0, 7)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(p[2] - glm::vec3(0, 2, 0)), 0.0f, 1e-6f);
  for (const glm::vec3& v : p)
    EXPECT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
}

// A triangle with one or two POSITION targets (+1 in y, +1 in z).
std::string morph_file(const std::string& mesh_extra, const std::string& node_extra,
                       bool second_primitive_without_targets = false, int targets = 1) {
  test::GltfTestFile f;
  const int pos = f.add(kTriangle, 5126, "VEC3", 3);
  const int dy = f.add(std::vector<float>{0, 1, 0, 0, 1, 0, 0, 1, 0}, 5126, "VEC3", 3);
  const int dz = f.add(std::vector<float>{0, 0, 1, 0, 0, 1, 0, 0, 1}, 5126, "VEC3", 3);
  std::string t = R"({"POSITION":)" + std::to_string(dy) + "}";
  if (targets > 1) t += R"(,{"POSITION":)" + std::to_string(dz) + "}";
  std::string prims =
      R"({"attributes":{"POSITION":)" + std::to_string(pos) + R"(},"targets":[)" + t + "]}";
  if (second_primitive_without_targets)
    prims += R"(,{"attributes":{"POSITION":)" + std::to_string(pos) + "}}";
  return f.file(R"("meshes":[{"primitives":[)" + prims + "]" + mesh_extra +
                R"(}],"nodes":[{"mesh":0)" + node_extra + R"(}],"scenes":[{"nodes":[0]}])");
}

TEST(GltfMorph, WeightZeroIsTheBaseAndOneAddsTheTarget) {
  const Scene base = load_text(morph_file(R"(,"weights":[0])", ""));
  EXPECT_EQ(base.meshes()[0].positions[1], glm::vec3(1, 0, 0));
  const Scene full = load_text(morph_file(R"(,"weights":[1])", ""));
  EXPECT_EQ(full.meshes()[0].positions[1], glm::vec3(1, 1, 0));
  // node.weights override mesh.weights.
  const Scene node = load_text(morph_file(R"(,"weights":[0])", R"(,"weights":[0.25])"));
  EXPECT_EQ(node.meshes()[0].positions[2], glm::vec3(0, 1.25f, 0));
  // No weights at all: zero.
  const Scene none = load_text(morph_file("", ""));
  EXPECT_EQ(none.meshes()[0].positions[2], glm::vec3(0, 1, 0));
}

TEST(GltfMorphBadInput, PrimitivesWithDifferentTargetCounts) {
  const std::string e = load_error(morph_file("", "", true));
  EXPECT_EQ(e.rfind("test.gltf: ", 0), 0u) << e;
  EXPECT_NE(e.find("mesh 0 primitive 1 has 0 morph targets but primitive 0 has 1"),
            std::string::npos)
      << e;
}

TEST(GltfMorphBadInput, WeightsLengthMismatchingTargets) {
  const std::string mesh = load_error(morph_file(R"(,"weights":[0.5,0.5])", ""));
  EXPECT_NE(mesh.find("mesh 0 has 2 weights but 1 morph targets"), std::string::npos) << mesh;
  const std::string node = load_error(morph_file("", R"(,"weights":[1,0,0])", false, 2));
  EXPECT_NE(node.find("node 0 has 3 weights but its mesh 0 has 2 morph targets"), std::string::npos)
      << node;
}

// --- the deformer itself ---------------------------------------------------------

TEST(MeshDeformer, NormalsUseTheInverseTransposeAndStayUnit) {
  // One vertex fully on a joint scaled 4x in x: a normal tilted in xy must
  // follow the inverse transpose (the surface's normal), not the matrix.
  MeshDeformation d;
  d.base_positions = {glm::vec3(1, 2, 3)};
  d.base_normals = {glm::normalize(glm::vec3(1, 1, 0))};
  d.base_tangents = {glm::vec4(glm::normalize(glm::vec3(1, -1, 0)), -1.0f)};
  d.palette_size = 1;
  d.influences = 4;
  d.joints = {0, 0, 0, 0};
  d.weights = {1, 0, 0, 0};
  const JointMatrix palette[1] = {joint_matrix(glm::scale(glm::mat4(1.0f), glm::vec3(4, 1, 1)))};
  Mesh out;
  out.positions.resize(1);
  out.normals.resize(1);
  out.tangents.resize(1);
  deform_mesh(d, palette, nullptr, out);
  EXPECT_EQ(out.positions[0], glm::vec3(4, 2, 3));
  EXPECT_NEAR(glm::length(out.normals[0]), 1.0f, 1e-6f);
  const glm::vec3 expected = glm::normalize(glm::vec3(0.25f, 1, 0));
  EXPECT_NEAR(glm::length(out.normals[0] - expected), 0.0f, 1e-6f);
  // The skinned tangent stays perpendicular to the skinned normal.
  EXPECT_NEAR(glm::dot(glm::vec3(out.tangents[0]), out.normals[0]), 0.0f, 1e-6f);
  EXPECT_EQ(out.tangents[0].w, -1.0f);
}

TEST(MeshDeformer, NormalsNormalisedFourAtATimeEqualTheOneAtATimePath) {
  // The unmorphed skinned path normalises its normals four at a time after
  // each block (on CPUs with AVX2: the whole vertex eight at a time, a vertex
  // a lane); the morphed path one at a time, right after skinning. A morph
  // target of zero deltas at weight 1 changes no bit of the input, so all
  // must give the same bits: over several blocks and a ragged tail, with
  // mirrored joints (a negative determinant) and exact zeros of both signs;
  // normals that collapse below. (The unmorphed path also blends its four
  // influences unrolled, the morphed one in the loop over the mesh's count:
  // the same bits too.)
  const size_t n = 2 * 4096 + 4099;
  MeshDeformation d;
  d.palette_size = 4;
  d.influences = 4;
  for (size_t v = 0; v < n; ++v) {
    const float a = 0.001f * float(v);
    d.base_positions.push_back({std::sin(a) * 3.0f, std::cos(0.7f * a), 0.01f * float(v % 97)});
    d.base_normals.push_back(glm::normalize(glm::vec3(std::cos(a), 1.0f, std::sin(3.0f * a))));
    if (v % 7 == 3) d.base_positions.back() = glm::vec3(-0.0f, 0.0f, -0.0f);
    const float w0 = float(v % 5) / 8.0f, w1 = float(v % 3) / 8.0f;
    // Mostly runs of eight vertices with the same joints (the AVX2 loop
    // blends those from broadcasts), with stretches and single vertices
    // where each has its own order (blended from gathered rows).
    const bool own = (v / 8) % 3 == 1 || v % 61 == 0;
    const uint16_t r = own ? uint16_t(v % 4) : 0;
    d.joints.insert(d.joints.end(), {uint16_t(r % 4), uint16_t((1 + r) % 4), uint16_t((2 + r) % 4),
                                     uint16_t((3 + r) % 4)});
    if (v % 11 == 5) {
      d.weights.insert(d.weights.end(), {0.0f, 0.0f, 0.0f, 1.0f});  // the mirror alone
    } else {
      d.weights.insert(d.weights.end(), {w0, w1, 1.0f - w0 - w1, 0.0f});
    }
  }
  const JointMatrix palette[4] = {
      joint_matrix(glm::rotate(glm::mat4(1.0f), 0.4f, glm::vec3(0, 0, 1))),
      joint_matrix(glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(1, 2, 3)),
                              glm::vec3(2.0f, 0.5f, 1.0f))),
      joint_matrix(glm::rotate(glm::mat4(1.0f), -1.1f, glm::vec3(1, 1, 0))),
      joint_matrix(glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.5f, 1.0f)))};
  const auto mesh = [&] {
    Mesh m;
    m.positions.resize(n);
    m.normals.resize(n);
    return m;
  };
  MeshDeformation morphed = d;
  morphed.targets = 1;
  morphed.position_deltas.assign(n, glm::vec3(0.0f));
  morphed.normal_deltas.assign(n, glm::vec3(0.0f));
  const float weight = 1.0f;
  Mesh single = mesh();
  deform_mesh(morphed, palette, &weight, single);

  const DeformIsaChoice saved = deform_isa;
  for (const bool avx2 : {false, true}) {
    if (avx2 && !host_cpu_has_avx2()) {
      std::printf("(no AVX2 on this CPU: the baseline loop only)\n");
      continue;
    }
    SCOPED_TRACE(avx2 ? "AVX2" : "baseline");
    deform_isa.avx2 = avx2;
    Mesh batched = mesh();
    deform_mesh(d, palette, nullptr, batched);
    EXPECT_EQ(std::memcmp(batched.positions.data(), single.positions.data(), n * sizeof(glm::vec3)),
              0);
    EXPECT_EQ(std::memcmp(batched.normals.data(), single.normals.data(), n * sizeof(glm::vec3)), 0);
    for (size_t v = 0; v < n; v += 1013)
      EXPECT_NEAR(glm::length(batched.normals[v]), 1.0f, 1e-6f) << v;
    // The mirrored vertices' normals keep facing out: det < 0 flips the
    // cofactor back.
    EXPECT_GT(batched.normals[5].y, 0.0f);
    // A blend that collapses (a zero matrix) keeps the base normal, in the
    // batch and in the tail alike.
    const JointMatrix zero[4] = {};
    Mesh collapsed = mesh();
    deform_mesh(d, zero, nullptr, collapsed);
    EXPECT_EQ(std::memcmp(collapsed.normals.data(), d.base_normals.data(), n * sizeof(glm::vec3)),
              0);
  }
  deform_isa = saved;
}

TEST(MeshDeformer, WalkerAndGridRigsStayFiniteAndMove) {
  for (int rig_kind = 0; rig_kind < 2; ++rig_kind) {
    ProceduralRig rig = rig_kind == 0 ? make_walker_rig(0) : make_skinned_grid_rig(64, 0);
    for (size_t v = 0; v < rig.deformation.vertex_count(); ++v) {
      float sum = 0.0f;
      for (uint32_t i = 0; i < 4; ++i)
        sum += rig.deformation.weights[4 * v + i];
      ASSERT_NEAR(sum, 1.0f, 1e-5f) << v;
    }
    JointMatrix palette[8];
    Mesh posed = rig.mesh;
    std::vector<glm::vec3> previous = posed.positions;
    for (double t : {0.0, 0.4, 1.3}) {
      if (rig_kind == 0) {
        walker_palette(t, arena_walker_paths()[0], palette);
      } else {
        skinned_grid_palette(t, palette);
      }
      deform_mesh(rig.deformation, palette, nullptr, posed);
      for (const glm::vec3& p : posed.positions)
        ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
      for (const glm::vec3& n : posed.normals)
        ASSERT_NEAR(glm::length(n), 1.0f, 1e-5f);
      EXPECT_NE(posed.positions, previous) << rig_kind << " " << t;
      previous = posed.positions;
    }
  }
}

TEST(MeshDeformer, ArenaWalkersAnimateThroughTheSceneAnimator) {
  Scene scene = make_builtin_scene("arena");
  std::vector<uint32_t> walkers;
  for (uint32_t i = 0; i < scene.meshes().size(); ++i) {
    if (scene.meshes()[i].name.rfind("rig.walker.", 0) == 0) walkers.push_back(i);
  }
  ASSERT_EQ(walkers.size(), arena_walker_paths().size());
  auto animator = make_scene_animator(scene);
  const std::vector<glm::vec3> before = scene.meshes()[walkers[0]].positions;
  scene.clear_dirty();
  animator->pose(0.75, scene);
  for (uint32_t m : walkers)
    EXPECT_TRUE(scene.mesh_dirty()[m] & kDirtyVertices) << m;
  EXPECT_NE(scene.meshes()[walkers[0]].positions, before);
  animator->pose(0.0, scene);  // back at t = 0: the scene as built
  EXPECT_EQ(scene.meshes()[walkers[0]].positions, before);
}

TEST(MeshDeformer, SkinnedGridIsABuiltinWithAMillionVerticesThatAnimates) {
  const auto names = builtin_scene_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "skinned-grid"), names.end());
  Scene scene = make_skinned_grid_scene(100);  // the built-in is 1000 x 1000
  EXPECT_EQ(scene.meshes()[0].positions.size(), 10000u);
  auto animator = make_scene_animator(scene);
  EXPECT_TRUE(animator->animated());
  scene.clear_dirty();
  animator->pose(1.0, scene);
  EXPECT_TRUE(scene.mesh_dirty()[0] & kDirtyVertices);
}

}  // namespace
}  // namespace tandem
