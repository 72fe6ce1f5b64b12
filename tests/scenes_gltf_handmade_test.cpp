// glTF loader on small files written by the test (tests/scenes_gltf_test_file.h):
// node transforms, primitive modes, accessors (sparse, strided, normalised),
// textures and samplers, material extensions, cameras and lights, and bad
// data reported with the file and the reason.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include "core/util/errors.h"
#include "scenes/gltf_internal.h"
#include "scenes/gltf_loader.h"
#include "tests/scenes_gltf_test_file.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

using test::GltfTestFile;
using test::kTriangle;

// 2x2 RGBA PNG: top row red, green; bottom row blue, white at alpha 128.
const char* kPng2x2 =
    "iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAYAAABytg0kAAAAE0lEQVR4nGP4z8DwHwyBNAg0AABJSQl4KKDbdwAAAABJRU"
    "5ErkJggg==";
// 1x1 16-bit grey PNG, value 0x8080.
const char* kPngGrey16 =
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABEAAAAABq7kcWAAAAC0lEQVR4nGNoaAAAAYMBARg1IhUAAAAASUVORK5CYII=";

class GltfHandMade : public testing::Test {
 protected:
  void SetUp() override {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("tandem_gltf_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

  // A file with one triangle mesh (3 vertices, accessor 0, mesh 0) plus the
  // given JSON members (nodes, scenes, materials, ...).
  static std::string triangle_gltf(const std::string& members) {
    GltfTestFile d;
    d.vec3(kTriangle);
    return d.file(R"("meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}])" +
                  (members.empty() ? "" : ", " + members));
  }

  Scene load(const std::string& name, const std::string& text, const GltfOptions& options = {}) {
    return load_gltf(write(name, text), options);
  }

  // Loads and returns the InputError message ("" if it loaded).
  std::string error(const std::string& name, const std::string& text) {
    try {
      load(name, text);
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind((dir_ / name).string() + ": ", 0), 0u) << msg;
      return msg;
    }
    return "";
  }

  fs::path dir_;
};

bool near(const glm::vec3& a, const glm::vec3& b, float eps = 1e-5f) {
  return glm::distance(a, b) < eps;
}

TEST_F(GltfHandMade, TrsComposesParentTimesLocal) {
  // Parent: T(1,2,3) * R(90 deg about Z; glTF order x,y,z,w) * S(2); child: T(1,0,0).
  const Scene scene = load("trs.gltf", triangle_gltf(R"(
      "nodes": [{"translation": [1, 2, 3], "rotation": [0, 0, 0.70710678, 0.70710678], "scale": [2, 2, 2], "children": [1]},
                {"translation": [1, 0, 0], "mesh": 0}],
      "scenes": [{"nodes": [0]}])"));
  ASSERT_EQ(scene.instances().size(), 1u);
  const glm::mat4& m = scene.instances()[0].transform;
  EXPECT_TRUE(near(glm::vec3(m * glm::vec4(0, 0, 0, 1)), {1, 4, 3}));
  EXPECT_TRUE(near(glm::vec3(m * glm::vec4(1, 0, 0, 0)), {0, 2, 0}));  // x -> y, scaled
}

TEST_F(GltfHandMade, MatrixNodeAndMirroredTransformAreKept) {
  const Scene scene = load("matrix.gltf", triangle_gltf(R"(
      "nodes": [{"matrix": [2,0,0,0, 0,3,0,0, 0,0,4,0, 5,6,7,1], "mesh": 0},
                {"scale": [-1, 1, 1], "mesh": 0}],
      "scenes": [{"nodes": [0, 1]}])"));
  ASSERT_EQ(scene.instances().size(), 2u);
  const glm::mat4 expected(2, 0, 0, 0, 0, 3, 0, 0, 0, 0, 4, 0, 5, 6, 7, 1);
  EXPECT_EQ(scene.instances()[0].transform, expected);
  EXPECT_LT(glm::determinant(scene.instances()[1].transform), 0.0f);  // mirrored, not "fixed"
  EXPECT_EQ(scene.meshes().size(), 1u);
}

TEST_F(GltfHandMade, StripAndFanBecomeTriangles) {
  GltfTestFile d;
  d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 2, 1, 0});
  const Scene scene = load("strip_fan.gltf", d.file(R"(
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 5},
                                 {"attributes": {"POSITION": 0}, "mode": 6}]}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])"));
  ASSERT_EQ(scene.meshes().size(), 1u);
  const Mesh& m = scene.meshes()[0];
  ASSERT_EQ(m.positions.size(), 10u);
  const std::vector<glm::uvec3> want = {{0, 1, 2}, {1, 3, 2}, {2, 3, 4},   // strip
                                        {6, 7, 5}, {7, 8, 5}, {8, 9, 5}};  // fan (+5 offset)
  EXPECT_EQ(m.triangles, want);
}

