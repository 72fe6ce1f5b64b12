// Tandem as an installed library, the way an application meets it:
// `cmake --install` of this build into a fresh prefix, then examples/embed
// configured against that prefix alone with find_package(Tandem) (a
// separate CMake project, same generator and compiler), built, run, and its
// PNGs checked: the right size, not black, and the box it moves between
// frames really moves in the image.
//
// Release suite only: an ASan build's libraries need the sanitizer runtime
// in every program that links them, which an application's plain
// find_package build does not add (see tests/CMakeLists.txt).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/image/image.h"
#include "test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'')
      out += "'\\''";
    else
      out += c;
  }
  return out + "'";
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class InstallPackage : public ::testing::Test {
 protected:
  // The install and the example's build take a while: once for all tests.
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("tandem_install_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    prefix_ = root_ / "prefix";
    example_build_ = root_ / "embed-build";
    const std::string cmake = quoted(TANDEM_CMAKE_COMMAND);
    if (!run(cmake + " --install " + quoted(TANDEM_BUILD_DIR) + " --prefix " +
             quoted(prefix_.string()))) {
      setup_error_ = "cmake --install failed";
      return;
    }
    std::string configure =
        cmake + " -S " + quoted(TANDEM_EXAMPLE_DIR) + " -B " + quoted(example_build_.string()) +
        " -G " + quoted(TANDEM_CMAKE_GENERATOR) +
        " -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=" + quoted(prefix_.string()) +
        " -DCMAKE_CXX_COMPILER=" + quoted(TANDEM_CXX_COMPILER);
    if (std::string(TANDEM_MAKE_PROGRAM).size())
      configure += " -DCMAKE_MAKE_PROGRAM=" + quoted(TANDEM_MAKE_PROGRAM);
    if (std::string(TANDEM_CXX_LAUNCHER).size())
      configure += " -DCMAKE_CXX_COMPILER_LAUNCHER=" + quoted(TANDEM_CXX_LAUNCHER);
    // Only the prefix may provide Tandem: not a package registry entry.
    configure += " -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF";
    if (!run(configure)) {
      setup_error_ = "configuring examples/embed against the installed prefix failed";
      return;
    }
    if (!run(cmake + " --build " + quoted(example_build_.string()))) {
      setup_error_ = "building examples/embed failed";
      return;
    }
  }

  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << setup_error_ << "; log:\n" << log_;
  }

  // Runs `command` with its output appended to the log; true on exit 0.
  static bool run(const std::string& command) {
    const fs::path out = root_ / "command.log";
    const int rc = std::system((command + " > " + quoted(out.string()) + " 2>&1").c_str());
    log_ += "$ " + command + "\n" + read_text(out);
    return rc == 0;
  }

  // Runs the installed example; the image it wrote, linear.
  static ImageRGB render_example(const std::string& name, const std::string& args) {
    const fs::path png = root_ / (name + ".png");
    EXPECT_TRUE(run(quoted((example_build_ / "embed").string()) + " --output " +
                    quoted(png.string()) + " " + args))
        << log_;
    EXPECT_TRUE(fs::exists(png)) << log_;
    return fs::exists(png) ? read_image(png) : ImageRGB{};
  }

  static fs::path root_, prefix_, example_build_;
  static std::string setup_error_, log_;
};

fs::path InstallPackage::root_, InstallPackage::prefix_, InstallPackage::example_build_;
std::string InstallPackage::setup_error_, InstallPackage::log_;

// How much more orange (red minus blue) the left half of the image is than
// the right half: where the example's orange box stands.
double orange_left_minus_right(const ImageRGB& img) {
  double left = 0.0, right = 0.0;
  for (uint32_t y = 0; y < img.height; ++y) {
    for (uint32_t x = 0; x < img.width; ++x) {
      const float* p = img.pixel(x, y);
      (x < img.width / 2 ? left : right) += double(p[0]) - double(p[2]);
    }
  }
  return (left - right) / (double(img.width) * img.height * 0.5);
}

