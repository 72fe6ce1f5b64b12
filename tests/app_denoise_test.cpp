// `tandem render --denoise / --aov DIR` and `tandem bench --denoise-quality`
// end to end: the files they write, the JSON keys, and bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/image/image.h"
#include "tests/app_run_tandem.h"
#include "tests/json_test_parser.h"
#include "tests/test_temp_dir.h"

namespace fs = std::filesystem;
using tandem::TempDir;
using tandem::app_test::run_tandem;
using tandem::app_test::RunResult;
using tandem::app_test::shell_quote;

namespace {

TEST(DenoiseCli, RenderWritesTheDenoisedImageAndTheFeatureBuffers) {
  TempDir dir("tandem_denoise_cli");
  const fs::path out = dir.path() / "clean.exr", aov = dir.path() / "aov";
  const RunResult r = run_tandem(
      "render builtin:cornell --backend cpu --width 40 --height 30 --spp 4 --quiet "
      "--denoise --aov " +
      shell_quote(aov.string()) + " --output " + shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const tandem::ImageRGB img = tandem::read_image(out);
  EXPECT_EQ(img.width, 40u);
  for (const char* name : {"albedo.exr", "normal.exr", "depth.exr", "motion.exr", "ids.exr"}) {
    const tandem::ImageRGB f = tandem::read_image(aov / name);
    EXPECT_EQ(f.width, 40u) << name;
    EXPECT_EQ(f.height, 30u) << name;
  }
  // The box fills the view: the centre pixel hits something at positive depth.
  const tandem::ImageRGB depth = tandem::read_image(aov / "depth.exr");
  EXPECT_GT(depth.pixel(20, 15)[0], 0.0f);
  const tandem::ImageRGB ids = tandem::read_image(aov / "ids.exr");
  EXPECT_GE(ids.pixel(20, 15)[0], 0.0f);
}

TEST(DenoiseCli, AovDirectoryThatIsAFileIsAnErrorBeforeRendering) {
  TempDir dir("tandem_denoise_cli");
  const fs::path file = dir.path() / "not_a_dir";
  std::ofstream(file) << "x";
  const RunResult r =
      run_tandem("render builtin:cornell --spp 1 --quiet --aov " + shell_quote(file.string()) +
                 " --output " + shell_quote((dir.path() / "o.png").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("not_a_dir"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.path() / "o.png"));
}

TEST(DenoiseCli, QualityBenchWritesOneObjectPerMeasuredFrame) {
  TempDir dir("tandem_denoise_cli");
  const fs::path json = dir.path() / "q.json";
  const RunResult r = run_tandem(
      "bench builtin:cornell --denoise-quality --width 64 --height 48 --path-frames 4 "
      "--reference-spp 64 --json " +
      shell_quote(json.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(json);
  std::stringstream text;
  text << in.rdbuf();
  const tandem::json_test::Node n = tandem::json_test::parse(text.str());
  ASSERT_EQ(n.items.size(), 3u);
  for (const tandem::json_test::Node& f : n.items) {
    for (const char* key : {"frame", "raw1_relmse", "raw8_relmse", "denoised_relmse", "filter_ms",
                            "render_1spp_ms"}) {
      EXPECT_GE(f[key].number, 0.0) << key;
    }
    EXPECT_GT(f["raw1_relmse"].number, f["raw8_relmse"].number);
    // The camera moves along the path: the history must still help.
    EXPECT_LT(f["denoised_relmse"].number, f["raw1_relmse"].number);
  }
}

}  // namespace
