// The denoiser's feature pass on the CUDA backend against the CPU backend's:
// the same per-pixel code (core/kernel/features.h) over the same BVH, so the
// simulated device (which computes with the host's arithmetic) must give the
// same bits and a GPU the same surfaces within float rounding. Two frames,
// the second with the camera turned and an instance moved, so that the
// motion vectors and the previous transforms (copied to the device) count.
#include <glm/gtc/matrix_transform.hpp>

#include "backends/cpu/cpu_backend.h"
#include "core/kernel/features.h"
#include "core/world/motion_history.h"
#include "cuda_test_util.h"
#include "scenes/builtin_scenes.h"

namespace tandem {
namespace {

using cuda_test::FrameScene;
using cuda_test::on_simulated_device;
using cuda_test::same_bits;

bool same_features(const PixelFeatures& a, const PixelFeatures& b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(CudaGpu, FeaturePassMatchesCpu) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  const bool sim = on_simulated_device();
  const uint32_t width = sim ? 48 : 320, height = sim ? 32 : 180;
  const size_t n = size_t(width) * height;
  FrameScene fs(make_cornell_spheres(), width, height);
  std::string reason;
  CudaBackend cuda(open_device(&reason), CudaKernelVariant::kMegakernel, {});
  std::vector<PixelFeatures> f(n);
  EXPECT_THROW(cuda.render_features(FeaturePass{}, f.data(), {}), std::logic_error);
  CpuBackend host{CpuTraversal::kTandemBvh};
  MotionHistory motion;
  for (int frame = 0; frame < 2; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    if (frame == 1) {
      Camera c = fs.scene.camera();
      const glm::mat4 r = glm::rotate(glm::mat4(1.0f), 0.03f, c.up);
      c.forward = glm::normalize(glm::vec3(r * glm::vec4(c.forward, 0.0f)));
      fs.scene.edit_camera() = c;
      const uint32_t last = uint32_t(fs.scene.instances().size()) - 1;
      fs.scene.set_instance_transform(
          last, glm::translate(glm::mat4(1.0f), glm::vec3(0.05f, 0.02f, 0.0f)) *
                    fs.scene.instances()[last].transform);
    }
    const SceneDelta delta = fs.next_frame();
    host.sync(fs.ks, delta);
    cuda.sync(fs.ks, delta);
    const FeaturePass pass = motion.advance(fs.ks.view());
    std::vector<PixelFeatures> g(n);
    ASSERT_TRUE(host.render_features(pass, f.data(), {}));
    ASSERT_TRUE(cuda.render_features(pass, g.data(), {}));
    size_t hits = 0, moving = 0, identical = 0, same_surface = 0;
    for (size_t i = 0; i < n; ++i) {
      const PixelFeatures& a = f[i];
      const PixelFeatures& b = g[i];
      identical += same_features(a, b);
      hits += features_hit(a);
      moving += frame == 1 && std::fabs(a.motion.x) > 0.5f;
      if (a.instance != b.instance || a.prim != b.prim) continue;
      ++same_surface;
      EXPECT_EQ(a.material, b.material);
      EXPECT_TRUE(same_bits(a.albedo.x, b.albedo.x) || std::fabs(a.albedo.x - b.albedo.x) < 1e-5f);
      EXPECT_NEAR(a.depth, b.depth, 1e-4f * std::max(a.depth, 1.0f));
      EXPECT_NEAR(a.prev_depth, b.prev_depth, 1e-4f * std::max(a.prev_depth, 1.0f));
      EXPECT_NEAR(a.motion.x, b.motion.x, 1e-3f);
      EXPECT_NEAR(a.motion.y, b.motion.y, 1e-3f);
      EXPECT_NEAR(dot(a.normal, b.normal), dot(a.normal, a.normal), 1e-4f);
    }
    EXPECT_GT(hits, n / 2);
    // A GPU may find another triangle for the odd ray through a shared edge.
    EXPECT_GE(same_surface, n - n / 500);
    if (frame == 1) {
      EXPECT_GT(moving, n / 2) << "the camera turned: most pixels move";
    }
    if (sim) {
      EXPECT_EQ(identical, n) << "the simulated device computes with the host's arithmetic";
    }
  }
}

}  // namespace
}  // namespace tandem
