// Removing objects through the API and an edited scene against the same
// scene from a file: a game that adds, moves, retextures and removes
// objects over many frames must end with the image of a scene that held
// only what is left, bit for bit for the same seed; ids of removed objects
// are refused, never taken for another object.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "api_test_scene.h"
#include "scenes_gltf_test_file.h"
#include "test_temp_dir.h"

namespace {

using tandem::Error;
using namespace tandem_api_test;

// --- a PNG without compression (stored deflate blocks), for the file -------

uint32_t crc32(const uint8_t* p, size_t n, uint32_t crc = 0) {
  crc = ~crc;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k)
      crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

void put32(std::vector<uint8_t>& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8)
    out.push_back(uint8_t(v >> s));
}

void chunk(std::vector<uint8_t>& png, const char* type, const std::vector<uint8_t>& data) {
  put32(png, uint32_t(data.size()));
  std::vector<uint8_t> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  png.insert(png.end(), body.begin(), body.end());
  put32(png, crc32(body.data(), body.size()));
}

// An 8-bit RGB PNG of `rgba`'s colour channels (alpha must be 255).
std::vector<uint8_t> png_rgb8(uint32_t w, uint32_t h, const std::vector<uint8_t>& rgba) {
  std::vector<uint8_t> raw;
  for (uint32_t y = 0; y < h; ++y) {
    raw.push_back(0);  // filter: none
    for (uint32_t x = 0; x < w; ++x)
      raw.insert(raw.end(), &rgba[(y * w + x) * 4], &rgba[(y * w + x) * 4] + 3);
  }
  std::vector<uint8_t> z = {0x78, 0x01};
  for (size_t at = 0; at < raw.size(); at += 65535) {
    const uint16_t n = uint16_t(std::min<size_t>(65535, raw.size() - at));
    z.push_back(at + n == raw.size() ? 1 : 0);  // final block?, stored
    z.insert(z.end(), {uint8_t(n), uint8_t(n >> 8), uint8_t(~n), uint8_t(uint16_t(~n) >> 8)});
    z.insert(z.end(), raw.begin() + long(at), raw.begin() + long(at + n));
  }
  uint32_t a = 1, b = 0;
  for (uint8_t v : raw)
    a = (a + v) % 65521, b = (b + a) % 65521;
  put32(z, b << 16 | a);
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> ihdr;
  put32(ihdr, w);
  put32(ihdr, h);
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, no filter, no interlace
  chunk(png, "IHDR", ihdr);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", {});
  return png;
}

std::vector<uint8_t> checker(uint8_t r0, uint8_t g0, uint8_t b0, uint8_t r1, uint8_t g1,
                             uint8_t b1) {
  std::vector<uint8_t> px(4 * 4 * 4);
  for (uint32_t i = 0; i < 16; ++i) {
    const bool odd = (i % 4 + i / 4) % 2;
    px[4 * i] = odd ? r1 : r0, px[4 * i + 1] = odd ? g1 : g0, px[4 * i + 2] = odd ? b1 : b0;
    px[4 * i + 3] = 255;
  }
  return px;
}

// --- the scene both ways -----------------------------------------------------

