// glTF loader on the shared sample models: counts checked against the
// files and ../shared/scenes/gltf/SOURCES.md, invariants every loaded scene
// must satisfy, and the features each sample exists to show. Hand-written
// files for what the samples do not cover: scenes_gltf_handmade_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "core/util/errors.h"
#include "scenes/gltf_internal.h"
#include "scenes/gltf_loader.h"
namespace tandem {
namespace {

namespace fs = std::filesystem;

fs::path models_dir() {
  return fs::path(TANDEM_SHARED_DIR) / "scenes/gltf";
}

std::vector<fs::path> all_model_files() {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(models_dir())) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".gltf" || ext == ".glb")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// The model folder a file belongs to: gltf/<Model>/<variant>/<file>.
std::string model_of(const fs::path& file) {
  return fs::relative(file, models_dir()).begin()->string();
}

// Per model, identical for every variant (.gltf, .glb, embedded).
// file_tris and in_scene are the SOURCES.md numbers ("tris" = sum of
// primitive index counts / 3; "in scene" counts node instancing).
// unique = triangles in the tandem meshes: glTF meshes that share accessors
// but use different materials cannot share a tandem Mesh (materials are per
// triangle), so MetalRoughSpheresNoTextures and TransmissionTest keep more
// unique triangles than SOURCES.md's accessor-level count.
struct Expected {
  size_t file_tris, in_scene, unique, instances, meshes, materials, textures;
  bool camera;
};

const std::map<std::string, Expected>& expected() {
  static const std::map<std::string, Expected> table = {
      {"AnimatedCube", {12, 12, 12, 1, 1, 1, 2, false}},
      {"Box", {12, 12, 12, 1, 1, 1, 0, false}},
      {"BoxAnimated", {254, 254, 254, 2, 2, 2, 0, false}},
      {"BoxTextured", {12, 12, 12, 1, 1, 1, 1, false}},
      {"Duck", {4212, 4212, 4212, 1, 1, 1, 1, true}},
      {"EmissiveStrengthTest", {90, 90, 90, 6, 6, 6, 1, false}},
      // 15 textures, 3 of whose images are missing from the shared copy.
      {"FlightHelmet", {94722, 94722, 94722, 6, 6, 6, 12, false}},
      {"MetalRoughSpheresNoTextures", {1040409, 1040409, 1040409, 102, 102, 99, 0, false}},
      // Default scene (1) shows the 2-triangle square; the file has 3 triangles.
      {"MultipleScenes", {3, 2, 2, 1, 1, 1, 0, false}},
      {"SimpleInstancing", {12, 1500, 12, 125, 1, 1, 0, false}},
      {"SimpleMeshes", {1, 2, 1, 2, 1, 1, 0, false}},
      // Occlusion textures are not read, so 7 of 8.
      {"ToyCar", {108936, 108936, 108936, 3, 3, 3, 7, true}},
      // 22 meshes, 18 distinct (same accessors and materials).
      {"TransmissionTest", {128775, 128775, 128759, 22, 18, 14, 9, true}},
  };
  return table;
}

Scene load(const std::string& relative, GltfSummary* summary = nullptr, int scene_index = -1) {
  GltfOptions options;
  options.scene_index = scene_index;
  return load_gltf(models_dir() / relative, options, summary);
}

// Invariants every loaded scene must satisfy, whatever the file.
void check_consistent(const Scene& scene) {
  for (const Mesh& m : scene.meshes()) {
    const size_t n = m.positions.size();
    EXPECT_TRUE(m.normals.empty() || m.normals.size() == n) << m.name;
    EXPECT_TRUE(m.tangents.empty() || m.tangents.size() == n) << m.name;
    EXPECT_TRUE(m.uv0.empty() || m.uv0.size() == n) << m.name;
    EXPECT_TRUE(m.uv1.empty() || m.uv1.size() == n) << m.name;
    ASSERT_EQ(m.triangle_materials.size(), m.triangles.size()) << m.name;
    EXPECT_FALSE(m.triangles.empty()) << m.name;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k)
        ASSERT_LT(m.triangles[t][k], n) << m.name;
      ASSERT_LT(m.triangle_materials[t], scene.materials().size()) << m.name;
    }
    for (const glm::vec3& p : m.positions) {
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << m.name;
    }
  }
  for (const Instance& i : scene.instances()) {
    ASSERT_LT(i.mesh, scene.meshes().size());
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r)
        ASSERT_TRUE(std::isfinite(i.transform[c][r])) << i.name;
    }
  }
  for (const Material& m : scene.materials()) {
    for (const TextureRef* ref :
         {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture,
          &m.emissive_texture, &m.transmission_texture, &m.clearcoat_texture,
          &m.clearcoat_roughness_texture, &m.sheen_color_texture, &m.sheen_roughness_texture}) {
      EXPECT_GE(ref->texture, -1);
      EXPECT_LT(ref->texture, int32_t(scene.textures().size())) << m.name;
      EXPECT_LE(ref->transform.uv_set, 1u);
    }
  }
  for (const Texture& t : scene.textures()) {
    EXPECT_GT(t.width, 0u);
    EXPECT_EQ(t.rgba8.size(), size_t(t.width) * t.height) << t.name;
  }
  if (scene.has_camera()) {
    const Camera& c = scene.camera();
    EXPECT_NEAR(glm::length(c.forward), 1.0f, 1e-4f);
    EXPECT_NEAR(glm::length(c.up), 1.0f, 1e-4f);
    EXPECT_NEAR(glm::dot(c.forward, c.up), 0.0f, 1e-4f);
    EXPECT_GT(c.focus_distance, 0.0f);
  }
}

