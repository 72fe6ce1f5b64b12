// `tandem export SCENE --output FILE.gltf`: the file loads back as the same
// scene (meshes, materials, instances, punctual lights, camera), so another
// renderer can draw what Tandem draws; bad use is refused before anything
// is written.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "scenes/builtin_scenes.h"
#include "scenes/gltf_loader.h"
#include "tests/app_run_tandem.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem;
using app_test::RunResult;
using app_test::shell_quote;

void expect_near_vec(const glm::vec3& a, const glm::vec3& b, float tol, const std::string& what) {
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(a[k], b[k], tol) << what << " [" << k << "]";
}

TEST(Export, TheManyLightSceneLoadsBackAsItself) {
  TempDir dir("tandem_export");
  const fs::path out = dir.path() / "many.gltf";
  const RunResult r =
      run_tandem("export builtin:many-lights --output " + shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Scene a = make_builtin_scene("many-lights");
  const Scene b = load_gltf(out);
  ASSERT_EQ(b.instances().size(), a.instances().size());
  ASSERT_EQ(b.lights().size(), a.lights().size());
  EXPECT_EQ(b.triangle_count_instanced(), a.triangle_count_instanced());
  EXPECT_EQ(b.triangle_count_unique(), a.triangle_count_unique());
  for (size_t i = 0; i < a.instances().size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      expect_near_vec(glm::vec3(b.instances()[i].transform[c]),
                      glm::vec3(a.instances()[i].transform[c]), 1e-6f,
                      "instance " + std::to_string(i));
    }
  }
  for (size_t i = 0; i < a.lights().size(); ++i) {
    const Light &la = a.lights()[i], &lb = b.lights()[i];
    EXPECT_EQ(lb.type, la.type) << i;
    EXPECT_FLOAT_EQ(lb.intensity, la.intensity) << i;
    expect_near_vec(lb.color, la.color, 1e-6f, "light colour");
    expect_near_vec(lb.position, la.position, 1e-5f, "light position");
    if (la.type == LightType::kSpot) {
      expect_near_vec(lb.direction, la.direction, 1e-5f, "spot direction");
      EXPECT_FLOAT_EQ(lb.outer_cone_angle, la.outer_cone_angle) << i;
      EXPECT_FLOAT_EQ(lb.inner_cone_angle, la.inner_cone_angle) << i;
    }
  }
  // Emission above 1 goes through KHR_materials_emissive_strength.
  ASSERT_EQ(b.materials().size(), a.materials().size());
  for (size_t i = 0; i < a.materials().size(); ++i) {
    const Material &ma = a.materials()[i], &mb = b.materials()[i];
    expect_near_vec(mb.emissive * mb.emissive_strength, ma.emissive * ma.emissive_strength, 1e-4f,
                    "emission of " + ma.name);
    expect_near_vec(glm::vec3(mb.base_color), glm::vec3(ma.base_color), 1e-6f, ma.name);
    EXPECT_FLOAT_EQ(mb.roughness, ma.roughness) << ma.name;
    EXPECT_FLOAT_EQ(mb.metallic, ma.metallic) << ma.name;
    EXPECT_EQ(mb.double_sided, ma.double_sided) << ma.name;
  }
  ASSERT_TRUE(b.has_camera());
  expect_near_vec(b.camera().position, a.camera().position, 1e-5f, "camera position");
  expect_near_vec(b.camera().forward, a.camera().forward, 1e-5f, "camera forward");
  EXPECT_NEAR(b.camera().yfov, a.camera().yfov, 1e-6f);
}

TEST(Export, BadUseWritesNothing) {
  TempDir dir("tandem_export");
  const fs::path out = dir.path() / "x.gltf";
  EXPECT_EQ(run_tandem("export builtin:cornell").exit_code, 2);  // no --output
  EXPECT_EQ(
      run_tandem("export builtin:cornell --output " + shell_quote((dir.path() / "x.png").string()))
          .exit_code,
      2);
  const RunResult missing =
      run_tandem("export /nonexistent.gltf --output " + shell_quote(out.string()));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("/nonexistent.gltf"), std::string::npos) << missing.output;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace tandem
