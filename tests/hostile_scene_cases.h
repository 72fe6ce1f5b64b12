// glTF scenes of kinds real files contain that a float renderer cannot take
// as they stand: nodes scaled to 0 (how an animation hides an object),
// values whose products overflow float, cameras and lights beyond its
// range, radiance that is infinite as a float. Shared by the loader's tests
// (scenes_hostile_test.cpp: the message) and the command line's
// (app_hostile_scenes_test.cpp: every backend, exit status, a finite
// image), so both hold the same cases.
#pragma once

#include <string>
#include <vector>

#include "tests/scenes_gltf_test_file.h"

namespace tandem::test {

struct HostileScene {
  std::string name;  // also the file's stem
  std::string json;
  // Empty: the file loads and renders (what cannot be drawn is not). Else
  // what the refusal must say, after "<file>: ".
  std::vector<std::string> refusal;
};

// Two triangles: node 0 (changed by `node0`, JSON members) and node 1, a
// plain triangle at x = 2; `members` adds top-level members, `primitive`
// members of the primitive, and `material` (JSON of one) gives it that
// material.
inline std::string two_triangle_file(GltfTestFile& f, const std::string& node0,
                                     const std::string& members = "",
                                     const std::string& primitive = "",
                                     const std::string& material = "") {
  const int pos = f.vec3(kTriangle);
  return f.file(
      R"("meshes":[{"name":"tri","primitives":[{"attributes":{"POSITION":)" + std::to_string(pos) +
      "}" + (material.empty() ? "" : R"(,"material":0)") + primitive + "}]}]" +
      (material.empty() ? "" : R"(,"materials":[)" + material + "]") +
      R"(,"nodes":[{"name":"first","mesh":0)" + (node0.empty() ? "" : "," + node0) +
      R"(},{"name":"second","mesh":0,"translation":[2,0,0]}],"scenes":[{"nodes":[0,1]}])" +
      (members.empty() ? "" : "," + members));
}

inline std::vector<HostileScene> hostile_scenes() {
  std::vector<HostileScene> cases;
  auto add = [&](const std::string& name, const std::string& json,
                 std::vector<std::string> refusal = {}) {
    cases.push_back({name, json, std::move(refusal)});
  };
  {
    GltfTestFile f;
    add("scale_zero", two_triangle_file(f, R"("scale":[0,0,0])"));
  }
  {
    GltfTestFile f;
    add("scale_tiny", two_triangle_file(f, R"("scale":[1e-12,1e-12,1e-12])"));
  }
  {
    GltfTestFile f;
    add("flattened", two_triangle_file(f, R"("scale":[1,1,0])"));
  }
  {
    GltfTestFile f;
    add("node_far_away", two_triangle_file(f, R"("translation":[1e20,0,0])"),
        {"node 0 ('first') with mesh 0 ('tri') lies beyond 1e+09 of the origin"});
  }
  {
    GltfTestFile f;
    add("scale_1e30", two_triangle_file(f, R"("scale":[1e30,1e30,1e30])"),
        {"node 0 ('first')", "lies beyond 1e+09"});
  }
  {
    // Each scale is finite; their product (1e60) is not, as a float.
    GltfTestFile f;
    const int pos = f.vec3(kTriangle);
    add("scale_product_overflows",
        f.file(R"("meshes":[{"primitives":[{"attributes":{"POSITION":)" + std::to_string(pos) +
               R"(}}]}],"nodes":[{"name":"big","scale":[1e30,1e30,1e30],"children":[1]},)" +
               R"({"name":"bigger","mesh":0,"scale":[1e30,1e30,1e30]}],"scenes":[{"nodes":[0]}])"),
        {"node 1 ('bigger') has a world transform that is not finite"});
  }
  {
    // Morph deltas of 3e38 times a weight of 2: infinite positions.
    GltfTestFile f;
    const int pos = f.vec3(kTriangle);
    const int delta = f.vec3({3e38f, 0, 0, 3e38f, 0, 0, 0, 0, 0});
    add("morph_overflows",
        f.file(
            R"("meshes":[{"name":"blob","weights":[2],"primitives":[{"attributes":{"POSITION":)" +
            std::to_string(pos) + R"(},"targets":[{"POSITION":)" + std::to_string(delta) +
            R"(}]}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}])"),
        {"mesh 0 ('blob')", "not finite"});
  }
  {
    // An inverse bind matrix of 3e38: the skinned rest pose leaves float.
    GltfTestFile f;
    const int pos = f.vec3({1, 1, 0, 2, 1, 0, 1, 2, 0});
    const int joints = f.add(std::vector<uint8_t>(12, 0), 5121, "VEC4", 3);
    const int weights =
        f.add(std::vector<float>{1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, 5126, "VEC4", 3);
    std::vector<float> ibm = {3e38f, 0, 0, 0, 0, 3e38f, 0, 0, 0, 0, 1, 0, 3e38f, 0, 0, 1};
    const int bind = f.add(ibm, 5126, "MAT4", 1);
    add("skin_overflows",
        f.file(R"("meshes":[{"name":"skinned","primitives":[{"attributes":{"POSITION":)" +
               std::to_string(pos) + R"(,"JOINTS_0":)" + std::to_string(joints) +
               R"(,"WEIGHTS_0":)" + std::to_string(weights) +
               R"(}}]}],"skins":[{"joints":[1],"inverseBindMatrices":)" + std::to_string(bind) +
               R"(}],"nodes":[{"name":"body","mesh":0,"skin":0},{"name":"joint"}],)" +
               R"("scenes":[{"nodes":[0,1]}])"),
        {"node 0 ('body') with mesh 0 ('skinned')"});
  }
  // A triangle (node 0) and node 1 holding `node` (a camera, a light),
  // with `members` at the top level.
  auto triangle_and_node = [](const std::string& members, const std::string& node) {
    GltfTestFile f;
    const int pos = f.vec3(kTriangle);
    return f.file(members + R"("meshes":[{"primitives":[{"attributes":{"POSITION":)" +
                  std::to_string(pos) + R"(}}]}],"nodes":[{"mesh":0},{)" + node +
                  R"(}],"scenes":[{"nodes":[0,1]}])");
  };
  add("ortho_camera_1e300",
      triangle_and_node(R"("cameras":[{"type":"orthographic","orthographic":)"
                        R"({"xmag":1e300,"ymag":1e300,"znear":0.1,"zfar":100}}],)",
                        R"("camera":0,"translation":[0,0,5])"),
      {"the camera cannot be rendered: its orthographic half height"});
  add("camera_far_away",
      triangle_and_node(
          R"("cameras":[{"type":"perspective","perspective":{"yfov":0.8,"znear":0.1}}],)",
          R"("camera":0,"translation":[0,0,5e18])"),
      {"the camera cannot be rendered: its position", "lies beyond 1e+09"});
  auto light_file = [&](const std::string& light, const std::string& placement) {
    return triangle_and_node(
        R"("extensionsUsed":["KHR_lights_punctual"],"extensions":{"KHR_lights_punctual":)"
        R"({"lights":[)" +
            light + "]}},",
        R"("extensions":{"KHR_lights_punctual":{"light":0}},)" + placement);
  };
  add("light_1e300",
      light_file(R"({"name":"sun","type":"point","intensity":1e300})", R"("translation":[0,0,2])"),
      {"light 0 ('sun') has an intensity of inf", "beyond the largest radiance"});
  add("light_far_away",
      light_file(R"({"name":"lamp","type":"point","intensity":10})", R"("translation":[0,0,1e20])"),
      {"light 0 ('lamp') is placed at", "not a finite point within 1e+09"});
  {
    GltfTestFile f;
    add("emission_1e300",
        two_triangle_file(f, "", R"("extensionsUsed":["KHR_materials_emissive_strength"])", "",
                          R"({"name":"glow","emissiveFactor":[1,1,1],"extensions":)"
                          R"({"KHR_materials_emissive_strength":{"emissiveStrength":1e300}}})"),
        {"material 0 ('glow') emits inf", "beyond the largest radiance"});
  }
  return cases;
}

// A triangle (node 0) whose scale a STEP animation sets to 0 at t = 1 s and
// back to 1 at t = 2 s, and whose translation (with `far_at_2`) another
// channel takes to x = 1e20 from t = 2 s to 3 s; the animation lasts 3 s and
// loops. Node 1 stays.
inline std::string animated_hiding_file(bool far_at_2) {
  GltfTestFile f;
  const int pos = f.vec3(kTriangle);
  const int times =
      f.accessor(R"({"bufferView":)" + std::to_string(f.view(std::vector<float>{0, 1, 2, 3})) +
                 R"(,"componentType":5126,"type":"SCALAR","count":4,"min":[0],"max":[3]})");
  const int scales = f.add(std::vector<float>{1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 1, 1}, 5126, "VEC3", 4);
  const int moves =
      f.add(std::vector<float>{0, 0, 0, 0, 0, 0, 1e20f, 0, 0, 0, 0, 0}, 5126, "VEC3", 4);
  return f.file(
      R"("meshes":[{"name":"tri","primitives":[{"attributes":{"POSITION":)" + std::to_string(pos) +
      R"(}}]}],"nodes":[{"name":"blinking","mesh":0},{"mesh":0,"translation":[2,0,0]}],)"
      R"("scenes":[{"nodes":[0,1]}],"animations":[{"samplers":[)"
      R"({"input":)" +
      std::to_string(times) + R"(,"output":)" + std::to_string(scales) +
      R"(,"interpolation":"STEP"},{"input":)" + std::to_string(times) + R"(,"output":)" +
      std::to_string(moves) +
      R"(,"interpolation":"STEP"}],"channels":[)"
      R"({"sampler":0,"target":{"node":0,"path":"scale"}})" +
      (far_at_2 ? R"(,{"sampler":1,"target":{"node":0,"path":"translation"}})" : "") + "]}]");
}

// A triangle (node 0, mesh 'blob') with a morph target of deltas 1e38
// whose weight a STEP animation sets to 10 from t = 1 s to 2 s (positions
// of 1e39: infinite as floats) and back to 0; the animation lasts 2 s and
// loops. Node 1 stays.
inline std::string animated_morph_overflow_file() {
  GltfTestFile f;
  const int pos = f.vec3(kTriangle);
  const int delta = f.vec3({1e38f, 0, 0, 1e38f, 0, 0, 0, 0, 0});
  const int times =
      f.accessor(R"({"bufferView":)" + std::to_string(f.view(std::vector<float>{0, 1, 2})) +
                 R"(,"componentType":5126,"type":"SCALAR","count":3,"min":[0],"max":[2]})");
  const int weights = f.add(std::vector<float>{0, 10, 0}, 5126, "SCALAR", 3);
  return f.file(R"("meshes":[{"name":"blob","weights":[0],"primitives":[{"attributes":)"
                R"({"POSITION":)" +
                std::to_string(pos) + R"(},"targets":[{"POSITION":)" + std::to_string(delta) +
                R"(}]}]}],"nodes":[{"name":"morpher","mesh":0},{"mesh":0,"translation":[2,0,0]}],)"
                R"("scenes":[{"nodes":[0,1]}],"animations":[{"samplers":[{"input":)" +
                std::to_string(times) + R"(,"output":)" + std::to_string(weights) +
                R"(,"interpolation":"STEP"}],"channels":[{"sampler":0,"target":)"
                R"({"node":0,"path":"weights"}}]}])");
}

}  // namespace tandem::test