// A small triangle standing on the floor (the mesh added and moved late).
struct Triangle {
  float positions[9];
  float normals[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  uint32_t indices[3] = {0, 1, 2};
  explicit Triangle(float dx) : positions{-0.5f + dx, 0, 0.5f, 0.5f + dx, 0, 0.5f, dx, 1, 0.5f} {}
  tandem::MeshData data() const {
    tandem::MeshData d;
    d.positions = positions;
    d.normals = normals;
    d.vertex_count = 3;
    d.indices = indices;
    d.triangle_count = 1;
    return d;
  }
};

tandem::CameraDesc camera() {
  tandem::CameraDesc cam;
  cam.position[0] = 0, cam.position[1] = 3, cam.position[2] = 5;
  return cam;
}

tandem::LightDesc warm_light() {
  tandem::LightDesc l;
  l.position[0] = 1, l.position[1] = 3, l.position[2] = 1;
  l.color[0] = 1, l.color[1] = 0.75f, l.color[2] = 0.5f;
  l.intensity = 20;
  return l;
}

const std::vector<uint8_t> kCheckerA = checker(255, 255, 255, 200, 0, 0);
const std::vector<uint8_t> kCheckerB = checker(0, 64, 255, 255, 224, 0);

std::string json_floats(const float* v, int n) {
  std::string s = "[";
  for (int i = 0; i < n; ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", double(v[i]));
    s += (i ? "," : "") + std::string(buf);
  }
  return s + "]";
}

// What the edits below leave, as a glTF file: the floor textured with
// checker B, the block at (1, 0.25, -1), the triangle moved by +0.5 in x,
// the warm light; no camera (set through the API on both sides).
void write_final_scene(const std::filesystem::path& file) {
  tandem::test::GltfTestFile d;
  const Quad floor(4.0f), block(0.5f);
  const Triangle tri(0.5f);
  auto floats = [](const float* p, size_t n) { return std::vector<float>(p, p + n); };
  auto add_mesh = [&](const float* pos, const float* nrm, const float* uv, size_t verts,
                      const uint32_t* idx, size_t tris) {
    std::string a = R"("POSITION": )" + std::to_string(d.vec3(floats(pos, verts * 3))) +
                    R"(, "NORMAL": )" + std::to_string(d.vec3(floats(nrm, verts * 3)));
    if (uv) {
      a +=
          R"(, "TEXCOORD_0": )" + std::to_string(d.add(floats(uv, verts * 2), 5126, "VEC2", verts));
    }
    const int indices = d.add(std::vector<uint32_t>(idx, idx + tris * 3), 5125, "SCALAR", tris * 3);
    return "{" + a + "}, \"indices\": " + std::to_string(indices);
  };
  const std::string floor_prim =
      add_mesh(floor.positions, floor.normals, floor.uvs, 4, floor.indices, 2);
  const std::string block_prim =
      add_mesh(block.positions, block.normals, block.uvs, 4, block.indices, 2);
  const std::string tri_prim = add_mesh(tri.positions, tri.normals, nullptr, 3, tri.indices, 1);
  const std::vector<uint8_t> png = png_rgb8(4, 4, kCheckerB);
  const int image_view = d.view(std::vector<unsigned char>(png.begin(), png.end()));
  const tandem::LightDesc l = warm_light();
  const tandem::Transform at = tandem::Transform::translation(1.0f, 0.25f, -1.0f);
  const std::string members = R"("images": [{"bufferView": )" + std::to_string(image_view) +
                              R"(, "mimeType": "image/png"}], "textures": [{"source": 0}],
      "materials": [
        {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0,
         "roughnessFactor": 0.5, "baseColorTexture": {"index": 0}}},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.1, 0.1, 1], "metallicFactor": 0,
         "roughnessFactor": 0.5}},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.7, 0.3, 1], "metallicFactor": 0,
         "roughnessFactor": 0.5}}],
      "meshes": [{"primitives": [{"attributes": )" +
                              floor_prim + R"(, "material": 0}]},
                 {"primitives": [{"attributes": )" +
                              block_prim + R"(, "material": 1}]},
                 {"primitives": [{"attributes": )" +
                              tri_prim + R"(, "material": 2}]}],
      "extensionsUsed": ["KHR_lights_punctual"],
      "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "color": )" +
                              json_floats(l.color, 3) + R"(, "intensity": 20}]}},
      "nodes": [{"mesh": 0}, {"mesh": 1, "matrix": )" +
                              json_floats(at.m, 16) + R"(}, {"mesh": 2},
                {"translation": )" +
                              json_floats(l.position, 3) +
                              R"(, "extensions": {"KHR_lights_punctual": {"light": 0}}}],
      "scenes": [{"nodes": [0, 1, 2, 3]}])";
  std::ofstream(file) << d.file(members);
}

TEST(ApiSceneEdits, AnEditedSceneRendersAsTheSameSceneLoadedFromAFile) {
  tandem::RendererOptions o = small_options();
  tandem::Renderer a(o);
  a.use_default_sky();
  a.set_camera(camera());
  auto texture = [&](const std::vector<uint8_t>& px) {
    tandem::TextureDesc t;
    t.width = t.height = 4;
    t.rgba8 = px.data();
    return a.add_texture(t);
  };
  const tandem::TextureId tex_a = texture(kCheckerA), tex_b = texture(kCheckerB);
  tandem::MaterialDesc floor_mat, red, green;
  floor_mat.base_color_texture = tex_a;
  red.base_color[0] = 0.9f, red.base_color[1] = 0.1f, red.base_color[2] = 0.1f;
  green.base_color[0] = 0.2f, green.base_color[1] = 0.7f, green.base_color[2] = 0.3f;
  const tandem::MaterialId floor_id = a.add_material(floor_mat);
  const tandem::MaterialId red_id = a.add_material(red), green_id = a.add_material(green);
  const Quad floor(4.0f), block(0.5f);
  a.add_instance(a.add_mesh(floor.data(), floor_id), tandem::Transform::identity());
  const tandem::MeshId block_mesh = a.add_mesh(block.data(), red_id);
  const tandem::InstanceId first =
      a.add_instance(block_mesh, tandem::Transform::translation(-1.0f, 0.5f, 0.0f));
  tandem::LightDesc white;
  white.position[1] = 4.0f;
  white.intensity = 30.0f;
  const tandem::LightId white_id = a.add_light(white);
  a.render_frame();
  a.render_frame();

  // Frame by frame: move, retexture, add, remove, swap the light, and a
  // mesh added and removed in the middle of the mesh list.
  a.set_instance_transform(first, tandem::Transform::translation(0.5f, 0.75f, 0.25f));
  a.render_frame();
  floor_mat.base_color_texture = tex_b;
  a.set_material(floor_id, floor_mat);
  a.render_frame();
  const tandem::InstanceId second =
      a.add_instance(block_mesh, tandem::Transform::translation(1.0f, 0.25f, -1.0f));
  a.render_frame();
  a.remove_instance(first);
  a.render_frame();
  const tandem::InstanceId respawned =
      a.add_instance(block_mesh, tandem::Transform::translation(-2.0f, 1.0f, 0.0f));
  a.begin_frame();  // edits while a frame renders reach the next one
  a.remove_instance(respawned);
  a.add_light(warm_light());
  a.remove_light(white_id);
  a.end_frame();
  const Triangle left(-1.5f), tri(0.0f), moved(0.5f);
  const tandem::MeshId doomed = a.add_mesh(left.data(), green_id);
  const tandem::MeshId kept = a.add_mesh(tri.data(), green_id);
  const tandem::InstanceId doomed_instance = a.add_instance(doomed, tandem::Transform::identity());
  a.add_instance(kept, tandem::Transform::identity());
  a.render_frame();
  a.remove_instance(doomed_instance);
  a.remove_mesh(doomed);
  a.set_mesh_vertices(kept, moved.data());  // its slot moved down; the id holds
  for (int f = 0; f < 3; ++f)
    a.render_frame();
  EXPECT_EQ(a.instance_count(), 3u);
  EXPECT_EQ(a.mesh_count(), 3u);
  EXPECT_EQ(a.light_count(), 1u);
  EXPECT_EQ(second.index, 2u);

  const tandem::TempDir dir("tandem_api_edits");
  const std::filesystem::path file = dir.path() / "final.gltf";
  write_final_scene(file);
  tandem::Renderer b(o);  // default_sky: the same built-in sky as use_default_sky()
  b.load_gltf(file.string());
  b.set_camera(camera());
  for (int f = 0; f < 3; ++f)
    b.render_frame();
  const std::vector<float> edited = a.image_linear(), loaded = b.image_linear();
  ASSERT_EQ(edited.size(), loaded.size());
  size_t differ = 0;
  for (size_t i = 0; i < edited.size(); ++i)
    differ += edited[i] != loaded[i];
  EXPECT_EQ(differ, 0u) << "of " << edited.size() << " values; means " << mean(edited) << " vs "
                        << mean(loaded);
  EXPECT_GT(mean(edited), 0.01);
}

TEST(ApiSceneEdits, RemovedIdsAreRefusedAndNeverHandedOutAgain) {
  tandem::Renderer r(small_options());
  const tandem::InstanceId block = build_scene(r);
  const tandem::MeshId block_mesh{1};
  r.remove_instance(block);
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { r.remove_instance(block); })
                .find("instance 1 was removed"),
            std::string::npos);
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.set_instance_transform(block, tandem::Transform::identity()); });
  // The next instance of the mesh takes the slot, not the id.
  const tandem::InstanceId again = r.add_instance(block_mesh, tandem::Transform::identity());
  EXPECT_EQ(again.index, 2u);
  error_of(Error::Kind::kInvalidArgument, [&] { r.remove_instance(block); });
  EXPECT_EQ(r.instance_count(), 2u);
  // A mesh with instances stays; without, it goes, and its id with it.
  EXPECT_NE(error_of(Error::Kind::kInvalidState, [&] { r.remove_mesh(block_mesh); })
                .find("still has 1 instance"),
            std::string::npos);
  r.remove_instance(again);
  r.remove_mesh(block_mesh);
  EXPECT_EQ(r.mesh_count(), 1u);
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.add_instance(block_mesh, tandem::Transform::identity()); });
  error_of(Error::Kind::kInvalidArgument, [&] { r.remove_mesh(tandem::MeshId{7}); });
  const tandem::LightId light{0};
  r.remove_light(light);
  EXPECT_EQ(r.light_count(), 0u);
  error_of(Error::Kind::kInvalidArgument, [&] { r.set_light(light, tandem::LightDesc{}); });
  error_of(Error::Kind::kInvalidArgument, [&] { r.remove_light(light); });
  r.render_frame();  // the floor alone, unlit: renders, black
  EXPECT_EQ(mean(r.image_linear()), 0.0);
  // Removing the last instance leaves nothing to render.
  r.remove_instance(tandem::InstanceId{0});
  error_of(Error::Kind::kInvalidState, [&] { r.render_frame(); });
}

