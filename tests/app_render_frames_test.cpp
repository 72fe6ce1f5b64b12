// `tandem render --frame/--frames/--fps`: animation frames of a glTF file's
// node animation, each the single-frame render of its time, written through
// a frame-number pattern.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/image/image.h"
#include "tests/app_run_tandem.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem;
using app_test::shell_quote;

// A textured cube rotating about its centre (a node animation); without
// lights of its own it is rendered under a white sky.
const std::string kCube =
    (fs::path(TANDEM_SHARED_DIR) / "scenes/gltf/AnimatedCube/glTF/AnimatedCube.gltf").string();
const std::string kRender = "render " + shell_quote(kCube) +
                            " --width 40 --height 30 --spp 4 --max-depth 2 --backend cpu "
                            "--threads 2 --env-color 1 --quiet ";

double mean_abs_diff(const ImageRGB& a, const ImageRGB& b) {
  EXPECT_EQ(a.rgb.size(), b.rgb.size());
  double d = 0.0;
  for (size_t i = 0; i < a.rgb.size() && i < b.rgb.size(); ++i)
    d += std::abs(double(a.rgb[i]) - double(b.rgb[i]));
  return d / double(std::max<size_t>(a.rgb.size(), 1));
}

TEST(AppRenderFrames, EachFrameIsTheStillRenderOfItsTime) {
  TempDir dir("tandem_render_frames");
  const std::string pattern = (dir.path() / "box_####.pfm").string();
  // At 4 fps frames 1 and 2 are a quarter of a second of rotation apart.
  const std::string fps = "--fps 4 ";
  const auto seq = run_tandem(kRender + fps + "--frames 1..2 --output " + shell_quote(pattern));
  ASSERT_EQ(seq.exit_code, 0) << seq.output;
  ASSERT_TRUE(fs::exists(dir.path() / "box_0001.pfm")) << seq.output;
  ASSERT_TRUE(fs::exists(dir.path() / "box_0002.pfm")) << seq.output;
  const fs::path single = dir.path() / "single_2.pfm";
  const auto one = run_tandem(kRender + fps + "--frame 2 --output " + shell_quote(single.string()));
  ASSERT_EQ(one.exit_code, 0) << one.output;
  const fs::path again = dir.path() / "again_2.pfm";
  ASSERT_EQ(
      run_tandem(kRender + fps + "--frame 2 --output " + shell_quote(again.string())).exit_code, 0);
  const ImageRGB f1 = read_image(dir.path() / "box_0001.pfm");
  const ImageRGB f2 = read_image(dir.path() / "box_0002.pfm");
  const ImageRGB s2 = read_image(single), a2 = read_image(again);
  // The same frame twice: the same image, bit for bit.
  EXPECT_EQ(s2.rgb, a2.rgb);
  // Frame 2 of a sequence (posed while frame 1 rendered, committed as a
  // delta) is the still render of t = 0.5 s.
  EXPECT_EQ(f2.rgb, s2.rgb) << "mean difference " << mean_abs_diff(f2, s2);
  // Different frames show the cube turned.
  EXPECT_GT(mean_abs_diff(f1, f2), 1e-2);
}

TEST(AppRenderFrames, TheDefaultRateIs24FpsAndShortPatternsGrow) {
  TempDir dir("tandem_render_frames_fps");
  // Frame 12 at the default 24 fps is t = 0.5 s: frame 2 at 4 fps.
  const std::string pattern = (dir.path() / "f_#.pfm").string();
  const auto r = run_tandem(kRender + "--frames 11..12 --output " + shell_quote(pattern));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_TRUE(fs::exists(dir.path() / "f_12.pfm")) << "a number longer than its pattern";
  const fs::path at4 = dir.path() / "at4.pfm";
  ASSERT_EQ(
      run_tandem(kRender + "--fps 4 --frame 2 --output " + shell_quote(at4.string())).exit_code, 0);
  EXPECT_EQ(read_image(dir.path() / "f_12.pfm").rgb, read_image(at4).rgb);
  EXPECT_GT(mean_abs_diff(read_image(dir.path() / "f_11.pfm"), read_image(at4)), 1e-3);
}

TEST(AppRenderFrames, BadFrameOptionsAreUsageErrors) {
  TempDir dir("tandem_render_frames_usage");
  const std::string out = shell_quote((dir.path() / "out.png").string());
  const std::string base = "render builtin:cornell --width 8 --height 8 --spp 1 --quiet ";
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"--frames 1..3 --output " + out, "frame-number pattern"},
      {"--frame 1 --frames 1..2 --output " + out, "not both"},
      {"--frames 3..1 --output " + out, "ends before it starts"},
      {"--frames 1-3 --output " + out, "range A..B"},
      {"--frame -1 --output " + out, "frame numbers"},
      {"--frame 1 --fps 0 --output " + out, "--fps"},
      {"--fps 30 --output " + out, "--fps needs"},
  };
  for (const Case& c : cases) {
    const auto r = run_tandem(base + c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
  EXPECT_FALSE(fs::exists(dir.path() / "out.png"));
}

TEST(AppRenderFrames, AStaticSceneRendersEveryFrameAndSaysSo) {
  TempDir dir("tandem_render_frames_static");
  const std::string pattern = (dir.path() / "c_###.png").string();
  const auto r = run_tandem(
      "render builtin:cornell --width 16 --height 16 --spp 2 --max-depth 2 --backend cpu "
      "--frames 7..8 --output " +
      shell_quote(pattern));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("no animation"), std::string::npos) << r.output;
  const ImageRGB a = read_image(dir.path() / "c_007.png");
  const ImageRGB b = read_image(dir.path() / "c_008.png");
  EXPECT_EQ(a.rgb, b.rgb);
}

}  // namespace
}  // namespace tandem
