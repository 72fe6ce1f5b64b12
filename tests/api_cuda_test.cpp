// The public API on the CUDA backend: the scene goes to the device and the
// overlapped frame loop (prepare_next_frame compiling and committing frame
// N + 1 while the GPU renders frame N) gives exactly the pixels of the
// plain loop. CudaGpu.*: on a GPU (label gpu; skipped without one, failing
// under TANDEM_REQUIRE_GPU=1) and on the simulated device
// (ApiOnSimulatedDevice, TANDEM_DEVICE=sim) in every CI run.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "api_test_scene.h"

namespace {

using namespace tandem_api_test;

#define TANDEM_API_REQUIRE_CUDA()                                                         \
  do {                                                                                    \
    std::string reason_;                                                                  \
    if (!tandem::cuda_available(&reason_)) {                                              \
      const char* required_ = std::getenv("TANDEM_REQUIRE_GPU");                          \
      if (required_ && std::string(required_) == "1")                                     \
        FAIL() << "TANDEM_REQUIRE_GPU=1 but the CUDA backend has no device: " << reason_; \
      GTEST_SKIP() << "no CUDA device: " << reason_;                                      \
    }                                                                                     \
  } while (0)

tandem::RendererOptions cuda_options() {
  tandem::RendererOptions o = small_options();
  o.backend = tandem::BackendChoice::kCuda;
  return o;
}

TEST(CudaGpu, ApiRendersOnTheDeviceAndOverlapsTheNextFrame) {
  TANDEM_API_REQUIRE_CUDA();
  tandem::Renderer r(cuda_options());
  const tandem::InstanceId block = build_scene(r);
  r.render_frame();
  EXPECT_EQ(r.backend_names(), "cuda");
  r.begin_frame();
  r.set_instance_transform(block, tandem::Transform::translation(1.0f, 0.5f, 0.0f));
  // Only the GPU renders: the next frame is compiled now.
  EXPECT_TRUE(r.prepare_next_frame());
  r.end_frame();
  const tandem::FrameInfo f = r.render_frame();
  EXPECT_TRUE(f.accumulation_reset);
  const std::vector<float> img = r.image_linear();
  ASSERT_EQ(img.size(), 48u * 32u * 3u);
  EXPECT_GT(mean(img), 0.01);
}

TEST(CudaGpu, ApiOverlappedLoopGivesThePixelsOfThePlainLoop) {
  TANDEM_API_REQUIRE_CUDA();
  std::vector<float> overlapped, sequential;
  {
    tandem::Renderer r(cuda_options());
    const tandem::InstanceId block = build_scene(r);
    for (int f = 0; f < 4; ++f) {
      r.begin_frame();
      r.set_instance_transform(block, tandem::Transform::translation(0.3f * float(f), 0.5f, 0));
      EXPECT_TRUE(r.prepare_next_frame());
      r.end_frame();
    }
    overlapped = r.image_linear();
  }
  {
    tandem::Renderer r(cuda_options());
    const tandem::InstanceId block = build_scene(r);
    for (int f = 0; f < 4; ++f) {
      r.render_frame();
      r.set_instance_transform(block, tandem::Transform::translation(0.3f * float(f), 0.5f, 0));
    }
    sequential = r.image_linear();
  }
  EXPECT_EQ(overlapped, sequential);
}

}  // namespace