// One test, not several: ctest runs each test in its own process, and the
// install and the example's build are the expensive part.
TEST_F(InstallPackage, AnApplicationBuildsAgainstThePrefixAndRendersThroughTheApi) {
  for (const char* f :
       {"bin/tandem", "include/tandem/tandem.h", "lib/libtandem.a",
        "lib/cmake/Tandem/TandemConfig.cmake", "lib/cmake/Tandem/TandemConfigVersion.cmake",
        "lib/cmake/Tandem/TandemTargets.cmake"}) {
    EXPECT_TRUE(fs::exists(prefix_ / f)) << f;
  }
#ifdef TANDEM_INSTALLS_VIEW
  EXPECT_TRUE(fs::exists(prefix_ / "bin/tandem-view"));
#endif
  // One public header, which includes only the standard library: an
  // application needs no engine, glm, Embree or TBB header.
  size_t headers = 0;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(prefix_ / "include")) {
    if (e.is_regular_file()) ++headers;
  }
  EXPECT_EQ(headers, 1u);
  std::istringstream header(read_text(prefix_ / "include/tandem/tandem.h"));
  for (std::string line; std::getline(header, line);) {
    if (line.rfind("#include", 0) != 0) continue;
    EXPECT_EQ(line.find('"'), std::string::npos) << line;
    EXPECT_EQ(line.find(".h"), std::string::npos) << line;  // <cstdint>, not <glm/glm.hpp>
  }
  // Nothing exported points back into the source or build tree.
  for (const fs::directory_entry& e : fs::directory_iterator(prefix_ / "lib/cmake/Tandem")) {
    const std::string text = read_text(e.path());
    EXPECT_EQ(text.find(TANDEM_SOURCE_DIR), std::string::npos) << e.path();
    EXPECT_EQ(text.find(TANDEM_BUILD_DIR), std::string::npos) << e.path();
  }
  EXPECT_TRUE(run(quoted((prefix_ / "bin/tandem").string()) + " --help")) << log_;

  // The example: the box starts left of the centre (x = -1) and, with
  // --frames 4, slides to x = +0.5.
  const std::string common = "--width 64 --height 48 --spp 2 --still-frames 1 --backend cpu";
  const ImageRGB start = render_example("start", common + " --frames 1");
  const ImageRGB moved = render_example("moved", common + " --frames 4");
  ASSERT_EQ(start.width, 64u);
  ASSERT_EQ(start.height, 48u);
  ASSERT_EQ(moved.width, 64u);
  ASSERT_EQ(moved.height, 48u);
  double mean = 0.0, bright = 0.0;
  for (float v : start.rgb) {
    mean += v;
    bright = std::max(bright, double(v));
  }
  mean /= double(start.rgb.size());
  EXPECT_GT(mean, 0.02) << "the example's image is black";
  EXPECT_GT(bright, 0.2);
  const double before = orange_left_minus_right(start), after = orange_left_minus_right(moved);
  EXPECT_GT(before, 0.005) << "the box is not left of the centre at the start";
  EXPECT_LT(after, before - 0.5 * std::fabs(before))
      << "moving the box did not move it in the image (" << before << " -> " << after << ")";

  // Bad usage and bad input are exit codes, not crashes.
  const std::string embed = quoted((example_build_ / "embed").string());
  EXPECT_EQ(std::system((embed + " --width x > /dev/null 2>&1").c_str()) >> 8, 2);
  EXPECT_EQ(std::system((embed + " --width 0 --output " + quoted((root_ / "z.png").string()) +
                         " > /dev/null 2>&1")
                            .c_str()) >>
                8,
            1);

#ifdef TANDEM_INSTALLS_VIEW
  // The interactive example (SDL2 is there when the viewer is), on SDL's
  // dummy video driver: the denoised frames it shows, the last written.
  const fs::path window = example_build_ / "embed_window";
  ASSERT_TRUE(fs::exists(window)) << log_;
  const fs::path shot = root_ / "window.png";
  const std::string run_window = "SDL_VIDEODRIVER=dummy " + quoted(window.string());
  EXPECT_TRUE(run(run_window + " --width 96 --height 54 --backend cpu --frames 6 --screenshot " +
                  quoted(shot.string())))
      << log_;
  ASSERT_TRUE(fs::exists(shot)) << log_;
  const ImageRGB shown = read_image(shot);
  ASSERT_EQ(shown.width, 96u);
  ASSERT_EQ(shown.height, 54u);
  double sum = 0.0, orange = 0.0;
  for (size_t i = 0; i < shown.rgb.size(); i += 3) {
    sum += shown.rgb[i] + shown.rgb[i + 1] + shown.rgb[i + 2];
    orange = std::max(orange, double(shown.rgb[i]) - double(shown.rgb[i + 2]));
  }
  EXPECT_GT(sum / double(shown.rgb.size()), 0.05) << "the window's frame is dark";
  EXPECT_GT(orange, 0.2) << "no orange box in the window's frame";
  EXPECT_EQ(std::system((run_window + " --screenshot x.png > /dev/null 2>&1").c_str()) >> 8, 2);
#endif
}

}  // namespace
}  // namespace tandem
