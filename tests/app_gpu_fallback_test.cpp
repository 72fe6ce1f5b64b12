// The CUDA backend from a user's seat, on the simulated device
// (TANDEM_DEVICE=sim) with injected faults (TANDEM_DEVICE_FAULT): under
// --backend auto and in backend lists a GPU failure gives one warning and the
// run completes with the right image; --backend cuda exits 1 with the
// message; the overlapped frame loop reports what it committed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "app_run_tandem.h"
#include "core/image/image.h"
#include "json_test_parser.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem_with_env;

class GpuFallback : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tandem_gpu_fallback_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string out(const std::string& name) const { return (dir_ / name).string(); }
  static std::string render_args(const std::string& backend, const std::string& output) {
    return "render builtin:cornell --width 48 --height 32 --spp 16 --seed 3 --backend " + backend +
           " --output " + app_test::shell_quote(output);
  }
  fs::path dir_;
};

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1))
    ++n;
  return n;
}

TEST_F(GpuFallback, SimulatedDeviceRendersTheHostBackendsImage) {
  const auto cuda = run_tandem_with_env("TANDEM_DEVICE=sim", render_args("cuda", out("cuda.exr")));
  ASSERT_EQ(cuda.exit_code, 0) << cuda.output;
  const auto host = run_tandem_with_env("", render_args("host", out("host.exr")));
  ASSERT_EQ(host.exit_code, 0) << host.output;
  const ImageRGB a = read_image(out("cuda.exr")), b = read_image(out("host.exr"));
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)), 0);
}

// Each kind of failure, early and late in the run: exit 0, one warning that
// names the error (a list may finish before its GPU reaches the failing
// operation), and the image agrees with a CPU-only render of the same seed.
// When the very first launch fails, the CPU renders everything: bit for bit
// the CPU's image.
TEST_F(GpuFallback, AutoAndListsFinishOnTheCpuWithTheRightImage) {
  ASSERT_EQ(run_tandem_with_env("", render_args("cpu", out("cpu.exr"))).exit_code, 0);
  const ImageRGB cpu = read_image(out("cpu.exr"));
  for (const char* fault : {"launch@1", "oom@12", "launch@5", "illegal-address@3", "lost@40"}) {
    for (const char* backend : {"auto", "cuda+cpu"}) {
      SCOPED_TRACE(std::string(fault) + " with --backend " + backend);
      const std::string image = out(std::string("fault_") + backend + ".exr");
      const auto r =
          run_tandem_with_env(std::string("TANDEM_DEVICE=sim TANDEM_DEVICE_FAULT=") + fault,
                              render_args(backend, image));
      ASSERT_EQ(r.exit_code, 0) << r.output;
      const size_t warnings = count(r.output, "the GPU failed");
      EXPECT_EQ(warnings, std::string(backend) == "auto" ? 1u : warnings) << r.output;
      EXPECT_LE(warnings, 1u) << r.output;
      if (warnings) {
        EXPECT_NE(r.output.find("injected device fault"), std::string::npos) << r.output;
      }
      const auto agree =
          run_tandem_with_env("", "compare " + app_test::shell_quote(out("cpu.exr")) + " " +
                                      app_test::shell_quote(image) + " --block 8");
      EXPECT_EQ(agree.exit_code, 0) << agree.output;
      EXPECT_NE(agree.output.find("AGREE"), std::string::npos) << agree.output;
      if (std::string(fault) == "launch@1") {
        const ImageRGB got = read_image(image);
        ASSERT_EQ(got.rgb.size(), cpu.rgb.size());
        EXPECT_EQ(std::memcmp(got.rgb.data(), cpu.rgb.data(), cpu.rgb.size() * sizeof(float)), 0);
      }
    }
  }
}

TEST_F(GpuFallback, BackendCudaExitsWithTheErrorAndWritesNothing) {
  const auto r = run_tandem_with_env("TANDEM_DEVICE=sim TANDEM_DEVICE_FAULT=illegal-address@2",
                                     render_args("cuda", out("x.png")));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("illegal memory access"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out("x.png")));
}

TEST_F(GpuFallback, MalformedFaultSpecIsACleanError) {
  const auto r = run_tandem_with_env("TANDEM_DEVICE=sim TANDEM_DEVICE_FAULT=boom",
                                     render_args("auto", out("x.png")));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("TANDEM_DEVICE_FAULT"), std::string::npos) << r.output;
}

// The frame loop overlaps every commit with the previous frame's render
// under the default backend, and says so per frame.
TEST_F(GpuFallback, FrameLoopCommitsWhileTheGpuRenders) {
  const auto r = run_tandem_with_env(
      "TANDEM_DEVICE=sim", "bench --scene builtin:arena --frames 5 --width 64 --height 36 --json " +
                               app_test::shell_quote(out("frames.json")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("commits during the render:         4 of 4 frames"), std::string::npos)
      << r.output;
  std::ifstream file(out("frames.json"));
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const json_test::Node report = json_test::parse(text);
  EXPECT_EQ(report["overlapped_commits"].number, 4.0);
  EXPECT_TRUE(report["backends"][0].has("commit_hidden_ms_per_frame"));
}

}  // namespace
}  // namespace tandem
