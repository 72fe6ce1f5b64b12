// The small scene the API tests render, built through <tandem/tandem.h> only.
#pragma once

#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace tandem_api_test {

// A unit quad in the xz-plane facing +y, `half` wide each way, at height y.
struct Quad {
  float positions[12];
  float normals[12];
  float uvs[8] = {0, 0, 1, 0, 1, 1, 0, 1};
  uint32_t indices[6] = {0, 2, 1, 0, 3, 2};
  explicit Quad(float half, float y = 0.0f, float ny = 1.0f)
      : positions{-half, y, -half, half, y, -half, half, y, half, -half, y, half},
        normals{0, ny, 0, 0, ny, 0, 0, ny, 0, 0, ny, 0} {}
  tandem::MeshData data() const {
    tandem::MeshData d;
    d.positions = positions;
    d.normals = normals;
    d.uvs = uvs;
    d.vertex_count = 4;
    d.indices = indices;
    d.triangle_count = 2;
    return d;
  }
};

inline tandem::RendererOptions small_options() {
  tandem::RendererOptions o;
  o.backend = tandem::BackendChoice::kCpu;
  o.width = 48;
  o.height = 32;
  o.samples_per_frame = 2;
  o.max_depth = 3;
  o.seed = 7;
  return o;
}

// The scene's point light above the origin and its camera looking at it
// from above and in front.
inline void add_light_and_camera(tandem::Renderer& r) {
  tandem::LightDesc light;
  light.position[1] = 4.0f;
  light.intensity = 30.0f;
  r.add_light(light);
  tandem::CameraDesc cam;
  cam.position[0] = 0, cam.position[1] = 3, cam.position[2] = 5;
  r.set_camera(cam);
}

// A floor, a small red square above it and a light: the square's instance is
// returned so tests can move it. Without `place_square` its mesh is added
// but no instance of it (the id returned is then meaningless).
inline tandem::InstanceId build_scene(tandem::Renderer& r, bool place_square = true) {
  const Quad floor(4.0f);
  const Quad block(0.5f);
  tandem::MaterialDesc grey;
  tandem::MaterialDesc red;
  red.base_color[0] = 0.9f, red.base_color[1] = 0.1f, red.base_color[2] = 0.1f;
  const tandem::MaterialId g = r.add_material(grey);
  const tandem::MaterialId rd = r.add_material(red);
  const tandem::MeshId floor_mesh = r.add_mesh(floor.data(), g);
  const tandem::MeshId block_mesh = r.add_mesh(block.data(), rd);
  r.add_instance(floor_mesh, tandem::Transform::identity());
  const tandem::InstanceId moving =
      place_square ? r.add_instance(block_mesh, tandem::Transform::translation(-1.0f, 0.5f, 0.0f))
                   : tandem::InstanceId{};
  add_light_and_camera(r);
  return moving;
}

// A glTF file of one triangle (positions inline as base64 of 9 floats),
// with `top` ("key": value, ...) added to the file's object and `node` to
// its one node's.
inline void write_triangle_gltf(const std::filesystem::path& file, const std::string& top,
                                const std::string& node) {
  std::ofstream(file) << R"({"asset":{"version":"2.0"},)" << top
                      << R"("buffers":[{"byteLength":36,"uri":)"
                         R"("data:application/octet-stream;base64,)"
                         R"(AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],)"
                         R"("bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{)"
                         R"("bufferView":0,"componentType":5126,"type":"VEC3","count":3,)"
                         R"("min":[0,0,0],"max":[1,1,0]}],"meshes":[{"primitives":[{)"
                         R"("attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0)"
                      << node << R"(}],"scenes":[{"nodes":[0]}]})";
}

// Runs `f`, which must throw a tandem::Error of `kind`; returns its message.
template <class F>
std::string error_of(tandem::Error::Kind kind, F&& f) {
  try {
    f();
  } catch (const tandem::Error& e) {
    EXPECT_EQ(int(e.kind()), int(kind)) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no tandem::Error was thrown";
  return "";
}

inline double mean(const std::vector<float>& v) {
  double s = 0.0;
  for (float x : v)
    s += x;
  return v.empty() ? 0.0 : s / double(v.size());
}

}  // namespace tandem_api_test
