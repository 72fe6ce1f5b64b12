// Hostile glTF input: files that are small but ask for deep recursion,
// huge allocations or files outside their folder. Every case is generated
// here (a few hundred bytes each); the loader's budgets are lowered so the
// tests stay small and fast while exercising the same checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/world/scene.h"
#include "scenes/gltf_loader.h"
#include "tests/hostile_scene_cases.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The InputError message of loading `path`, or "" when it loads.
std::string load_error(const fs::path& path, const GltfOptions& options = {},
                       GltfSummary* summary = nullptr) {
  try {
    load_gltf(path, options, summary);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string nested(size_t depth) {
  return std::string(depth, '[') + std::string(depth, ']');
}

TEST(GltfHostile, DeepNestingIsRefusedBeforeParsing) {
  TempDir dir("tandem_hostile");
  // 16000 levels: enough to overflow tinygltf's recursive JSON conversion.
  const std::string cases[] = {
      R"({"asset":{"version":"2.0","extras":)" + nested(16000) + "}}",
      R"({"asset":{"version":"2.0"},"extensions":{"X":)" + nested(16000) + "}}",
      // Brackets inside strings do not count; these do.
      R"({"asset":{"version":"2.0","extras":{"s":"[[[[","a":)" + nested(200) + "}}}",
  };
  for (const std::string& json : cases) {
    const fs::path file = dir.path() / "deep.gltf";
    write_text(file, json);
    const std::string error = load_error(file);
    EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << error;
    EXPECT_NE(error.find("nested more than 128 levels"), std::string::npos) << error;
  }
  // The same inside a .glb JSON chunk.
  std::string json = R"({"asset":{"version":"2.0","extras":)" + nested(16000) + "}}";
  json.resize((json.size() + 3) / 4 * 4, ' ');
  std::string glb = "glTF";
  auto u32 = [&](uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  u32(uint32_t(12 + 8 + json.size()));
  u32(uint32_t(json.size()));
  glb += "JSON" + json;
  const fs::path file = dir.path() / "deep.glb";
  write_text(file, glb);
  EXPECT_NE(load_error(file).find("nested more than 128 levels"), std::string::npos);
}

TEST(GltfHostile, GlbBinChunkPastTheEndIsRefused) {
  // Found by the fuzzer: a BIN chunk that claims 20 bytes with 16 left made
  // tinygltf read past the end of the file.
  std::string json = R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":17}]})";
  json.resize((json.size() + 3) / 4 * 4, ' ');
  std::string glb = "glTF";
  auto u32 = [&](uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  u32(uint32_t(12 + 8 + json.size() + 8 + 16));
  u32(uint32_t(json.size()));
  glb += "JSON" + json;
  u32(20);
  glb += std::string("BIN\0", 4) + std::string(16, '\x01');
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "bin.glb";
  write_text(file, glb);
  EXPECT_NE(load_error(file).find("the BIN chunk (20 bytes) runs past the end of the file"),
            std::string::npos)
      << load_error(file);
}

TEST(GltfHostile, ModerateNestingInExtrasStillLoads) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "ok.gltf";
  write_text(file,
             R"({"asset":{"version":"2.0","extras":{"s":"[[[[[[","a":)" + nested(100) + "}}}");
  testing::internal::CaptureStderr();
  EXPECT_EQ(load_error(file), "");
  testing::internal::GetCapturedStderr();
}

// One mesh, `primitives` primitives of `mode` drawing accessor 0, which
// has `count` VEC3 elements and no bufferView (zeros, by the spec).
std::string zero_accessor_gltf(int mode, size_t count, int primitives, int accessors = 1,
                               int nodes = 1) {
  std::string json = R"({"asset":{"version":"2.0"},"accessors":[)";
  for (int a = 0; a < accessors; ++a) {
    json += std::string(a ? "," : "") + R"({"componentType":5126,"type":"VEC3","count":)" +
            std::to_string(count) + "}";
  }
  json += R"(],"meshes":[{"primitives":[)";
  for (int p = 0; p < primitives; ++p) {
    json += std::string(p ? "," : "") + R"({"attributes":{"POSITION":)" +
            std::to_string(p % accessors) + R"(},"mode":)" + std::to_string(mode) + "}";
  }
  json += R"(]}],"nodes":[)";
  for (int n = 0; n < nodes; ++n)
    json += std::string(n ? "," : "") + R"({"mesh":0})";
  json += R"(],"scenes":[{"nodes":[)";
  for (int n = 0; n < nodes; ++n)
    json += std::string(n ? "," : "") + std::to_string(n);
  return json + "]}]}";
}

TEST(GltfHostile, PointsAndLinesAreNotDecoded) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "points.gltf";
  GltfOptions options;
  options.limits.max_accessor_bytes = 1 << 20;
  // 4 M points would decode to 46 MiB of positions; they are not shown.
  for (int mode : {0, 1, 2, 3}) {
    write_text(file, zero_accessor_gltf(mode, 4000000, 1));
    testing::internal::CaptureStderr();
    EXPECT_EQ(load_error(file, options), "") << "mode " << mode;
    testing::internal::GetCapturedStderr();
  }
  // As triangles they would be decoded: the budget refuses them, by name.
  write_text(file, zero_accessor_gltf(4, 4000000, 1));
  const std::string error = load_error(file, options);
  EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << error;
  EXPECT_NE(error.find("mesh 0 primitive 0 POSITION (accessor 0)"), std::string::npos) << error;
  EXPECT_NE(error.find("46 MiB"), std::string::npos) << error;
  EXPECT_NE(error.find("limit of 1.0 MiB"), std::string::npos) << error;
}

TEST(GltfHostile, ZeroFilledAccessorsAreCountedTogether) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "zeros.gltf";
  GltfOptions options;
  options.limits.max_zero_filled_elements = 5000;
  write_text(file, zero_accessor_gltf(4, 3000, 2, 2));  // each fits, both do not
  const std::string error = load_error(file, options);
  EXPECT_NE(error.find("mesh 0 primitive 1 POSITION (accessor 1)"), std::string::npos) << error;
  EXPECT_NE(error.find("without a bufferView"), std::string::npos) << error;
  EXPECT_NE(error.find("5000"), std::string::npos) << error;
}

TEST(GltfHostile, OneAccessorSharedByManyPrimitivesIsBudgeted) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "shared.gltf";
  GltfOptions options;
  options.limits.max_geometry_bytes = 1 << 20;
  write_text(file, zero_accessor_gltf(4, 3000, 50));  // 3000 vertices x 50 merged
  const std::string error = load_error(file, options);
  EXPECT_NE(error.find("mesh geometry"), std::string::npos) << error;
  EXPECT_NE(error.find("mesh 0 primitive 5 (3000 vertices, 1000 triangles)"), std::string::npos)
      << error;
}

TEST(GltfHostile, InstancesAreBudgeted) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "instances.gltf";
  GltfOptions options;
  options.limits.max_instances = 5;
  write_text(file, zero_accessor_gltf(4, 3, 1, 1, 8));
  const std::string error = load_error(file, options);
  EXPECT_NE(error.find("node 5 instance needs 1 more instances (5 already used)"),
            std::string::npos)
      << error;
}

// A file whose `images` entries name `uris`, one texture and material each.
std::string textured_gltf(const std::vector<std::string>& uris) {
  std::string images, textures, materials;
  for (size_t i = 0; i < uris.size(); ++i) {
    const std::string sep = i ? "," : "";
    images += sep + R"({"uri":")" + uris[i] + R"("})";
    textures += sep + R"({"source":)" + std::to_string(i) + "}";
    materials += sep + R"({"pbrMetallicRoughness":{"baseColorTexture":{"index":)" +
                 std::to_string(i) + "}}}";
  }
  return R"({"asset":{"version":"2.0"},"images":[)" + images + R"(],"textures":[)" + textures +
         R"(],"materials":[)" + materials + "]}";
}

void write_png(const fs::path& path, uint32_t size, uint8_t value) {
  write_png_rgb8(path, size, size, std::vector<uint8_t>(size_t(size) * size * 3, value));
}

TEST(GltfHostile, OneImageFileIsDecodedOnceForAllItsEntries) {
  TempDir dir("tandem_hostile");
  write_png(dir.path() / "tex.png", 64, 200);
  const fs::path file = dir.path() / "same.gltf";
  write_text(file, textured_gltf(std::vector<std::string>(16, "tex.png")));
  GltfOptions options;
  options.limits.max_texture_bytes = 64 * 64 * 4;  // one decode, not sixteen
  GltfSummary summary;
  testing::internal::CaptureStderr();
  const Scene scene = load_gltf(file, options, &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 0u) << log;
  ASSERT_EQ(scene.textures().size(), 1u);  // same pixels, same sampling: one texture
  for (const Material& m : scene.materials())
    EXPECT_EQ(m.base_color_texture.texture, 0);
}

TEST(GltfHostile, TextureBudgetSkipsImagesNamingTheSize) {
  TempDir dir("tandem_hostile");
  write_png(dir.path() / "a.png", 64, 10);
  write_png(dir.path() / "b.png", 64, 20);
  const fs::path file = dir.path() / "two.gltf";
  write_text(file, textured_gltf({"a.png", "b.png"}));
  GltfOptions options;
  options.limits.max_texture_bytes = 64 * 64 * 4 + 100;
  GltfSummary summary;
  testing::internal::CaptureStderr();
  load_gltf(file, options, &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 1u);
  EXPECT_NE(log.find(file.string() + ": image 1 (\"b.png\") is unavailable: its 64x64 pixels need "
                                     "16 KiB"),
            std::string::npos)
      << log;
}

uint32_t crc32(const unsigned char* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k)
      c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

TEST(GltfHostile, HugeClaimedTextureNamesTheSizeLimit) {
  TempDir dir("tandem_hostile");
  const fs::path png = dir.path() / "huge.png";
  write_png(png, 1, 0);
  std::string bytes;
  {
    std::ifstream in(png, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto* p = reinterpret_cast<unsigned char*>(bytes.data());
  for (int off : {16, 20}) {  // IHDR width and height: 60000, big-endian
    p[off] = 0, p[off + 1] = 0, p[off + 2] = 0xea, p[off + 3] = 0x60;
  }
  const uint32_t crc = crc32(p + 12, 17);
  for (int k = 0; k < 4; ++k)
    p[29 + k] = uint8_t(crc >> (24 - 8 * k));
  write_text(png, bytes);
  const fs::path file = dir.path() / "huge.gltf";
  write_text(file, textured_gltf({"huge.png"}));
  testing::internal::CaptureStderr();
  GltfSummary summary;
  load_gltf(file, {}, &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 1u);
  EXPECT_NE(log.find("it claims 60000x60000 pixels, over the limit of 67108864 pixels"),
            std::string::npos)
      << log;
}

// A one-triangle file whose buffer is `buffer_uri` (36 bytes).
std::string buffer_gltf(const std::string& buffer_uri) {
  return R"({"asset":{"version":"2.0"},"buffers":[{"uri":")" + buffer_uri +
         R"(","byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],)"
         R"("accessors":[{"bufferView":0,"componentType":5126,"type":"VEC3","count":3}],)"
         R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
         R"("nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
}

void write_triangle_bin(const fs::path& path, size_t bytes = 36) {
  const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::string data(reinterpret_cast<const char*>(v), sizeof v);
  data.resize(bytes, '\0');
  write_text(path, data);
}

TEST(GltfHostile, UrisOutsideTheSceneFolderAreRefused) {
  TempDir dir("tandem_hostile");
  fs::create_directories(dir.path() / "scene" / "sub");
  write_triangle_bin(dir.path() / "secret.bin", 1234);  // a size the error must not reveal
  write_triangle_bin(dir.path() / "scene" / "inside.bin");
  fs::create_symlink("../secret.bin", dir.path() / "scene" / "link.bin");
  const fs::path file = dir.path() / "scene" / "s.gltf";

  write_text(file, buffer_gltf("inside.bin"));
  EXPECT_EQ(load_error(file), "");
  for (const std::string uri : {"../secret.bin", "link.bin", "sub/../../secret.bin"}) {
    write_text(file, buffer_gltf(uri));
    const std::string error = load_error(file);
    EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << error;
    EXPECT_NE(error.find("the URI \"" + uri + "\" leaves the scene's folder"), std::string::npos)
        << error;
    EXPECT_EQ(error.find("1234"), std::string::npos) << error;
    GltfOptions allow;
    allow.allow_outside_uris = true;
    // Allowed, the file is read (and its wrong size reported as usual).
    EXPECT_EQ(load_error(file, allow).find("leaves"), std::string::npos);
  }
  // Images: unavailable with the reason, the scene still loads.
  write_png(dir.path() / "outside.png", 4, 1);
  write_text(file, textured_gltf({"../outside.png"}));
  testing::internal::CaptureStderr();
  GltfSummary summary;
  load_gltf(file, {}, &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 1u);
  EXPECT_NE(log.find("the URI \"../outside.png\" leaves the scene's folder"), std::string::npos)
      << log;
}

// Out-of-range transforms, cameras, lights and emission, and values whose
// products overflow float (hostile_scene_cases.h): refused naming the file
// and the object, or loaded with finite bounds (singular nodes are simply
// not drawn).
TEST(GltfHostile, SceneValuesBeyondFloatAreRefusedByNameOrNotDrawn) {
  TempDir dir("tandem_hostile");
  for (const test::HostileScene& c : test::hostile_scenes()) {
    const fs::path file = dir.path() / (c.name + ".gltf");
    write_text(file, c.json);
    testing::internal::CaptureStderr();
    std::string error;
    Scene scene;
    try {
      scene = load_gltf(file);
    } catch (const InputError& e) {
      error = e.what();
    }
    const std::string log = testing::internal::GetCapturedStderr();
    if (c.refusal.empty()) {
      EXPECT_EQ(error, "") << c.name;
      const SceneBounds b = scene.bounds();
      EXPECT_FALSE(b.empty) << c.name;  // node 1 is always drawn
      EXPECT_TRUE(b.finite) << c.name;
      // Only node 1's triangle.
      EXPECT_LE(std::max({b.hi.x, b.hi.y, b.hi.z, -b.lo.x, -b.lo.y, -b.lo.z}), 3.0f) << c.name;
      continue;
    }
    EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << c.name << ": " << error;
    for (const std::string& part : c.refusal)
      EXPECT_NE(error.find(part), std::string::npos) << c.name << ": " << error;
  }
}

// A file of one triangle placed `count` times by EXT_mesh_gpu_instancing
// (a zero-filled TRANSLATION accessor), its node named `name`; with
// `emissive`, its material glows.
std::string instanced_gltf(const std::string& name, size_t count, bool emissive) {
  test::GltfTestFile f;
  const int pos = f.vec3(test::kTriangle);
  const int where =
      f.accessor(R"({"componentType":5126,"type":"VEC3","count":)" + std::to_string(count) + "}");
  return f.file(
      R"("extensionsUsed":["EXT_mesh_gpu_instancing"],"materials":[{"emissiveFactor":)" +
      std::string(emissive ? "[1,1,1]" : "[0,0,0]") +
      R"(}],"meshes":[{"name":"glow","primitives":[{"attributes":{"POSITION":)" +
      std::to_string(pos) + R"(},"material":0}]}],"nodes":[{"name":")" + name +
      R"(","mesh":0,"extensions":{"EXT_mesh_gpu_instancing":{"attributes":{"TRANSLATION":)" +
      std::to_string(where) + R"(}}}}],"scenes":[{"nodes":[0]}])");
}

// A node's name is copied to each of its instances: 600 KB x 1,200 took
// 1.4 GB. Names are cut to 256 bytes and all together budgeted.
TEST(GltfHostile, InstanceNamesAreCutAndBudgeted) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "names.gltf";
  write_text(file, instanced_gltf(std::string(200000, 'n'), 50, false));
  const Scene scene = load_gltf(file);
  ASSERT_EQ(scene.instances().size(), 50u);
  for (const Instance& i : scene.instances()) {
    EXPECT_LE(i.name.size(), 256u + 4u);
    EXPECT_EQ(i.name.compare(0, 10, std::string(10, 'n')), 0);
  }
  GltfOptions options;
  options.limits.max_name_bytes = 5000;  // 50 x about 260 bytes do not fit
  const std::string error = load_error(file, options);
  EXPECT_EQ(error.rfind(file.string() + ": node 0 EXT_mesh_gpu_instancing (50 instances named", 0),
            0u)
      << error;
  EXPECT_NE(error.find("more of instance names"), std::string::npos) << error;
  EXPECT_NE(error.find("limit of 4.9 KiB"), std::string::npos) << error;
}

// One light record per emissive triangle and instance was 1.4 GB for 5.6
// KB of glTF; now a mesh's triangles are lights once and each instance is
// one, and the file is still charged for them before any instance is made.
TEST(GltfHostile, EmissiveLightsAreBudgeted) {
  TempDir dir("tandem_hostile");
  const fs::path file = dir.path() / "glow.gltf";
  write_text(file, instanced_gltf("lamp", 100, true));
  GltfOptions options;
  options.limits.max_emissive_lights = 100;
  const std::string error = load_error(file, options);
  EXPECT_EQ(error.rfind(file.string() + ": node 0 EXT_mesh_gpu_instancing (100 instances of mesh "
                                        "'glow' with 1 emissive triangles) needs 101 more lights",
                        0),
            0u)
      << error;
  EXPECT_NE(error.find("limit of 100"), std::string::npos) << error;
  options.limits.max_emissive_lights = 101;
  EXPECT_EQ(load_error(file, options), "");
  // Not emissive: nothing is charged.
  write_text(file, instanced_gltf("lamp", 100, false));
  options.limits.max_emissive_lights = 0;
  EXPECT_EQ(load_error(file, options), "");
}

// A PNG of `width` x `height` 16-bit RGB pixels (value `value` each),
// written with stored (uncompressed) deflate blocks.
void write_png16(const fs::path& path, uint32_t width, uint32_t height, uint16_t value) {
  auto be32 = [](std::string& out, uint32_t v) {
    for (int k = 3; k >= 0; --k)
      out.push_back(char(v >> (8 * k)));
  };
  auto crc = [](const std::string& bytes) {
    uint32_t c = 0xffffffffu;
    for (unsigned char b : bytes) {
      c ^= b;
      for (int k = 0; k < 8; ++k)
        c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return ~c;
  };
  auto chunk = [&](std::string& out, const char* type, const std::string& data) {
    be32(out, uint32_t(data.size()));
    const std::string body = type + data;
    out += body;
    be32(out, crc(body));
  };
  std::string raw;
  for (uint32_t y = 0; y < height; ++y) {
    raw.push_back(0);  // filter: none
    for (uint32_t i = 0; i < width * 3; ++i) {
      raw.push_back(char(value >> 8));
      raw.push_back(char(value & 0xff));
    }
  }
  std::string z = "\x78\x01";
  for (size_t at = 0; at < raw.size() || at == 0;) {
    const size_t n = std::min<size_t>(65535, raw.size() - at);
    z.push_back(at + n == raw.size() ? 1 : 0);
    z.push_back(char(n & 0xff));
    z.push_back(char(n >> 8));
    z.push_back(char(~n & 0xff));
    z.push_back(char((~n >> 8) & 0xff));
    z += raw.substr(at, n);
    at += n;
  }
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  be32(z, (b << 16) | a);
  std::string header;
  be32(header, width);
  be32(header, height);
  header += std::string("\x10\x02\x00\x00\x00", 5);  // 16 bits, RGB
  std::string png = "\x89PNG\r\n\x1a\n";
  chunk(png, "IHDR", header);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", "");
  write_text(path, png);
}

// A 16-bit 8192x8192 PNG of 522 KB peaked at 1.03 GB while the texel
// budget charged it 256 MB: decoding is now held to a limit of its own,
// at its decoded size.
TEST(GltfHostile, SixteenBitTexturesAreDecodedAndChargedAtTheirDecodedSize) {
  TempDir dir("tandem_hostile");
  write_png16(dir.path() / "deep.png", 16, 8, 0x8080);
  const fs::path file = dir.path() / "deep.gltf";
  write_text(file, textured_gltf({"deep.png"}));
  const Scene scene = load_gltf(file);
  ASSERT_EQ(scene.textures().size(), 1u);
  const Texture& t = scene.textures()[0];
  ASSERT_EQ(t.rgba8.size(), 16u * 8u);
  EXPECT_EQ(t.rgba8[0], 0xff808080u);  // 0x8080 -> 0x80, alpha 255
  GltfOptions options;
  options.limits.max_image_decode_bytes = 16 * 8 * 12 - 1;  // stb's rows and image: 12 B/pixel
  GltfSummary summary;
  testing::internal::CaptureStderr();
  load_gltf(file, options, &summary);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(summary.images_unavailable, 1u);
  EXPECT_NE(log.find("image 0 (\"deep.png\") is unavailable: its 16x8 pixels, 3 channels of 16 "
                     "bits need 1.5 KiB while decoding, over this loader's limit of 1.5 KiB per "
                     "image"),
            std::string::npos)
      << log;
}

// Values the schema forbids, which tinygltf reads as absent (a negative
// byteOffset rendered as if it were 0): refused naming the object and field.
TEST(GltfHostile, SchemaRangesAreCheckedOnTheJsonText) {
  TempDir dir("tandem_hostile");
  test::GltfTestFile f;
  const int pos = f.vec3(test::kTriangle);
  const std::string good =
      f.file(R"("meshes":[{"primitives":[{"attributes":{"POSITION":)" + std::to_string(pos) +
             R"(},"mode":4}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0,)"
             R"("samplers":[{"magFilter":9729}],"extras":{"byteOffset":-1,"index":"x"})");
  const fs::path file = dir.path() / "schema.gltf";
  write_text(file, good);
  EXPECT_EQ(load_error(file), "");  // extras are the application's, not checked
  const struct {
    std::string from, to, message;
  } cases[] = {
      {R"("byteOffset": 0)", R"("byteOffset": -4)",
       "bufferViews[0].byteOffset is -4; the glTF schema requires an integer >= 0"},
      {R"("count": 3)", R"("count": 1.5)",
       "accessors[0].count is 1.5; the glTF schema requires an integer >= 1"},
      {R"("componentType": 5126)", R"("componentType": 5124)",
       "accessors[0].componentType is 5124; the glTF schema requires one of 5120, 5121, 5122, "
       "5123, 5125, 5126"},
      {R"("mode":4)", R"("mode":9)",
       "meshes[0].primitives[0].mode is 9; the glTF schema requires an integer in 0..6"},
      {R"("magFilter":9729)", R"("magFilter":1)", "samplers[0].magFilter is 1"},
      {R"("mesh":0)", R"("mesh":"0")",
       "nodes[0].mesh is \"0\"; the glTF schema requires an integer >= 0"},
      {R"("scene":0)", R"("scene":-1)", "scene is -1"},
      {R"("type": "VEC3")", R"("type": "VEC9")", "accessors[0].type is \"VEC9\""},
      {R"("byteLength": 36})", R"("byteLength": 36, "byteStride": 2})",
       "bufferViews[0].byteStride is 2; the glTF schema requires an integer in 4..252"},
  };
  for (const auto& c : cases) {
    const size_t at = good.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    write_text(file, std::string(good).replace(at, c.from.size(), c.to));
    const std::string error = load_error(file);
    EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << error;
    EXPECT_NE(error.find(c.message), std::string::npos) << c.to << ": " << error;
  }
}

}  // namespace
}  // namespace tandem
