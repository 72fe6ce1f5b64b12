// The denoiser's filter on the GPU against the CPU: the same per-pixel code
// (core/kernel/svgf.h) must give the same image within float rounding, on a
// first frame and on a frame with reprojected history.
#include <random>

#include "backends/cuda/svgf_device.h"
#include "cuda_test_util.h"

namespace tandem {
namespace {

// A synthetic frame: two planes at different depths, a sphere-like normal
// field, sky, textured albedo and noisy radiance; moving by `shift` pixels.
void make_frame(uint32_t w, uint32_t h, int shift, uint32_t seed, std::vector<PixelFeatures>& f,
                std::vector<Vec3>& radiance) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  f.assign(size_t(w) * h, PixelFeatures{});
  radiance.assign(size_t(w) * h, Vec3{});
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      PixelFeatures& p = f[size_t(y) * w + x];
      const int sx = int(x) - shift;
      if (y < h / 8) {
        p.instance = p.prim = p.material = kInvalidIndex;
        p.albedo = make_vec3(1.0f);
      } else {
        const bool near_plane = sx > int(w / 3) && sx < int(2 * w / 3);
        p.instance = near_plane ? 1u : 0u;
        p.material = p.instance;
        p.prim = 0;
        p.depth = near_plane ? 2.0f : 5.0f + 0.01f * float(y);
        p.prev_depth = p.depth;
        const float nx = near_plane ? float(sx - int(w / 2)) / float(w) : 0.0f;
        p.normal = normalize(make_vec3(nx, 0.0f, 1.0f));
        p.albedo = make_vec3(0.3f + 0.5f * float((x / 4 + y / 4) % 2), 0.5f, 0.4f);
        if (near_plane && shift > 0) p.motion = make_vec2(-1.0f, 0.0f);
      }
      radiance[size_t(y) * w + x] = p.albedo * (u(rng) * 2.0f);
    }
  }
}

TEST(CudaGpu, SvgfFilterMatchesCpu) {
  std::string reason;
  if (!svgf_cuda_available(&reason)) {
    if (cuda_test::gpu_required()) FAIL() << "TANDEM_REQUIRE_GPU=1 but: " << reason;
    GTEST_SKIP() << reason;
  }
  if (cuda_test::on_simulated_device()) GTEST_SKIP() << "tests the GPU's own arithmetic";
  const uint32_t w = 160, h = 96;
  const size_t n = size_t(w) * h;
  const SvgfParams params = svgf_default_params(w, h);
  std::vector<PixelFeatures> f0, f1;
  std::vector<Vec3> r0, r1;
  make_frame(w, h, 0, 1, f0, r0);
  make_frame(w, h, 1, 2, f1, r1);
  struct Out {
    std::vector<Vec4> hist, moments, a, b;
    std::vector<Vec3> image;
    std::vector<Vec2> slope;
    std::vector<SvgfGuide> guide;
    std::vector<uint32_t> material;
    Out(size_t n) : hist(n), moments(n), a(n), b(n), image(n), slope(n), guide(n), material(n) {}
  };
  Out cpu0(n), gpu0(n), cpu1(n), gpu1(n);
  auto frame = [&](const std::vector<PixelFeatures>& f, const std::vector<Vec3>& r,
                   const std::vector<PixelFeatures>* prev, const Out* prev_out, Out& out) {
    return SvgfFrame{f.data(),
                     r.data(),
                     prev ? prev->data() : nullptr,
                     prev_out ? prev_out->hist.data() : nullptr,
                     prev_out ? prev_out->moments.data() : nullptr,
                     out.hist.data(),
                     out.moments.data(),
                     out.image.data(),
                     out.a.data(),
                     out.b.data(),
                     out.slope.data(),
                     out.guide.data(),
                     out.material.data()};
  };
  svgf_run_cpu(params, frame(f0, r0, nullptr, nullptr, cpu0));
  svgf_run_cuda(params, frame(f0, r0, nullptr, nullptr, gpu0));
  // The second frame reprojects each side's own history.
  svgf_run_cpu(params, frame(f1, r1, &f0, &cpu0, cpu1));
  svgf_run_cuda(params, frame(f1, r1, &f0, &cpu0, gpu1));
  for (const auto& [c, g] : {std::pair{&cpu0, &gpu0}, std::pair{&cpu1, &gpu1}}) {
    double worst = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const float* a = &c->image[i].x;
      const float* b = &g->image[i].x;
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, double(std::fabs(a[k] - b[k]) / (std::fabs(a[k]) + 1e-3f)));
      EXPECT_EQ(c->moments[i].z, g->moments[i].z) << "history length of pixel " << i;
    }
    EXPECT_LT(worst, 1e-3) << "largest relative difference GPU vs CPU";
  }
}

}  // namespace
}  // namespace tandem
