// End to end: tandem-view under Xvfb renders the arena along its scripted
// path and writes screenshots that show a lit, moving scene.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdio>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "core/image/image.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

bool have_xvfb_run() {
  return std::system("command -v xvfb-run > /dev/null 2>&1") == 0;
}

// Under the sanitizer build, leaks are checked in the windowed run too:
// what D-Bus, Mesa and X11 keep until exit is suppressed by library name
// (kept mapped by a preloaded no-op dlclose so that it has one), so any
// report left is Tandem's own.
std::string leak_check_environment() {
  std::string env = "LSAN_OPTIONS=\"${LSAN_OPTIONS}:suppressions=" TANDEM_SOURCE_DIR
                    "/tests/lsan_system_libraries.supp\" ";
#ifdef TANDEM_LSAN_KEEP_MODULES
  env += "LD_PRELOAD='" TANDEM_LSAN_KEEP_MODULES
         "' ASAN_OPTIONS=\"${ASAN_OPTIONS}:verify_asan_link_order=0\" ";
#endif
  return env;
}

// Runs the viewer for `frames` frames; returns its exit status.
int run_view(uint32_t frames, const fs::path& out) {
  const std::string cmd =
      leak_check_environment() + "xvfb-run -a -s '-screen 0 640x480x24' '" + TANDEM_VIEW_BINARY +
      "' --frames " + std::to_string(frames) + " --screenshot '" + out.string() +
      "' --width 160 --height 120 --backend cpu > '" + out.string() + ".log' 2>&1";
  return std::system(cmd.c_str());
}

TEST(ViewXvfb, ScriptedRunWritesALitImageThatChangesAsObjectsMove) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built (SDL2/OpenGL/ImGui missing at configure time)";
#else
  if (!have_xvfb_run()) GTEST_SKIP() << "xvfb-run is not installed (./setup.sh installs xvfb)";
  const fs::path dir =
      fs::temp_directory_path() / ("tandem_view_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path a = dir / "a.png", b = dir / "b.png";
  ASSERT_EQ(run_view(4, a), 0) << "see " << a.string() << ".log";
  ASSERT_EQ(run_view(12, b), 0) << "see " << b.string() << ".log";
  const ImageRGB ia = read_image(a), ib = read_image(b);
  ASSERT_EQ(ia.width, 160u);
  ASSERT_EQ(ia.height, 120u);
  ASSERT_EQ(ib.width, 160u);
  double mean = 0.0, lo = 1e9, hi = -1e9, diff = 0.0;
  for (size_t i = 0; i < ia.rgb.size(); ++i) {
    mean += ia.rgb[i];
    lo = std::min(lo, double(ia.rgb[i]));
    hi = std::max(hi, double(ia.rgb[i]));
    diff += std::abs(double(ia.rgb[i]) - ib.rgb[i]);
  }
  mean /= double(ia.rgb.size());
  diff /= double(ia.rgb.size());
  EXPECT_GT(mean, 0.02) << "image is black";
  EXPECT_GT(hi - lo, 0.3) << "image is uniform: no objects visible";
  EXPECT_GT(diff, 0.005) << "frames 4 and 12 are the same: nothing moved";
  fs::remove_all(dir);
#endif
}

}  // namespace
}  // namespace tandem
