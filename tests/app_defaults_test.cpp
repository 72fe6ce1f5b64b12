// The default environment: one rule in every command (render, bench in both
// modes, tandem-view), a sky embedded into the binary, and the README's
// example runnable from a fresh clone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "app/scene_setup.h"
#include "core/image/image.h"
#include "tests/app_run_tandem.h"
#include "tests/test_temp_dir.h"

namespace fs = std::filesystem;
using tandem::TempDir;
using tandem::app_test::run_tandem;
using tandem::app_test::run_tandem_in;
using tandem::app_test::RunResult;
using tandem::app_test::shell_quote;

namespace {

const fs::path kGltf = fs::path(TANDEM_SHARED_DIR) / "scenes" / "gltf";
const fs::path kBox = kGltf / "Box" / "glTF" / "Box.gltf";
const fs::path kSpheres =
    kGltf / "MetalRoughSpheresNoTextures" / "glTF" / "MetalRoughSpheresNoTextures.gltf";
const char kNotice[] = "with the built-in sky";

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1))
    ++n;
  return n;
}

double mean(const tandem::ImageRGB& img) {
  double sum = 0.0;
  for (float v : img.rgb)
    sum += v;
  return img.rgb.empty() ? 0.0 : sum / double(img.rgb.size());
}

// Runs `tandem ARGS` with the working directory `cwd` (not the build or
// source tree: the sky must come from the binary itself).
RunResult run_in(const fs::path& cwd, const std::string& args) {
  return run_tandem_in(cwd, args);
}

TEST(DefaultEnvironment, EmbeddedSkyIsTheShippedFileAndLooksLikeASky) {
  const tandem::ImageRGB sky = tandem::default_environment_image();
  const tandem::ImageRGB file =
      tandem::read_image(fs::path(TANDEM_SOURCE_DIR) / "data" / "env" / "sky.hdr");
  ASSERT_EQ(sky.width, file.width);
  ASSERT_EQ(sky.height, file.height);
  EXPECT_EQ(sky.rgb, file.rgb) << "the embedded bytes are not data/env/sky.hdr";
  EXPECT_EQ(sky.width, 2 * sky.height) << "equirectangular";
  EXPECT_LE(fs::file_size(fs::path(TANDEM_SOURCE_DIR) / "data" / "env" / "sky.hdr"), 400u * 1024u);
  // Upper half (sky) brighter than the lower half (ground); a small, much
  // brighter sun for highlights; nothing negative or non-finite.
  double upper = 0.0, lower = 0.0, brightest = 0.0;
  for (uint32_t y = 0; y < sky.height; ++y) {
    for (uint32_t x = 0; x < sky.width; ++x) {
      const float* p = sky.pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(p[c]) && p[c] >= 0.0f);
        (y < sky.height / 2 ? upper : lower) += p[c];
        brightest = std::max(brightest, double(p[c]));
      }
    }
  }
  EXPECT_GT(upper, 1.5 * lower);
  const double average = (upper + lower) / double(sky.rgb.size());
  EXPECT_GT(average, 0.3);
  EXPECT_LT(average, 2.0);
  EXPECT_GT(brightest, 20.0 * average) << "no sun to reflect";
}

TEST(DefaultEnvironment, RuleIsGltfWithoutEnvOrEnvColor) {
  tandem::SceneRequest r;
  r.spec = "model.glb";
  EXPECT_TRUE(tandem::uses_default_environment(r));
  r.environment.intensity = 2.0f;  // scales the default sky, does not replace it
  EXPECT_TRUE(tandem::uses_default_environment(r));
  r.environment.color = glm::vec3(0.0f);
  EXPECT_FALSE(tandem::uses_default_environment(r));
  r.environment.color.reset();
  r.environment.map = "sky.hdr";
  EXPECT_FALSE(tandem::uses_default_environment(r));
  r.environment.map.reset();
  r.default_environment = false;  // tandem info
  EXPECT_FALSE(tandem::uses_default_environment(r));
  r.default_environment = true;
  r.spec = "builtin:cornell";  // built-in scenes keep their own lighting
  EXPECT_FALSE(tandem::uses_default_environment(r));
}

