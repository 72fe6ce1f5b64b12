// What a game needs of each frame: a CPU thread budget that leaves cores to
// its own loop, each backend's part of the frame, and the image written
// into its own buffers. Only <tandem/tandem.h> is on the include path.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
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
  EXPECT_FALSE(f.gpu_failed);
  // The stages: the first frame compiles the scene and gives it to Embree.
  EXPECT_GT(f.compile_seconds, 0.0);
  EXPECT_GT(f.upload_seconds, 0.0);
  EXPECT_GE(f.render_seconds, cpu.seconds);
  EXPECT_LE(f.compile_seconds + f.bvh_seconds + f.upload_seconds + f.render_seconds,
            f.seconds * 1.001);
  EXPECT_EQ(f.denoise_seconds, 0.0);
  tandem::RendererOptions o = small_options();
  o.denoise = true;
  r.set_options(o);
  EXPECT_GT(r.render_frame().denoise_seconds, 0.0);
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

TEST(ApiFrames, FeatureBuffersDescribeTheFirstHits) {
  tandem::Renderer r(small_options());
  const tandem::InstanceId square = build_scene(r);
  r.render_frame();
  const tandem::FeatureBuffers f = r.features();
  ASSERT_EQ(f.width, 48u);
  ASSERT_EQ(f.height, 32u);
  ASSERT_EQ(f.albedo.size(), 48u * 32 * 3);
  ASSERT_EQ(f.motion.size(), 48u * 32 * 2);
  size_t floor = 0, sky = 0, red = 0;
  for (size_t i = 0; i < f.depth.size(); ++i) {
    const float* a = &f.albedo[3 * i];
    if (f.depth[i] == 0.0f) {
      sky += a[0] == 1.0f && f.normal[3 * i + 1] == 0.0f;
    } else if (std::fabs(a[0] - 0.8f) < 1e-3f && f.normal[3 * i + 1] > 0.99f) {
      ++floor;  // the grey floor, facing up
    } else if (std::fabs(a[0] - 0.9f) < 1e-3f && std::fabs(a[1] - 0.1f) < 1e-3f) {
      ++red;
    }
  }
  EXPECT_GT(floor, 200u);
  EXPECT_GT(sky, 50u);
  EXPECT_GT(red, 4u);
  // The square moves: its pixels carry motion, the floor's none.
  r.set_instance_transform(square, tandem::Transform::translation(-0.5f, 0.5f, 0.0f));
  r.render_frame();
  const tandem::FeatureBuffers moved = r.features();
  size_t moving = 0;
  for (size_t i = 0; i < moved.depth.size(); ++i)
    moving += std::fabs(moved.motion[2 * i]) > 0.5f;
  EXPECT_GT(moving, 4u);
}

// Under the built-in sky (noisy at a few samples; a point light alone is
// sampled without noise), at the viewer's kind of resolution.
TEST(ApiFrames, TheDenoisedImageIsCloserToTheConvergedOne) {
  tandem::RendererOptions o = small_options();
  o.width = 160;
  o.height = 96;
  auto make = [&](const tandem::RendererOptions& options) {
    auto r = std::make_unique<tandem::Renderer>(options);
    build_scene(*r);
    r->use_default_sky();
    return r;
  };
  o.samples_per_frame = 256;
  const auto reference = make(o);
  const std::vector<float> ref = (reference->render_frame(), reference->image_linear());
  o.samples_per_frame = 1;
  o.seed = 99;
  const auto plain = make(o);
  plain->render_frame();
  EXPECT_EQ(error_of(Error::Kind::kInvalidState, [&] { plain->image_denoised(); })
                .find("image_denoised: RendererOptions::denoise is off"),
            0u);
  o.denoise = true;
  const auto denoised = make(o);
  for (int i = 0; i < 2; ++i)
    denoised->render_frame();
  auto rel_mse = [&](const std::vector<float>& img) {
    double s = 0.0;
    for (size_t i = 0; i < img.size(); ++i)
      s += (img[i] - ref[i]) * (img[i] - ref[i]) / (ref[i] * ref[i] + 0.01);
    return s / double(img.size());
  };
  const double raw = rel_mse(denoised->image_linear());
  const double filtered = rel_mse(denoised->image_denoised());
  EXPECT_LT(filtered, 0.5 * raw) << "raw " << raw << ", denoised " << filtered;
  std::printf("relMSE raw %.4f, denoised %.4f\n", raw, filtered);
}

TEST(ApiFrames, TheCudaErrorSpeaksOfTheApiNotOfCommandLineFlags) {
  if (tandem::cuda_available()) GTEST_SKIP() << "a CUDA device is available";
  // Which backend runs, and why not the GPU, through the API.
  tandem::RendererOptions automatic = small_options();
  automatic.backend = tandem::BackendChoice::kAuto;
  tandem::Renderer fallback(automatic);
  std::string reason;
  tandem::cuda_available(&reason);
  EXPECT_EQ(fallback.gpu_unused_reason(), reason);
  EXPECT_FALSE(reason.empty());
  build_scene(fallback);
  fallback.render_frame();
  EXPECT_EQ(fallback.backend_names(), "cpu");
  EXPECT_EQ(tandem::Renderer(small_options()).gpu_unused_reason(), "") << "kCpu was asked for";
  tandem::RendererOptions o = small_options();
  o.backend = tandem::BackendChoice::kCuda;
  const std::string message = error_of(Error::Kind::kDevice, [&] { tandem::Renderer r(o); });
  EXPECT_EQ(message.find("--"), std::string::npos) << message;
  EXPECT_NE(message.find("the cuda backend cannot run"), std::string::npos) << message;
}

}  // namespace