TEST(GltfModels, FindsEveryModelAndVariant) {
  const std::vector<fs::path> files = all_model_files();
  EXPECT_EQ(files.size(), 22u);
  std::set<std::string> models;
  for (const fs::path& f : files)
    models.insert(model_of(f));
  for (const auto& [name, e] : expected())
    EXPECT_EQ(models.count(name), 1u) << name;
  EXPECT_EQ(models.size(), expected().size());
}

class GltfModelFile : public testing::TestWithParam<fs::path> {};

TEST_P(GltfModelFile, LoadsWithExpectedCounts) {
  const fs::path file = GetParam();
  const auto it = expected().find(model_of(file));
  ASSERT_NE(it, expected().end()) << "no expectations for " << file;
  const Expected& e = it->second;
  GltfSummary summary;
  const Scene scene = load_gltf(file, {}, &summary);
  check_consistent(scene);
  EXPECT_EQ(summary.file_triangles, e.file_tris);
  EXPECT_EQ(summary.degenerate_triangles_dropped, 0u);
  EXPECT_EQ(scene.triangle_count_instanced(), e.in_scene);
  EXPECT_EQ(scene.triangle_count_unique(), e.unique);
  EXPECT_EQ(scene.instances().size(), e.instances);
  EXPECT_EQ(scene.meshes().size(), e.meshes);
  EXPECT_EQ(scene.materials().size(), e.materials);
  EXPECT_EQ(scene.textures().size(), e.textures);
  EXPECT_EQ(scene.has_camera(), e.camera);
  EXPECT_TRUE(scene.lights().empty());  // none of the samples has punctual lights
  EXPECT_FALSE(scene.bounds().empty);
}