TEST_F(GltfHandMade, NonIndexedPrimitiveAndDefaultMaterial) {
  GltfTestFile d;
  d.vec3({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1});
  const Scene scene = load("non_indexed.gltf", d.file(R"(
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0)"));
  const std::vector<glm::uvec3> want = {{0, 1, 2}, {3, 4, 5}};
  EXPECT_EQ(scene.meshes()[0].triangles, want);
  ASSERT_EQ(scene.materials().size(), 1u);  // the glTF default material, added once
  const Material& m = scene.materials()[0];
  EXPECT_EQ(m.base_color, glm::vec4(1.0f));
  EXPECT_EQ(m.metallic, 1.0f);
  EXPECT_EQ(m.roughness, 1.0f);
}

TEST_F(GltfHandMade, IndexedMixedAttributesAreFilled) {
  // Two primitives of one mesh: the first has NORMAL and TEXCOORD_0 (as
  // normalized UNSIGNED_SHORT, with byteStride), the second has neither.
  GltfTestFile d;
  d.vec3(kTriangle);
  d.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  const int uv = d.view(std::vector<uint16_t>{0, 0, 99, 99, 65535, 0, 99, 99, 0, 65535}, 8);
  d.accessor(R"({"bufferView": )" + std::to_string(uv) +
             R"(, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC2"})");
  const int idx = d.view(std::vector<uint16_t>{0, 1, 2});
  d.accessor(R"({"bufferView": )" + std::to_string(idx) +
             R"(, "componentType": 5123, "count": 3, "type": "SCALAR"})");
  const Scene scene = load("mixed.gltf", d.file(R"(
      "materials": [{"name": "a"}, {"name": "b"}],
      "meshes": [{"primitives": [
          {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 1},
          {"attributes": {"POSITION": 0}, "indices": 3, "material": 0}]}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])"));
  const Mesh& m = scene.meshes()[0];
  ASSERT_EQ(m.positions.size(), 6u);
  ASSERT_EQ(m.normals.size(), 6u);
  ASSERT_EQ(m.uv0.size(), 6u);
  EXPECT_TRUE(m.tangents.empty());
  EXPECT_TRUE(m.uv1.empty());
  EXPECT_EQ(m.uv0[1], glm::vec2(1, 0));
  EXPECT_EQ(m.uv0[2], glm::vec2(0, 1));
  EXPECT_EQ(m.uv0[4], glm::vec2(0, 0));        // filled
  EXPECT_TRUE(near(m.normals[4], {0, 0, 1}));  // face normal of the second copy
  EXPECT_EQ(m.triangle_materials, (std::vector<uint32_t>{1, 0}));
  EXPECT_EQ(scene.materials().size(), 2u);  // no default needed
}

TEST_F(GltfHandMade, SparseAccessorSubstitutesValues) {
  GltfTestFile d;
  const int pos = d.view(kTriangle);
  const int sidx = d.view(std::vector<uint8_t>{2});
  const int sval = d.view(std::vector<float>{0, 5, 0});
  const std::string sparse = R"("sparse": {"count": 1, "indices": {"bufferView": )" +
                             std::to_string(sidx) + R"(, "componentType": 5121},
                             "values": {"bufferView": )" +
                             std::to_string(sval) + "}}";
  d.accessor(R"({"bufferView": )" + std::to_string(pos) +
             R"(, "componentType": 5126, "count": 3, "type": "VEC3", )" + sparse + "}");
  d.accessor(R"({"componentType": 5126, "count": 3, "type": "VEC3", )" + sparse + "}");
  const Scene scene = load("sparse.gltf", d.file(R"(
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]},
                 {"primitives": [{"attributes": {"POSITION": 1}}]}],
      "nodes": [{"mesh": 0}, {"mesh": 1}], "scenes": [{"nodes": [0, 1]}])"));
  ASSERT_EQ(scene.meshes().size(), 2u);
  EXPECT_EQ(scene.meshes()[0].positions[1], glm::vec3(1, 0, 0));
  EXPECT_EQ(scene.meshes()[0].positions[2], glm::vec3(0, 5, 0));  // substituted
  EXPECT_EQ(scene.meshes()[1].positions[0], glm::vec3(0, 0, 0));  // no bufferView: zeros
  EXPECT_EQ(scene.meshes()[1].positions[2], glm::vec3(0, 5, 0));
}