// A game that spawns and despawns objects every frame: the image after
// many rounds is that of the objects alive (each round's cost, a TLAS
// update, is world_removal_test's).
TEST(ApiSceneEdits, SpawningAndDespawningEveryFrameLeavesTheObjectsAlive) {
  tandem::RendererOptions o = small_options();
  tandem::Renderer r(o);
  const tandem::InstanceId block = build_scene(r);
  r.remove_instance(block);
  const tandem::MeshId block_mesh{1};
  r.render_frame();
  for (int round = 0; round < 50; ++round) {
    const tandem::InstanceId a =
        r.add_instance(block_mesh, tandem::Transform::translation(0.05f * float(round), 0.5f, 0));
    const tandem::InstanceId b =
        r.add_instance(block_mesh, tandem::Transform::translation(-1.0f, 0.5f, 0));
    r.remove_instance(a);
    if (round < 49) r.remove_instance(b);
    r.render_frame();
  }
  EXPECT_EQ(r.instance_count(), 2u);
  tandem::Renderer fresh(o);
  build_scene(fresh);  // the block at (-1, 0.5, 0), as left above
  r.reset_accumulation();
  r.render_frame();
  fresh.render_frame();
  EXPECT_EQ(r.image_linear(), fresh.image_linear());
}

}  // namespace
