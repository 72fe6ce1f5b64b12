// The public API on the CUDA backend: the scene goes to the device and the
// overlapped frame loop (prepare_next_frame compiling and committing frame
// N + 1 while the GPU renders frame N) gives exactly the pixels of the
// plain loop. CudaGpu.*: on a GPU (label gpu; skipped without one, failing
// under TANDEM_REQUIRE_GPU=1) and on the simulated device
// (ApiOnSimulatedDevice, TANDEM_DEVICE=sim) in every CI run.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <stdlib.h>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "api_test_scene.h"

#ifdef TANDEM_TEST_CUDART
#include <cuda_runtime_api.h>
#endif

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

// `bytes` at a device pointer the API gave, as a host would read them:
// through the CUDA runtime on a GPU, directly on the simulated device
// (whose memory is the process's).
std::vector<uint8_t> read_device(const void* p, size_t bytes) {
  std::vector<uint8_t> out(bytes);
  const char* device = std::getenv("TANDEM_DEVICE");
  if (device != nullptr && std::string(device) == "sim") {
    std::memcpy(out.data(), p, bytes);
    return out;
  }
#ifdef TANDEM_TEST_CUDART
  EXPECT_EQ(cudaMemcpy(out.data(), p, bytes, cudaMemcpyDeviceToHost), cudaSuccess);
#else
  ADD_FAILURE() << "this test build has no CUDA runtime to read a GPU pointer with";
#endif
  return out;
}

// RendererOptions::cuda_image: the GPU keeps the accumulated image, and a
// host that presents through its own interop reads the image_linear() /
// image_srgb8() pixels where they are, after edits restarted them too.
TEST(CudaGpu, TheImageStaysOnTheGpuForTheHostsInterop) {
  TANDEM_API_REQUIRE_CUDA();
  tandem::RendererOptions o = cuda_options();
  o.cuda_image = true;
  tandem::Renderer r(o);
  const tandem::InstanceId block = build_scene(r);
  r.render_frame();
  r.set_instance_transform(block, tandem::Transform::translation(0.5f, 0.5f, 0.0f));
  for (int f = 0; f < 3; ++f)
    r.render_frame();
  const size_t values = size_t(r.width()) * r.height() * 3;
  const std::vector<float> host = r.image_linear();
  const std::vector<uint8_t> linear = read_device(r.cuda_image_linear(), values * sizeof(float));
  std::vector<float> device(values);
  std::memcpy(device.data(), linear.data(), linear.size());
  EXPECT_EQ(device, host);
  EXPECT_GT(mean(device), 0.01);
  const std::vector<uint8_t> host8 = r.image_srgb8(0.5f, tandem::ToneCurve::kAces);
  const std::vector<uint8_t> device8 =
      read_device(r.cuda_image_srgb8(0.5f, tandem::ToneCurve::kAces), values);
  size_t off = 0;
  for (size_t i = 0; i < values; ++i)
    off += std::abs(int(device8[i]) - int(host8[i])) > 1;  // the device's powf, last level
  EXPECT_EQ(off, 0u);

  o.cuda_image = false;
  r.set_options(o);
  r.render_frame();
  error_of(tandem::Error::Kind::kInvalidState, [&] { r.cuda_image_linear(); });
  o.backend = tandem::BackendChoice::kCpu;
  o.cuda_image = true;
  EXPECT_NE(error_of(tandem::Error::Kind::kInvalidArgument, [&] { tandem::Renderer cpu(o); })
                .find("cuda_image needs BackendChoice::kCuda"),
            std::string::npos);
}

// A GPU lost in the middle of a run (the device fault injector, on the
// simulated device in CI or on a real one): the frame is finished on the
// CPU, FrameInfo says so once, gpu_unused_reason() names the failure, and
// the game goes on rendering the scene it edits on the CPU.
TEST(CudaGpu, AGpuLostMidRunIsReportedAndTheCpuGoesOn) {
  TANDEM_API_REQUIRE_CUDA();
  ::setenv("TANDEM_DEVICE_FAULT", "lost@40", 1);
  tandem::RendererOptions o = small_options();
  o.backend = tandem::BackendChoice::kAuto;
  tandem::Renderer r(o);
  ::unsetenv("TANDEM_DEVICE_FAULT");
  const tandem::InstanceId block = build_scene(r);
  EXPECT_EQ(r.gpu_unused_reason(), "");
  int failed_frames = 0, frames_after = 0;
  for (int f = 0; f < 12; ++f) {
    r.set_instance_transform(block, tandem::Transform::translation(0.1f * float(f), 0.5f, 0));
    const tandem::FrameInfo info = r.render_frame();
    failed_frames += info.gpu_failed;
    if (failed_frames > 0 && !info.gpu_failed) {
      ++frames_after;
      EXPECT_EQ(r.backend_names(), "cpu");
    }
    EXPECT_GT(mean(r.image_linear()), 0.01) << "frame " << f;
  }
  EXPECT_EQ(failed_frames, 1);
  EXPECT_GT(frames_after, 0);
  EXPECT_NE(r.gpu_unused_reason().find("the GPU failed (injected device fault"), std::string::npos)
      << r.gpu_unused_reason();
}

}  // namespace
