// Without a display tandem-view must say so and exit 1, not fall back to a
// window nobody sees and render into it forever.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

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

}  // namespace
}  // namespace tandem
