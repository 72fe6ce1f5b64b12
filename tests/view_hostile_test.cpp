// tandem-view refuses a screenshot it could not write, or would write in
// the wrong format, before it renders anything; scenes with values a float
// renderer cannot take (hostile_scene_cases.h) are shown or refused by
// name, never an abort.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/hostile_scene_cases.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

#ifdef TANDEM_VIEW_BINARY
// Exit status of a headless scripted run with `screenshot`; output in `log`.
int run_headless(const std::string& screenshot, const fs::path& log, const std::string& scene = "",
                 int frames = 400000) {
  const std::string cmd = std::string("'") + TANDEM_VIEW_BINARY + "' " +
                          (scene.empty() ? "" : "'" + scene + "' ") + "--no-window --frames " +
                          std::to_string(frames) +
                          " --width 64 --height 48 --backend cpu "
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

TEST(ViewHostile, ScenesBeyondFloatAreShownOrRefusedByName) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  TempDir dir("tandem_view_hostile");
  const fs::path log = dir.path() / "log", shot = dir.path() / "shot.png";
  std::vector<test::HostileScene> cases = test::hostile_scenes();
  cases.push_back({"animated_far", test::animated_hiding_file(true), {}});
  for (const test::HostileScene& c : cases) {
    const fs::path file = dir.path() / (c.name + ".gltf");
    std::ofstream(file) << c.json;
    fs::remove(shot);
    const int status = run_headless(shot.string(), log, file.string(), 3);
    if (c.refusal.empty()) {
      EXPECT_EQ(status, 0) << c.name << ": " << text(log);
      EXPECT_TRUE(fs::exists(shot)) << c.name;
    } else {
      EXPECT_EQ(status, 1) << c.name << ": " << text(log);
      EXPECT_NE(text(log).find(file.string() + ": "), std::string::npos) << text(log);
    }
  }
#endif
}

}  // namespace
}  // namespace tandem