TEST(DefaultEnvironment, RenderOfAGltfFileIsLitAndSaysSoOnce) {
  TempDir dir("tandem_defaults");
  const fs::path out = dir.path() / "box.pfm";
  RunResult r = run_in(dir.path(), "render " + shell_quote(kBox.string()) +
                                       " --width 32 --height 24 --spp 4 --backend cpu --output " +
                                       shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 1u) << r.output;
  EXPECT_NE(r.output.find("--env-color 0"), std::string::npos) << r.output;
  const double lit = mean(tandem::read_image(out));
  EXPECT_GT(lit, 0.1) << "the glTF render is (nearly) black";
  EXPECT_LT(lit, 5.0) << "the glTF render is blown out";

  // --env-color 0 turns it off: no notice, and a scene without lights is black.
  r = run_in(dir.path(), "render " + shell_quote(kBox.string()) +
                             " --width 32 --height 24 --spp 4 --backend cpu --env-color 0 "
                             "--output " +
                             shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 0u) << r.output;
  EXPECT_EQ(mean(tandem::read_image(out)), 0.0);

  // --env-intensity scales the default sky.
  r = run_in(dir.path(), "render " + shell_quote(kBox.string()) +
                             " --width 32 --height 24 --spp 4 --backend cpu --env-intensity 2 "
                             "--output " +
                             shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NEAR(mean(tandem::read_image(out)), 2.0 * lit, 0.02 * lit);
}

TEST(DefaultEnvironment, BuiltinScenesKeepTheirOwnLighting) {
  TempDir dir("tandem_defaults");
  const RunResult r = run_in(dir.path(),
                             "render builtin:cornell --width 8 --height 8 --spp 1 --backend cpu "
                             "--output " +
                                 shell_quote((dir.path() / "c.pfm").string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 0u) << r.output;
}

TEST(DefaultEnvironment, MetalsReflectSomething) {
  TempDir dir("tandem_defaults");
  const fs::path out = dir.path() / "spheres.pfm";
  const RunResult r = run_in(dir.path(), "render " + shell_quote(kSpheres.string()) +
                                             " --width 48 --height 48 --spp 4 --backend cpu "
                                             "--output " +
                                             shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const tandem::ImageRGB img = tandem::read_image(out);
  // The sphere grid fills the middle of the frame: metals there mirror the
  // sky and ground, so it is neither black nor uniform.
  double lo = 1e30, hi = 0.0, sum = 0.0;
  size_t n = 0;
  for (uint32_t y = 16; y < 32; ++y) {
    for (uint32_t x = 16; x < 32; ++x) {
      const float g = img.pixel(x, y)[1];
      lo = std::min(lo, double(g));
      hi = std::max(hi, double(g));
      sum += g;
      ++n;
    }
  }
  EXPECT_GT(sum / double(n), 0.05) << "the metal spheres are black";
  EXPECT_GT(hi - lo, 0.05) << "the metal spheres reflect nothing";
}

TEST(DefaultEnvironment, BenchUsesTheSameRuleInBothModes) {
  TempDir dir("tandem_defaults");
  RunResult r = run_in(dir.path(), "bench " + shell_quote(kBox.string()) +
                                       " --width 16 --height 16 --spp 1 --threads 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 1u) << r.output;
  r = run_in(dir.path(), "bench " + shell_quote(kBox.string()) +
                             " --width 16 --height 16 --spp 1 --threads 1 --env-color 0.5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 0u) << r.output;
  r = run_in(dir.path(), "bench " + shell_quote(kBox.string()) +
                             " --frames 2 --width 16 --height 16 --backend cpu --threads 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 1u) << r.output;
}

// The README's glTF example names the shipped sky by its path in the
// repository, so it runs as written from a fresh clone.
TEST(DefaultEnvironment, ReadmeExampleRunsFromAFreshClone) {
  std::ifstream in(fs::path(TANDEM_SOURCE_DIR) / "README.md");
  const std::string readme((std::istreambuf_iterator<char>(in)), {});
  const std::string example = "--env data/env/sky.hdr";
  ASSERT_NE(readme.find(example), std::string::npos) << "README lost its runnable example";
  EXPECT_EQ(readme.find("--env sky.hdr"), std::string::npos);
  TempDir dir("tandem_defaults");
  const RunResult r =
      run_in(TANDEM_SOURCE_DIR, "render " + shell_quote(kBox.string()) +
                                    " --env data/env/sky.hdr --width 16 --height 12 --spp 1 "
                                    "--backend cpu --tonemap aces --output " +
                                    shell_quote((dir.path() / "model.png").string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, kNotice), 0u) << r.output;
  // The built-in example needs nothing outside the clone (smaller here).
  const std::string builtin = "tandem render builtin:sky-plane --env data/env/sky.hdr";
  ASSERT_NE(readme.find(builtin), std::string::npos);
  const fs::path out = dir.path() / "sky-plane.png";
  const RunResult b = run_in(TANDEM_SOURCE_DIR, builtin.substr(7) +
                                                    " --width 16 --height 12 --spp 1 --backend "
                                                    "cpu --output " +
                                                    shell_quote(out.string()));
  EXPECT_EQ(b.exit_code, 0) << b.output;
  EXPECT_GT(mean(tandem::read_image(out)), 0.1);
}

}  // namespace
