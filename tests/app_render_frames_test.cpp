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
      {"--frames 1..9..0 --output " + out, "step must be 1 or more"},
      {"--frames 1..9..x --output " + out, "frame numbers"},
      {"--frames all --output " + out, "every frame of the animation"},
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

const std::string kBoxAnimated =
    (fs::path(TANDEM_SHARED_DIR) / "scenes/gltf/BoxAnimated/glTF/BoxAnimated.gltf").string();

TEST(AppRenderFrames, StepsAllAndFramesPastTheEnd) {
  TempDir dir("tandem_render_frames_step");
  const std::string base = "render " + shell_quote(kBoxAnimated) +
                           " --width 8 --height 6 --spp 1 --max-depth 1 --backend cpu "
                           "--env-color 1 --fps 2 ";
  // Every 3rd frame of 1..8: 1, 4, 7 (8 is not on the step).
  const auto stepped = run_tandem(base + "--frames 1..8..3 --output " +
                                  shell_quote((dir.path() / "s_#.pfm").string()));
  ASSERT_EQ(stepped.exit_code, 0) << stepped.output;
  for (const char* f : {"s_1.pfm", "s_4.pfm", "s_7.pfm"})
    EXPECT_TRUE(fs::exists(dir.path() / f)) << f;
  for (const char* f : {"s_2.pfm", "s_8.pfm"})
    EXPECT_FALSE(fs::exists(dir.path() / f)) << f;
  // The animation lasts 3.708 s: at 2 fps `all` is frames 0..7, and
  // frames from 8 on (t = 4 s) say once that the animation loops.
  EXPECT_EQ(stepped.output.find("past the end"), std::string::npos) << stepped.output;
  const auto all = run_tandem(base + "--frames all --quiet --output " +
                              shell_quote((dir.path() / "a_#.pfm").string()));
  ASSERT_EQ(all.exit_code, 0) << all.output;
  for (int f = 0; f <= 7; ++f)
    EXPECT_TRUE(fs::exists(dir.path() / ("a_" + std::to_string(f) + ".pfm"))) << f;
  EXPECT_FALSE(fs::exists(dir.path() / "a_8.pfm"));
  const auto past =
      run_tandem(base + "--frames 6..9 --output " + shell_quote((dir.path() / "p_#.pfm").string()));
  ASSERT_EQ(past.exit_code, 0) << past.output;
  EXPECT_NE(past.output.find("frames 8..9 are past the end of the animation (3.708 s long: its "
                             "last frame at 2 fps is 7); it loops"),
            std::string::npos)
      << past.output;
  // A frame past the end is the frame one loop earlier (t - 3.708 s).
  EXPECT_EQ(read_image(dir.path() / "p_8.pfm").rgb.size(), 8u * 6 * 3);
}

// BoxAnimated lifts one box well above the other: the automatic camera
// frames the whole animation, so no frame cuts it off. Against a white sky
// every frame's border is sky, and the boxes are in every picture.
TEST(AppRenderFrames, TheAutomaticCameraFramesTheWholeAnimation) {
  TempDir dir("tandem_render_frames_framing");
  const std::string pattern = (dir.path() / "f_##.pfm").string();
  const auto r = run_tandem("render " + shell_quote(kBoxAnimated) +
                            " --width 48 --height 36 --spp 1 --max-depth 1 --backend cpu "
                            "--env-color 1 --quiet --frames 0..80..10 --output " +
                            shell_quote(pattern));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (uint32_t f = 0; f <= 80; f += 10) {
    const ImageRGB img =
        read_image(dir.path() / ((f < 10 ? "f_0" : "f_") + std::to_string(f) + ".pfm"));
    size_t object = 0, border_object = 0;
    for (uint32_t y = 0; y < img.height; ++y) {
      for (uint32_t x = 0; x < img.width; ++x) {
        const bool sky = img.pixel(x, y)[0] == 1.0f && img.pixel(x, y)[2] == 1.0f;
        object += !sky;
        const bool border = x == 0 || y == 0 || x + 1 == img.width || y + 1 == img.height;
        border_object += border && !sky;
      }
    }
    EXPECT_GT(object, 40u) << "frame " << f;
    EXPECT_EQ(border_object, 0u) << "frame " << f << ": the animation leaves the picture";
  }
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