TEST_F(GltfHandMade, TextureTransformSamplerAndImages) {
  const std::string text = triangle_gltf(std::string(R"(
      "images": [{"uri": "data:image/png;base64,)") +
                                         kPng2x2 + R"("},
                 {"uri": "missing.png"},
                 {"uri": "data:image/png;base64,)" +
                                         kPngGrey16 + R"("}],
      "samplers": [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33648}],
      "textures": [{"source": 0, "sampler": 0}, {"source": 1}, {"source": 2}],
      "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 0,
                       "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.25], "rotation": 0.3,
                                                                "scale": [2, 3], "texCoord": 1}}},
                                              "metallicRoughnessTexture": {"index": 2}},
                     "normalTexture": {"index": 1, "scale": 0.5}, "alphaMode": "MASK", "alphaCutoff": 0.25,
                     "doubleSided": true, "emissiveFactor": [1, 0.5, 0],
                     "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.75, "transmissionTexture": {"index": 0, "texCoord": 3}},
                                    "KHR_materials_ior": {"ior": 1.33},
                                    "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [2, 0.5, -1]},
                                    "KHR_materials_emissive_strength": {"emissiveStrength": 5}}}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])");
  // The mesh has no material on its primitive; make it use material 0.
  std::string with_material = text;
  with_material.replace(with_material.find(R"({"POSITION": 0}})"), 16,
                        R"({"POSITION": 0}, "material": 0})");
  testing::internal::CaptureStderr();
  const Scene scene = load("textures.gltf", with_material);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("missing.png"), std::string::npos) << log;
  EXPECT_NE(log.find("TEXCOORD_3"), std::string::npos) << log;

  ASSERT_EQ(scene.materials().size(), 1u);
  const Material& m = scene.materials()[0];
  const TextureRef& bc = m.base_color_texture;
  ASSERT_EQ(bc.texture, 0);
  EXPECT_EQ(bc.transform.offset, glm::vec2(0.5f, 0.25f));
  EXPECT_EQ(bc.transform.scale, glm::vec2(2.0f, 3.0f));
  EXPECT_FLOAT_EQ(bc.transform.rotation, 0.3f);
  EXPECT_EQ(bc.transform.uv_set, 1u);       // the transform's texCoord overrides
  EXPECT_EQ(m.normal_texture.texture, -1);  // its image is missing
  EXPECT_FLOAT_EQ(m.normal_scale, 0.5f);
  EXPECT_EQ(m.transmission_texture.texture, 0);
  EXPECT_EQ(m.transmission_texture.transform.uv_set, 0u);  // TEXCOORD_3 -> 0 with a warning
  EXPECT_FLOAT_EQ(m.transmission, 0.75f);
  EXPECT_FLOAT_EQ(m.ior, 1.33f);
  EXPECT_FLOAT_EQ(m.specular, 0.5f);
  EXPECT_EQ(m.specular_color, glm::vec3(1.0f, 0.5f, 0.0f));  // clamped
  EXPECT_FLOAT_EQ(m.emissive_strength, 5.0f);
  EXPECT_EQ(m.emissive, glm::vec3(1.0f, 0.5f, 0.0f));
  EXPECT_EQ(m.alpha_mode, AlphaMode::kMask);
  EXPECT_FLOAT_EQ(m.alpha_cutoff, 0.25f);
  EXPECT_TRUE(m.double_sided);

  ASSERT_EQ(scene.textures().size(), 2u);
  const Texture& t = scene.textures()[0];
  EXPECT_EQ(t.wrap_s, WrapMode::kClampToEdge);
  EXPECT_EQ(t.wrap_t, WrapMode::kMirroredRepeat);
  EXPECT_TRUE(t.nearest);
  ASSERT_EQ(t.width, 2u);
  ASSERT_EQ(t.height, 2u);
  EXPECT_EQ(t.rgba8, (std::vector<uint32_t>{0xFF0000FFu, 0xFF00FF00u, 0xFFFF0000u, 0x80FFFFFFu}));
  const Texture& grey16 = scene.textures()[m.metallic_roughness_texture.texture];
  EXPECT_EQ(grey16.rgba8, (std::vector<uint32_t>{0xFF808080u}));
  EXPECT_EQ(grey16.wrap_s, WrapMode::kRepeat);
  EXPECT_FALSE(grey16.nearest);
}

