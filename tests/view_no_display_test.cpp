// Without a display tandem-view must say so and exit 1, not fall back to a
// window nobody sees and render into it forever.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/json_test_parser.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

#ifdef TANDEM_VIEW_BINARY
struct ViewRun {
  int status;  // exit code; 124: killed by the timeout (it hung)
  std::string output;
};

ViewRun run_view(const std::string& env, const fs::path& log) {
  // The timeout turns the old behaviour (rendering invisibly until killed)
  // into a failure instead of a hung test.
  const std::string cmd = "env " + env + " timeout 60 '" + TANDEM_VIEW_BINARY +
                          "' --width 64 --height 48 --backend cpu > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(log);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1,
          std::string(std::istreambuf_iterator<char>(in), {})};
}
#endif

TEST(ViewNoDisplay, WithoutADisplayItExitsOneWithAClearMessage) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  TempDir dir("tandem_view_no_display");
  const ViewRun r =
      run_view("-u DISPLAY -u WAYLAND_DISPLAY -u SDL_VIDEODRIVER", dir.path() / "log");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("no display"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--no-window"), std::string::npos) << "no hint at the headless mode";
#endif
}

TEST(ViewNoDisplay, AnUnavailableVideoDriverExitsOne) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  TempDir dir("tandem_view_no_driver");
  const ViewRun r = run_view("-u DISPLAY SDL_VIDEODRIVER=no-such-driver", dir.path() / "log");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("cannot initialise SDL video"), std::string::npos) << r.output;
#endif
}

// A scripted run without a window writes its figures with --stats: frames
// presented per second, frame times, how long input waited, what was shown.
TEST(ViewNoDisplay, AScriptedRunWritesItsStats) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  TempDir dir("tandem_view_stats");
  const fs::path stats = dir.path() / "stats.json", log = dir.path() / "log";
  std::string cmd = "timeout 120 '";
  cmd += TANDEM_VIEW_BINARY;
  cmd += "' builtin:cornell --no-window --frames 10 --width 64 --height 48 --backend cpu ";
  cmd += "--motion-reference-spp 4 --still-frames 3 ";
  cmd += "--stats '" + stats.string() + "' > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  std::ifstream in(stats);
  const std::string text{std::istreambuf_iterator<char>(in), {}};
  const json_test::Node n = json_test::parse(text);
  EXPECT_EQ(n["tool"].string, "tandem-view");
  EXPECT_EQ(n["frames"].number, 9.0)
      << "the first frame (the scene's build) and the still ones are not counted";
  EXPECT_EQ(n["still_frames"].number, 3.0);
  EXPECT_GT(n["fps"].number, 0.0);
  EXPECT_GT(n["frame_ms_p99"].number, 0.0);
  EXPECT_GT(n["max_input_wait_ms"].number, 0.0);
  EXPECT_LE(n["p99_input_wait_ms"].number, n["max_input_wait_ms"].number);
  EXPECT_EQ(n["shown_width"].number, 64.0) << "still frames are shown at full resolution";
  EXPECT_GT(n["spp_per_frame"].number, 0.0);
  EXPECT_GT(n["motion_relmse"].number, 0.0);
  EXPECT_EQ(n["motion_relmse_frames"].items.size(), 4u);
  // The references would stall a window: only a run without one takes them.
  std::string windowed = "env -u DISPLAY -u WAYLAND_DISPLAY timeout 60 '";
  windowed += TANDEM_VIEW_BINARY;
  windowed +=
      "' builtin:cornell --frames 10 --motion-reference-spp 4 > '" + log.string() + "' 2>&1";
  const int usage = std::system(windowed.c_str());
  EXPECT_TRUE(WIFEXITED(usage) && WEXITSTATUS(usage) == 2);
#endif
}

}  // namespace
}  // namespace tandem
