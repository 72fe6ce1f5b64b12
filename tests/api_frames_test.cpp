// What a game needs of each frame: a CPU thread budget that leaves cores to
// its own loop, each backend's part of the frame, and the image written
// into its own buffers. Only <tandem/tandem.h> is on the include path.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "api_test_scene.h"

namespace {

using tandem::Error;
using namespace tandem_api_test;

TEST(ApiFrames, TheThreadBudgetHoldsWhileTheRendererLivesAndChangesNoPixel) {
  std::vector<float> unlimited, budgeted;
  uint32_t all_threads = 0;
  {
    tandem::Renderer r(small_options());
    build_scene(r);
    const tandem::FrameInfo f = r.render_frame();
    all_threads = f.threads;
    unlimited = r.image_linear();
  }
  EXPECT_GE(all_threads, 1u);
  {
    tandem::RendererOptions o = small_options();
    o.reserve_cores = 4096;  // leave every core but one to the host
    tandem::Renderer r(o);
    build_scene(r);
    EXPECT_EQ(r.render_frame().threads, 1u);
    budgeted = r.image_linear();
    // A new budget applies from the next frame: two threads, less one reserved.
    o.threads = 2;
    o.reserve_cores = 1;
    r.set_options(o);
    EXPECT_EQ(r.render_frame().threads, 1u);
    o.reserve_cores = 0;
    r.set_options(o);
    EXPECT_EQ(r.render_frame().threads, 2u);
  }
  EXPECT_EQ(budgeted, unlimited);  // the image does not depend on the threads
  // Gone with its renderer.
  tandem::Renderer again(small_options());
  build_scene(again);
  EXPECT_EQ(again.render_frame().threads, all_threads);
  tandem::RendererOptions bad = small_options();
  bad.threads = 5000;
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { tandem::Renderer r(bad); })
                .find("threads and reserve_cores must each be at most 4096"),
            std::string::npos);
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { again.set_options(bad); }).size(), 0u);
}

TEST(ApiFrames, EachBackendsPartOfTheFrameIsReported) {
  tandem::Renderer r(small_options());
  build_scene(r);
  const tandem::FrameInfo f = r.render_frame();
  ASSERT_EQ(f.backends.size(), 1u);
  const tandem::BackendFrameStats& cpu = f.backends[0];
  EXPECT_EQ(cpu.name, "cpu");
  EXPECT_DOUBLE_EQ(cpu.share, 1.0);
  EXPECT_EQ(cpu.rays, f.rays);
  EXPECT_GT(cpu.seconds, 0.0);
  EXPECT_GT(cpu.mrays_per_second, 0.0);
}

TEST(ApiFrames, TheImageIsWrittenIntoTheCallersBuffers) {
  tandem::Renderer r(small_options());
  std::vector<float> linear(48 * 32 * 3, -1.0f);
  std::vector<uint8_t> srgb(48 * 32 * 3, 7);
  EXPECT_NE(error_of(Error::Kind::kInvalidState,
                     [&] { r.copy_image_linear(linear.data(), linear.size()); })
                .find("no frame has been rendered yet"),
            std::string::npos);
  build_scene(r);
  r.render_frame();
  r.copy_image_linear(linear.data(), linear.size());
  EXPECT_EQ(linear, r.image_linear());
  r.copy_image_srgb8(srgb.data(), srgb.size(), 1.5f, tandem::ToneCurve::kAces);
  EXPECT_EQ(srgb, r.image_srgb8(1.5f, tandem::ToneCurve::kAces));
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument,
                     [&] { r.copy_image_linear(linear.data(), linear.size() - 1); })
                .find("the buffer holds 4607 floats; the 48x32 image needs 4608"),
            std::string::npos);
  error_of(Error::Kind::kInvalidArgument, [&] { r.copy_image_srgb8(nullptr, srgb.size()); });
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.copy_image_srgb8(srgb.data(), srgb.size(), std::nanf("")); });
}

TEST(ApiFrames, TheCudaErrorSpeaksOfTheApiNotOfCommandLineFlags) {
  if (tandem::cuda_available()) GTEST_SKIP() << "a CUDA device is available";
  tandem::RendererOptions o = small_options();
  o.backend = tandem::BackendChoice::kCuda;
  const std::string message = error_of(Error::Kind::kDevice, [&] { tandem::Renderer r(o); });
  EXPECT_EQ(message.find("--"), std::string::npos) << message;
  EXPECT_NE(message.find("the cuda backend cannot run"), std::string::npos) << message;
}

}  // namespace