TEST_F(GltfHandMade, ClearcoatAndSheenFactorsAndTextures) {
  std::string text = triangle_gltf(std::string(R"(
      "extensionsUsed": ["KHR_materials_clearcoat", "KHR_materials_sheen"],
      "images": [{"uri": "data:image/png;base64,)") +
                                   kPng2x2 + R"("}],
      "textures": [{"source": 0}],
      "materials": [{"extensions": {
          "KHR_materials_clearcoat": {"clearcoatFactor": 0.75, "clearcoatRoughnessFactor": 0.25,
                                      "clearcoatTexture": {"index": 0},
                                      "clearcoatRoughnessTexture": {"index": 0, "texCoord": 1},
                                      "clearcoatNormalTexture": {"index": 0}},
          "KHR_materials_sheen": {"sheenColorFactor": [0.5, 2, -1], "sheenRoughnessFactor": 0.3,
                                  "sheenColorTexture": {"index": 0},
                                  "sheenRoughnessTexture": {"index": 0}}}},
                    {"extensions": {"KHR_materials_clearcoat": {}, "KHR_materials_sheen": {}}}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])");
  text.replace(text.find(R"({"POSITION": 0}})"), 16, R"({"POSITION": 0}, "material": 0})");
  testing::internal::CaptureStderr();
  const Scene scene = load("layers.gltf", text);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("clearcoatNormalTexture"), std::string::npos) << log;
  EXPECT_NE(log.find("clamped"), std::string::npos) << log;  // the sheen colour
  EXPECT_EQ(log.find("not supported"), std::string::npos) << log;
  ASSERT_EQ(scene.materials().size(), 2u);
  const Material& m = scene.materials()[0];
  EXPECT_FLOAT_EQ(m.clearcoat, 0.75f);
  EXPECT_FLOAT_EQ(m.clearcoat_roughness, 0.25f);
  EXPECT_EQ(m.clearcoat_texture.texture, 0);
  EXPECT_EQ(m.clearcoat_roughness_texture.texture, 0);
  EXPECT_EQ(m.clearcoat_roughness_texture.transform.uv_set, 1u);
  EXPECT_EQ(m.sheen_color, glm::vec3(0.5f, 1.0f, 0.0f));
  EXPECT_FLOAT_EQ(m.sheen_roughness, 0.3f);
  EXPECT_EQ(m.sheen_color_texture.texture, 0);
  EXPECT_EQ(m.sheen_roughness_texture.texture, 0);
  // Empty extension objects: the spec's defaults, which mean "no layer".
  const Material& d = scene.materials()[1];
  EXPECT_FLOAT_EQ(d.clearcoat, 0.0f);
  EXPECT_FLOAT_EQ(d.clearcoat_roughness, 0.0f);
  EXPECT_EQ(d.sheen_color, glm::vec3(0.0f));
  EXPECT_FLOAT_EQ(d.sheen_roughness, 0.0f);
  EXPECT_EQ(d.clearcoat_texture.texture, -1);

  EXPECT_NE(error("badcoat.gltf", triangle_gltf(R"(
      "materials": [{"extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": "shiny"}}}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])"))
                .find("clearcoatFactor must be a finite number"),
            std::string::npos);
  EXPECT_NE(error("badsheen.gltf", triangle_gltf(R"(
      "materials": [{"extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 0]}}}],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])"))
                .find("sheenColorFactor must be an array of 3 numbers"),
            std::string::npos);
}

TEST(GltfImages, ConvertsEveryChannelLayoutToRgba8) {
  tinygltf::Image img;
  img.width = 1;
  img.height = 1;
  img.bits = 8;
  std::vector<uint32_t> out;
  const std::vector<std::pair<std::vector<unsigned char>, uint32_t>> cases8 = {
      {{0x40}, 0xFF404040u},
      {{0x40, 0x7F}, 0x7F404040u},
      {{1, 2, 3}, 0xFF030201u},
      {{1, 2, 3, 4}, 0x04030201u},
  };
  for (const auto& [pixels, want] : cases8) {
    img.component = int(pixels.size());
    img.image = pixels;
    ASSERT_TRUE(gltf::image_to_rgba8(img, out));
    EXPECT_EQ(out[0], want);
  }
  img.bits = 16;
  img.component = 3;
  img.image = {0xFF, 0xFF, 0x00, 0x00, 0x80, 0x80};  // little-endian 65535, 0, 0x8080
  ASSERT_TRUE(gltf::image_to_rgba8(img, out));
  EXPECT_EQ(out[0], 0xFF8000FFu);
  img.image.pop_back();  // wrong size
  EXPECT_FALSE(gltf::image_to_rgba8(img, out));
}

// Every layout over an image of several pixels with every byte different,
// against the glTF rules written out here pixel by pixel: grey fills r, g
// and b, a missing alpha is opaque, 16-bit values (little endian) round to
// the nearest 8-bit step. Catches a loop that strides or offsets wrongly.
TEST(GltfImages, EveryLayoutConvertsEveryPixel) {
  for (const int bits : {8, 16}) {
    for (int c = 1; c <= 4; ++c) {
      tinygltf::Image img;
      img.width = 5;
      img.height = 3;
      img.bits = bits;
      img.component = c;
      const size_t bytes = size_t(bits / 8), pixels = 15;
      for (size_t i = 0; i < pixels * size_t(c) * bytes; ++i)
        img.image.push_back(static_cast<unsigned char>(37 * i + 11));
      std::vector<uint32_t> out;
      ASSERT_TRUE(gltf::image_to_rgba8(img, out)) << bits << " bits, " << c << " channels";
      ASSERT_EQ(out.size(), pixels);
      for (size_t p = 0; p < pixels; ++p) {
        uint32_t ch[4];
        for (int k = 0; k < c; ++k) {
          const unsigned char* q = &img.image[(p * size_t(c) + size_t(k)) * bytes];
          const uint32_t v = bits == 8 ? q[0] : uint32_t(q[0]) | (uint32_t(q[1]) << 8);
          ch[k] = bits == 8 ? v : uint32_t(std::lround(double(v) * 255.0 / 65535.0));
        }
        const uint32_t r = ch[0], g = c >= 3 ? ch[1] : ch[0], b = c >= 3 ? ch[2] : ch[0];
        const uint32_t a = c == 2 ? ch[1] : (c == 4 ? ch[3] : 255u);
        EXPECT_EQ(out[p], r | (g << 8) | (b << 16) | (a << 24))
            << bits << " bits, " << c << " channels, pixel " << p;
      }
    }
  }
}

TEST_F(GltfHandMade, GpuInstancingComposesWithTheNode) {
  GltfTestFile d;
  d.vec3(kTriangle);
  d.vec3({0, 0, 0, 10, 0, 0, 20, 0, 0});
  d.vec3({1, 1, 1, 2, 2, 2, 3, 3, 3});
  const Scene scene = load("gpu.gltf", d.file(R"(
      "extensionsUsed": ["EXT_mesh_gpu_instancing"],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
      "nodes": [{"mesh": 0, "translation": [0, 1, 0],
                 "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 1, "SCALE": 2}}}}],
      "scenes": [{"nodes": [0]}])"));
  ASSERT_EQ(scene.instances().size(), 3u);
  EXPECT_EQ(scene.meshes().size(), 1u);
  for (size_t i = 0; i < 3; ++i) {
    const glm::mat4& m = scene.instances()[i].transform;  // node * T * S
    EXPECT_TRUE(near(glm::vec3(m[3]), {10.0f * float(i), 1, 0}));
    EXPECT_FLOAT_EQ(m[0][0], float(i + 1));
  }
  EXPECT_EQ(scene.triangle_count_instanced(), 3u);
}

TEST_F(GltfHandMade, CameraAndLightsFromNodes) {
  const Scene scene = load("camera_lights.gltf", triangle_gltf(R"(
      "extensionsUsed": ["KHR_lights_punctual"],
      "extensions": {"KHR_lights_punctual": {"lights": [
          {"type": "spot", "color": [1, 0.5, 0.25], "intensity": 7, "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}},
          {"type": "directional"}, {"type": "point", "intensity": 3}]}},
      "cameras": [{"type": "orthographic", "orthographic": {"xmag": 3, "ymag": 2, "znear": 0.1, "zfar": 100}},
                  {"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}}],
      "nodes": [{"mesh": 0},
                {"translation": [0, 0, 10], "children": [2, 3]},
                {"camera": 0},
                {"camera": 1},
                {"translation": [1, 2, 3], "rotation": [-0.70710678, 0, 0, 0.70710678],
                 "extensions": {"KHR_lights_punctual": {"light": 0}}},
                {"extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"translation": [4, 5, 6], "extensions": {"KHR_lights_punctual": {"light": 2}}}],
      "scenes": [{"nodes": [0, 1, 4, 5, 6]}])"));
  ASSERT_TRUE(scene.has_camera());
  const Camera& c = scene.camera();  // the first in the hierarchy: node 2's
  EXPECT_EQ(c.type, CameraType::kOrthographic);
  EXPECT_FLOAT_EQ(c.ortho_half_height, 2.0f);
  EXPECT_TRUE(near(c.position, {0, 0, 10}));
  EXPECT_TRUE(near(c.forward, {0, 0, -1}));
  EXPECT_TRUE(near(c.up, {0, 1, 0}));
  // Focus on the plane through the triangle's bounds centre (z = 0).
  EXPECT_NEAR(c.focus_distance, 10.0f, 1e-4f);

  ASSERT_EQ(scene.lights().size(), 3u);
  const Light& spot = scene.lights()[0];
  EXPECT_EQ(spot.type, LightType::kSpot);
  EXPECT_TRUE(near(spot.position, {1, 2, 3}));
  EXPECT_TRUE(near(spot.direction, {0, -1, 0}));  // -Z rotated -90 degrees about X
  EXPECT_EQ(spot.color, glm::vec3(1, 0.5f, 0.25f));
  EXPECT_FLOAT_EQ(spot.intensity, 7.0f);
  EXPECT_FLOAT_EQ(spot.inner_cone_angle, 0.1f);
  EXPECT_FLOAT_EQ(spot.outer_cone_angle, 0.5f);
  EXPECT_EQ(scene.lights()[1].type, LightType::kDirectional);
  EXPECT_TRUE(near(scene.lights()[1].direction, {0, 0, -1}));
  EXPECT_EQ(scene.lights()[2].type, LightType::kPoint);
  EXPECT_TRUE(near(scene.lights()[2].position, {4, 5, 6}));
}

// --camera N: the scene's camera nodes in walk order, listed in the
// summary; one beyond them is an error naming the count.
TEST_F(GltfHandMade, ACameraIsChosenByItsIndexInTheScene) {
  const std::string text = triangle_gltf(R"(
      "cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}},
                  {"type": "orthographic", "orthographic": {"xmag": 3, "ymag": 2, "znear": 0.1, "zfar": 100}}],
      "nodes": [{"mesh": 0},
                {"name": "front", "translation": [0, 0, 10], "camera": 0},
                {"name": "high", "translation": [0, 5, 10], "camera": 1},
                {"name": "side", "translation": [10, 0, 0], "rotation": [0, 0.70710678, 0, 0.70710678], "camera": 0}],
      "scenes": [{"nodes": [0, 1, 2, 3]}])");
  GltfSummary summary;
  const Scene first = load_gltf(write("cameras.gltf", text), {}, &summary);
  EXPECT_TRUE(near(first.camera().position, {0, 0, 10}));
  ASSERT_EQ(summary.scene_cameras, 3u);
  ASSERT_EQ(summary.camera_names.size(), 3u);
  EXPECT_EQ(summary.camera_names[0], "front, perspective, 57.3 degrees vertical");
  EXPECT_EQ(summary.camera_names[1], "high, orthographic");
  ASSERT_EQ(summary.camera_list.size(), 3u);
  GltfOptions o;
  o.camera = 2;
  const Scene side = load("cameras.gltf", text, o);
  EXPECT_TRUE(near(side.camera().position, {10, 0, 0}));
  EXPECT_TRUE(near(side.camera().forward, {-1, 0, 0}));
  EXPECT_EQ(side.camera().position, summary.camera_list[2].position);
  o.camera = 3;
  try {
    load("cameras.gltf", text, o);
    ADD_FAILURE() << "loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("camera 3 was asked for, but the scene has 3 cameras"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(GltfHandMade, UnsupportedExtensionsWarnOrFail) {
  testing::internal::CaptureStderr();
  const Scene scene = load("used.gltf", triangle_gltf(R"(
      "extensionsUsed": ["KHR_materials_iridescence", "EXT_some_vendor_thing"],
      "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])"));
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("KHR_materials_iridescence"), std::string::npos);
  EXPECT_NE(log.find("EXT_some_vendor_thing"), std::string::npos);
  EXPECT_EQ(scene.instances().size(), 1u);

  EXPECT_NE(error("required.gltf", triangle_gltf(R"(
      "extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"],
      "extensions": {"KHR_draco_mesh_compression": {}})"))
                .find("requires extension KHR_draco_mesh_compression"),
            std::string::npos);
  // Required and unsupported where a texture would carry it: refused.
  EXPECT_NE(error("dds.gltf", triangle_gltf(R"(
      "extensionsUsed": ["MSFT_texture_dds"], "extensionsRequired": ["MSFT_texture_dds"],
      "textures": [{"extensions": {"MSFT_texture_dds": {"source": 0}}}])"))
                .find("requires extension MSFT_texture_dds"),
            std::string::npos);
  // Required but used by nothing in the file (an exporter's habit): loads,
  // with a notice naming it.
  testing::internal::CaptureStderr();
  EXPECT_NO_THROW(load("unused.gltf", triangle_gltf(R"(
      "extensionsUsed": ["MSFT_texture_dds"], "extensionsRequired": ["MSFT_texture_dds"])")));
  EXPECT_NE(testing::internal::GetCapturedStderr().find(
                "requires extension MSFT_texture_dds, which is not supported, but nothing in it "
                "uses it"),
            std::string::npos);
  // Required but safely ignorable: loads.
  EXPECT_NO_THROW(load("ignorable.gltf", triangle_gltf(R"(
      "extensionsUsed": ["KHR_materials_volume"], "extensionsRequired": ["KHR_materials_volume"])")));
}

TEST_F(GltfHandMade, PointsAreSkippedWithAWarning) {
  std::string text = triangle_gltf(R"("nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}])");
  text.replace(text.find(R"({"POSITION": 0}})"), 16, R"({"POSITION": 0}, "mode": 0})");
  testing::internal::CaptureStderr();
  const Scene scene = load("points.gltf", text);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("points or lines"), std::string::npos) << log;
  EXPECT_NE(log.find("no triangles"), std::string::npos) << log;
  EXPECT_EQ(scene.triangle_count_instanced(), 0u);
}

TEST_F(GltfHandMade, NoScenesShowsAllRootNodes) {
  const Scene scene =
      load("no_scenes.gltf", triangle_gltf(R"("nodes": [{"mesh": 0}, {"mesh": 0}])"));
  EXPECT_EQ(scene.instances().size(), 2u);
}

TEST_F(GltfHandMade, ExplicitTextureIndexMinusOneIsAnError) {
  const std::string msg = error("minus_one.gltf", triangle_gltf(R"(
      "images": [{"uri": "data:image/png;base64,)" + std::string(kPng2x2) +
                                                                R"("}],
      "textures": [{"source": 0}],
      "materials": [{"emissiveTexture": {"index": -1}}])"));
  EXPECT_NE(msg.find("materials[0].emissiveTexture.index is -1; the glTF schema requires an "
                     "integer >= 0"),
            std::string::npos)
      << msg;
}

TEST_F(GltfHandMade, NodeCyclesAndSharedChildrenAreErrors) {
  EXPECT_NE(error("cycle.gltf", triangle_gltf(R"(
      "nodes": [{"mesh": 0, "children": [1]}, {"children": [2]}, {"children": [1]}],
      "scenes": [{"nodes": [0]}])"))
                .find("more than one parent"),
            std::string::npos);
  EXPECT_NE(error("cycle2.gltf", triangle_gltf(R"(
      "nodes": [{"mesh": 0}, {"children": [2]}, {"children": [1]}],
      "scenes": [{"nodes": [0]}])"))
                .find("cycle (nodes 2 -> 1 -> 2)"),
            std::string::npos);
  EXPECT_NE(error("self.gltf", triangle_gltf(R"("nodes": [{"children": [0]}])")).find("itself"),
            std::string::npos);
  EXPECT_NE(error("not_root.gltf", triangle_gltf(R"(
      "nodes": [{"children": [1]}, {"mesh": 0}], "scenes": [{"nodes": [1]}])"))
                .find("scene nodes must be roots"),
            std::string::npos);
}

TEST_F(GltfHandMade, ByteOrderMarkIsAnError) {
  const std::string msg = error("bom.gltf", "\xEF\xBB\xBF" + triangle_gltf(""));
  EXPECT_NE(msg.find("byte order mark"), std::string::npos) << msg;
}

TEST_F(GltfHandMade, BadDataIsReportedPrecisely) {
  // NaN in POSITION data (JSON cannot hold one, binary data can).
  GltfTestFile d;
  d.vec3({0, 0, 0, 1, 0, 0, 0, std::nanf(""), 0});
  const std::string nan_file =
      d.file(R"("meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}])");
  const std::string nan_msg = error("nan.gltf", nan_file);
  EXPECT_NE(nan_msg.find("POSITION (accessor 0) has a non-finite value"), std::string::npos)
      << nan_msg;
  EXPECT_NE(nan_msg.find("element 2"), std::string::npos) << nan_msg;

  std::string past_view = nan_file;
  past_view.replace(past_view.find(R"("count": 3)"), 10, R"("count": 4)");
  EXPECT_NE(error("past_view.gltf", past_view).find("runs past the end of bufferView 0"),
            std::string::npos);

  std::string misaligned = nan_file;
  misaligned.replace(misaligned.find(R"("count": 3)"), 10, R"("count": 2, "byteOffset": 2)");
  EXPECT_NE(error("misaligned.gltf", misaligned).find("not aligned"), std::string::npos);

  std::string no_attrs = triangle_gltf("");
  no_attrs.replace(no_attrs.find(R"("attributes": {"POSITION": 0})"), 29, R"("indices": 0)");
  EXPECT_NE(error("no_attrs.gltf", no_attrs).find("attributes"), std::string::npos);

  EXPECT_NE(error("bad_mesh_ref.gltf", triangle_gltf(R"("nodes": [{"mesh": 3}])"))
                .find("node 0 refers to mesh 3, but the file has 1 mesh"),
            std::string::npos);
  EXPECT_NE(
      error("bad_material.gltf", triangle_gltf(R"("materials": [{"alphaMode": "SOMETIMES"}])"))
          .find("alphaMode"),
      std::string::npos);
  // An accessor without bufferView is all zeros; its count is capped so a
  // few bytes of JSON cannot ask for gigabytes.
  const std::string huge = R"({"asset": {"version": "2.0"},
      "accessors": [{"componentType": 5126, "count": 4000000000, "type": "VEC3"}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]})";
  EXPECT_NE(error("huge.gltf", huge).find("has no bufferView and count 4000000000"),
            std::string::npos);
}

}  // namespace
}  // namespace tandem
