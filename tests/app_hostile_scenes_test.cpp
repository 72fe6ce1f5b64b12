// Scenes with values a float renderer cannot take (hostile_scene_cases.h)
// from a user's seat: `tandem render` on every backend CI can run (cpu,
// host, and cuda on the simulated device where CUDA is built) and `tandem
// info`. Each run exits 0 with a finite image, or 1 with a message naming
// the file; none ends by a signal (Embree's assertions used to abort), and
// no NaN or Inf reaches a film or a printed bound.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "app_run_tandem.h"
#include "core/image/image.h"
#include "tests/hostile_scene_cases.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem;
using app_test::run_tandem_with_env;
using app_test::shell_quote;

struct BackendRun {
  const char* env;
  const char* backend;
};

std::vector<BackendRun> backends() {
  std::vector<BackendRun> b = {{"", "cpu"}, {"", "host"}};
  if (TANDEM_BUILT_WITH_CUDA) b.push_back({"TANDEM_DEVICE=sim", "cuda"});
  return b;
}

bool all_finite(const ImageRGB& image) {
  for (float v : image.rgb)
    if (!std::isfinite(v)) return false;
  return true;
}

bool mentions_non_finite(const std::string& text) {
  for (const char* word : {"nan", "NaN", "inf ", "inf,", "inf)", "Inf"})
    if (text.find(word) != std::string::npos) return true;
  return false;
}

TEST(CliHostileScenes, EveryBackendRendersOrRefusesByNameAndNeverAborts) {
  TempDir dir("tandem_hostile_scenes");
  for (const test::HostileScene& c : test::hostile_scenes()) {
    const fs::path file = dir.path() / (c.name + ".gltf");
    std::ofstream(file) << c.json;
    const std::string scene = shell_quote(file.string());
    const auto info = run_tandem("info " + scene);
    if (!c.refusal.empty()) {
      EXPECT_EQ(info.exit_code, 1) << c.name << ": " << info.output;
      EXPECT_NE(info.output.find(file.string() + ": "), std::string::npos) << info.output;
      for (const std::string& part : c.refusal)
        EXPECT_NE(info.output.find(part), std::string::npos) << c.name << ": " << info.output;
      const auto render = run_tandem("render " + scene + " --width 8 --height 8 --spp 1 --output " +
                                     shell_quote((dir.path() / "never.pfm").string()));
      EXPECT_EQ(render.exit_code, 1) << c.name << ": " << render.output;
      EXPECT_FALSE(fs::exists(dir.path() / "never.pfm"));
      continue;
    }
    EXPECT_EQ(info.exit_code, 0) << c.name << ": " << info.output;
    EXPECT_NE(info.output.find("instances:  2 (1 not drawn"), std::string::npos) << info.output;
    EXPECT_FALSE(mentions_non_finite(info.output)) << c.name << ": " << info.output;
    for (const BackendRun& b : backends()) {
      const fs::path out = dir.path() / (c.name + "_" + b.backend + ".pfm");
      const auto r = run_tandem_with_env(
          b.env, "render " + scene + " --width 24 --height 16 --spp 2 --env-color 1 --backend " +
                     b.backend + " --output " + shell_quote(out.string()));
      ASSERT_EQ(r.exit_code, 0) << c.name << " on " << b.backend << ": " << r.output;
      const ImageRGB image = read_image(out);
      EXPECT_TRUE(all_finite(image)) << c.name << " on " << b.backend;
    }
  }
}

// A STEP animation scales a node to 0 at 1 s and back at 2 s, and (second
// file) moves it to x = 1e20 from 2 s to 3 s: every frame renders (0..4,
// the loop included); while hidden or
// out of range the node is simply not drawn, the out-of-range frame with
// a warning naming the file and the node.
TEST(CliHostileScenes, AnimationsPlayThroughHiddenAndOutOfRangeFrames) {
  TempDir dir("tandem_hostile_scenes");
  struct Case {
    std::string name, json, warning;  // warning: "" for none expected
  };
  const Case cases[] = {
      {"blink", test::animated_hiding_file(false), ""},
      {"far", test::animated_hiding_file(true),
       "far.gltf: instance 0 ('blinking') of mesh 0 ('tri') lies beyond 1e+09"},
      {"morph", test::animated_morph_overflow_file(),
       "morph.gltf: instance 0 ('morpher') of mesh 0 ('blob') has positions that are not finite"},
  };
  for (const Case& c : cases) {
    const fs::path file = dir.path() / (c.name + ".gltf");
    std::ofstream(file) << c.json;
    const fs::path pattern = dir.path() / (c.name + "_##.pfm");
    for (const BackendRun& b : backends()) {
      const auto r = run_tandem_with_env(
          b.env, "render " + shell_quote(file.string()) +
                     " --frames 0..4 --fps 1 --width 16 --height 12 --spp 1 --env-color 1 "
                     "--backend " +
                     b.backend + " --output " + shell_quote(pattern.string()));
      ASSERT_EQ(r.exit_code, 0) << c.name << " on " << b.backend << ": " << r.output;
      for (int frame = 0; frame <= 4; ++frame) {
        const fs::path out = dir.path() / (c.name + "_0" + std::to_string(frame) + ".pfm");
        ASSERT_TRUE(fs::exists(out)) << out;
        EXPECT_TRUE(all_finite(read_image(out))) << out;
      }
      if (!c.warning.empty()) {
        EXPECT_NE(r.output.find(c.warning), std::string::npos) << b.backend << ": " << r.output;
      }
    }
  }
}

}  // namespace
}  // namespace tandem
