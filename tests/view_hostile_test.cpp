// tandem-view refuses a screenshot it could not write, or would write in
// the wrong format, before it renders anything.
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
// Exit status of a headless scripted run with `screenshot`; output in `log`.
int run_headless(const std::string& screenshot, const fs::path& log) {
  const std::string cmd = std::string("'") + TANDEM_VIEW_BINARY +
                          "' --no-window --frames 400000 --width 64 --height 48 --backend cpu "
                          "--screenshot '" +
                          screenshot + "' > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string text(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
#endif

TEST(ViewHostile, ScreenshotNameAndFolderAreCheckedFirst) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  TempDir dir("tandem_view_hostile");
  const fs::path log = dir.path() / "log";
  // 400000 frames would take hours: each of these must fail at once.
  EXPECT_EQ(run_headless((dir.path() / "shot.jpg").string(), log), 2);
  EXPECT_NE(text(log).find("must end in .png"), std::string::npos) << text(log);
  EXPECT_EQ(run_headless((dir.path() / "missing" / "shot.png").string(), log), 1);
  EXPECT_NE(text(log).find("does not exist"), std::string::npos) << text(log);
  EXPECT_EQ(run_headless(dir.path().string() + "/", log), 2);
#endif
}

}  // namespace
}  // namespace tandem