std::string variant_name(const testing::TestParamInfo<fs::path>& info) {
  std::string name = fs::relative(info.param, models_dir()).string();
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(Shared, GltfModelFile, testing::ValuesIn(all_model_files()), variant_name);

TEST(GltfModels, SimpleInstancingMakesOneInstancePerEntry) {
  const Scene scene = load("SimpleInstancing/glTF/SimpleInstancing.gltf");
  ASSERT_EQ(scene.meshes().size(), 1u);
  std::set<std::tuple<float, float, float>> origins;
  for (const Instance& i : scene.instances()) {
    EXPECT_EQ(i.mesh, 0u);
    origins.insert({i.transform[3].x, i.transform[3].y, i.transform[3].z});
  }
  EXPECT_EQ(origins.size(), 125u);  // every instance in its own place
}

TEST(GltfModels, SimpleMeshesSharesTheMesh) {
  const Scene scene = load("SimpleMeshes/glTF/SimpleMeshes.gltf");
  ASSERT_EQ(scene.instances().size(), 2u);
  EXPECT_EQ(scene.instances()[0].mesh, scene.instances()[1].mesh);
  EXPECT_EQ(glm::vec3(scene.instances()[1].transform[3]), glm::vec3(1, 0, 0));
}

TEST(GltfModels, BoxParentMatrixIsApplied) {
  // Node 0's matrix rotates -90 degrees about X; the mesh is on its child.
  const Scene scene = load("Box/glTF/Box.gltf");
  ASSERT_EQ(scene.instances().size(), 1u);
  const glm::mat4& m = scene.instances()[0].transform;
  const glm::vec3 y(m * glm::vec4(0, 1, 0, 0)), z(m * glm::vec4(0, 0, 1, 0));
  EXPECT_NEAR(glm::distance(y, glm::vec3(0, 0, -1)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::distance(z, glm::vec3(0, 1, 0)), 0.0f, 1e-6f);
}

TEST(GltfModels, DuckCameraComesFromTheNodeHierarchy) {
  // Camera node 1 sits under node 0, which scales by 0.01.
  const Scene scene = load("Duck/glTF/Duck.gltf");
  ASSERT_TRUE(scene.has_camera());
  const Camera& c = scene.camera();
  EXPECT_EQ(c.type, CameraType::kPerspective);
  EXPECT_NEAR(c.yfov, 0.6605925559997559f, 1e-6f);
  EXPECT_NEAR(glm::distance(c.position, glm::vec3(4.00113f, 4.63264f, -4.31078f)), 0.0f, 1e-4f);
  const glm::vec3 forward = -glm::normalize(glm::vec3(0.53647506f, 0.62114781f, -0.57128799f));
  EXPECT_NEAR(glm::distance(c.forward, forward), 0.0f, 1e-4f);
  // The duck's mesh instance carries the parent's 0.01 scale.
  const glm::mat4& m = scene.instances()[0].transform;
  EXPECT_NEAR(glm::length(glm::vec3(m[0])), 0.01f, 1e-6f);
}

TEST(GltfModels, MultipleScenesSelectsByIndex) {
  GltfSummary s0, s1;
  const Scene scene0 = load("MultipleScenes/glTF/MultipleScenes.gltf", &s0, 0);
  const Scene scene1 = load("MultipleScenes/glTF/MultipleScenes.gltf", &s1, 1);
  const Scene default_scene = load("MultipleScenes/glTF/MultipleScenes.gltf");
  EXPECT_EQ(s0.scenes, 2u);
  EXPECT_EQ(s0.scene_loaded, 0);
  EXPECT_EQ(s1.scene_loaded, 1);
  EXPECT_EQ(scene0.triangle_count_instanced(), 1u);         // the triangle
  EXPECT_EQ(scene1.triangle_count_instanced(), 2u);         // the square
  EXPECT_EQ(default_scene.triangle_count_instanced(), 2u);  // the file says "scene": 1
}

TEST(GltfModels, OutOfRangeSceneIndexIsAnInputError) {
  try {
    load("MultipleScenes/glTF/MultipleScenes.gltf", nullptr, 2);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("MultipleScenes.gltf: scene index 2 is out of range"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(load("Box/glTF/Box.gltf", nullptr, 1), InputError);
  EXPECT_THROW(load("Box/glTF/Box.gltf", nullptr, -5), InputError);
}

TEST(GltfModels, EmissiveStrengthIsApplied) {
  const Scene scene = load("EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf");
  std::map<std::string, float> strength;
  for (const Material& m : scene.materials())
    strength[m.name] = m.emissive_strength;
  EXPECT_EQ(strength["Emit1"], 1.0f);
  EXPECT_EQ(strength["Emit2"], 2.0f);
  EXPECT_EQ(strength["Emit4"], 4.0f);
  EXPECT_EQ(strength["Emit8"], 8.0f);
  EXPECT_EQ(strength["Emit16"], 16.0f);
  for (const Material& m : scene.materials()) {
    if (m.name.rfind("Emit", 0) == 0) {
      EXPECT_NEAR(glm::distance(m.emissive, glm::vec3(0.1f, 0.5f, 0.9f)), 0.0f, 1e-6f);
    }
  }
}

TEST(GltfModels, TransmissionTestHasTransmissiveMaterials) {
  for (const char* file : {"TransmissionTest/glTF/TransmissionTest.gltf",
                           "TransmissionTest/glTF-Binary/TransmissionTest.glb"}) {
    const Scene scene = load(file);
    EXPECT_TRUE(std::any_of(scene.materials().begin(), scene.materials().end(),
                            [](const Material& m) { return m.transmission > 0.0f; }))
        << file;
  }
}

TEST(GltfModels, ToyCarHasTextureTransformAndGlass) {
  const Scene scene = load("ToyCar/glTF/ToyCar.gltf");
  bool transformed = false;
  for (const Material& m : scene.materials()) {
    if (m.base_color_texture.transform.scale == glm::vec2(3.0f) &&
        m.base_color_texture.texture >= 0) {
      transformed = true;
      EXPECT_EQ(m.normal_texture.transform.scale, glm::vec2(3.0f));
    }
  }
  EXPECT_TRUE(transformed);
  const auto glass = std::find_if(scene.materials().begin(), scene.materials().end(),
                                  [](const Material& m) { return m.name == "Glass"; });
  ASSERT_NE(glass, scene.materials().end());
  EXPECT_EQ(glass->transmission, 1.0f);
  EXPECT_TRUE(scene.materials()[0].double_sided);
}

TEST(GltfModels, ToyCarGetsItsClearcoatAndSheenWithoutWarnings) {
  testing::internal::CaptureStderr();
  const Scene scene = load("ToyCar/glTF/ToyCar.gltf");
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(log.find("KHR_materials_clearcoat"), std::string::npos) << log;
  EXPECT_EQ(log.find("KHR_materials_sheen"), std::string::npos) << log;
  EXPECT_EQ(log.find("not supported"), std::string::npos) << log;
  auto named = [&](const std::string& name) -> const Material& {
    const auto it = std::find_if(scene.materials().begin(), scene.materials().end(),
                                 [&](const Material& m) { return m.name == name; });
    EXPECT_NE(it, scene.materials().end()) << name;
    return it == scene.materials().end() ? scene.materials()[0] : *it;
  };
  // The body: a full clear coat whose strength comes from a texture.
  const Material& body = named("ToyCar");
  EXPECT_FLOAT_EQ(body.clearcoat, 1.0f);
  EXPECT_FLOAT_EQ(body.clearcoat_roughness, 0.0f);
  ASSERT_GE(body.clearcoat_texture.texture, 0);
  EXPECT_EQ(scene.textures()[size_t(body.clearcoat_texture.texture)].name, "ToyCar_clearcoat.png");
  EXPECT_EQ(body.clearcoat_roughness_texture.texture, -1);
  EXPECT_EQ(body.sheen_color, glm::vec3(0.0f));
  // The cloth: a red sheen of roughness 0.5 over a dark base.
  const Material& fabric = named("Fabric");
  EXPECT_EQ(fabric.sheen_color, glm::vec3(1.0f, 0.0f, 0.0f));
  EXPECT_FLOAT_EQ(fabric.sheen_roughness, 0.5f);
  EXPECT_EQ(fabric.sheen_color_texture.texture, -1);
  EXPECT_EQ(fabric.sheen_roughness_texture.texture, -1);
  EXPECT_FLOAT_EQ(fabric.clearcoat, 0.0f);
  // The glass has neither layer.
  const Material& glass = named("Glass");
  EXPECT_FLOAT_EQ(glass.clearcoat, 0.0f);
  EXPECT_EQ(glass.sheen_color, glm::vec3(0.0f));
}

TEST(GltfModels, FlightHelmetLoadsWithWarningsForMissingImages) {
  GltfSummary summary;
  testing::internal::CaptureStderr();
  const Scene scene = load("FlightHelmet/glTF/FlightHelmet.gltf", &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 3u);
  EXPECT_EQ(summary.textures, 15u);
  for (const char* name : {"LeatherPartsMat_BaseColor.png", "LeatherPartsMat_Normal.png",
                           "LeatherPartsMat_OcclusionRoughMetal.png"}) {
    EXPECT_NE(log.find(name), std::string::npos) << log;
  }
  const auto leather = std::find_if(scene.materials().begin(), scene.materials().end(),
                                    [](const Material& m) { return m.name == "LeatherPartsMat"; });
  ASSERT_NE(leather, scene.materials().end());
  EXPECT_EQ(leather->base_color_texture.texture, -1);
  EXPECT_EQ(leather->normal_texture.texture, -1);
  for (const Material& m : scene.materials()) {
    if (m.name != "LeatherPartsMat") {
      EXPECT_GE(m.base_color_texture.texture, 0) << m.name;
    }
  }
}

TEST(GltfModels, EmbeddedAndExternalImagesDecodeAlike) {
  // BoxTextured's CesiumLogoFlat.png: same pixels from the .gltf (file) and
  // the .glb (bufferView).
  const Scene a = load("BoxTextured/glTF/BoxTextured.gltf");
  const Scene b = load("BoxTextured/glTF-Binary/BoxTextured.glb");
  ASSERT_EQ(a.textures().size(), 1u);
  ASSERT_EQ(b.textures().size(), 1u);
  EXPECT_EQ(a.textures()[0].width, b.textures()[0].width);
  EXPECT_EQ(a.textures()[0].rgba8, b.textures()[0].rgba8);
  EXPECT_EQ(a.materials()[0].base_color_texture.texture, 0);
}

}  // namespace
}  // namespace tandem
