// The denoiser's filter on the device (svgf_device.h) against the CPU: the
// same per-pixel code (core/kernel/svgf.h) must give the same image within
// float rounding, and a device failure must fall back to the CPU.
#include <random>

#include "backends/cuda/device_faults.h"
#include "backends/cuda/sim_device.h"
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

// Buffers of one frame of the filter's output and work space.
struct FrameOut {
  std::vector<Vec4> hist, moments, a, b;
  std::vector<Vec3> image;
  std::vector<Vec2> slope;
  std::vector<SvgfGuide> guide;
  std::vector<uint32_t> material;
  explicit FrameOut(size_t n)
      : hist(n), moments(n), a(n), b(n), image(n), slope(n), guide(n), material(n) {}
};

SvgfFrame frame_of(const std::vector<PixelFeatures>& f, const std::vector<Vec3>& r,
                   const std::vector<PixelFeatures>* prev, const FrameOut* prev_out,
                   FrameOut& out) {
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
}

// The filter's kernels on the device (a GPU, or the simulated device that
// runs the same kernel bodies) against the CPU driver: within float
// rounding on a first frame and on a frame with reprojected history.
TEST(CudaGpu, SvgfFilterMatchesCpu) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  std::string reason;
  std::shared_ptr<DeviceOps> device = open_device(&reason);
  ASSERT_TRUE(device) << reason;
  const bool sim = cuda_test::on_simulated_device();
  const uint32_t w = sim ? 48 : 160, h = sim ? 32 : 96;
  const size_t n = size_t(w) * h;
  // The default filter, and the temporal and variance stages alone (no
  // a-trous iteration: the modulation kernel).
  for (const uint32_t iterations : {svgf_default_params(w, h).iterations, 0u}) {
    SCOPED_TRACE(std::to_string(iterations) + " a-trous iterations");
    SvgfParams params = svgf_default_params(w, h);
    params.iterations = iterations;
    std::vector<PixelFeatures> f0, f1;
    std::vector<Vec3> r0, r1;
    make_frame(w, h, 0, 1, f0, r0);
    make_frame(w, h, 1, 2, f1, r1);
    FrameOut cpu0(n), gpu0(n), cpu1(n), gpu1(n);
    DeviceSvgf filter(device);
    svgf_run_cpu(params, frame_of(f0, r0, nullptr, nullptr, cpu0));
    filter.run(params, frame_of(f0, r0, nullptr, nullptr, gpu0));
    // The second frame reprojects each side's own history.
    svgf_run_cpu(params, frame_of(f1, r1, &f0, &cpu0, cpu1));
    filter.run(params, frame_of(f1, r1, &f0, &cpu0, gpu1));
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
}

ImageRGB image_of(const std::vector<Vec3>& v, uint32_t w, uint32_t h) {
  ImageRGB image(w, h);
  for (size_t i = 0; i < v.size(); ++i) {
    image.rgb[3 * i] = v[i].x;
    image.rgb[3 * i + 1] = v[i].y;
    image.rgb[3 * i + 2] = v[i].z;
  }
  return image;
}

// The denoiser on the simulated device through DeviceOps: the same frames
// as on the CPU within rounding; and when the device fails at any of its
// first operations, that frame and the later ones are filtered on the CPU
// and come out exactly as a CPU-only denoiser's, with nothing left on the
// device.
TEST(CudaSvgf, DenoiserOnTheDeviceFallsBackToTheCpuOnAFault) {
  const uint32_t w = 24, h = 16;
  std::vector<PixelFeatures> f[3];
  std::vector<Vec3> r[3];
  for (uint32_t k = 0; k < 3; ++k)
    make_frame(w, h, int(k), 10 + k, f[k], r[k]);
  TemporalDenoiser cpu;
  std::vector<ImageRGB> expected;
  for (uint32_t k = 0; k < 3; ++k)
    expected.push_back(cpu.process(f[k], image_of(r[k], w, h)));
  for (uint32_t nth = 0; nth <= 12; ++nth) {
    SCOPED_TRACE("launch@" + std::to_string(nth));
    auto sim = std::make_shared<SimDevice>();
    {
      TemporalDenoiser denoiser;
      denoiser.set_offload(make_device_svgf_offload(
          nth ? inject_faults(sim, parse_fault_spec("launch@" + std::to_string(nth))) : sim));
      bool fell_back = false, all_on_cpu = true;
      for (uint32_t k = 0; k < 3; ++k) {
        const ImageRGB out = denoiser.process(f[k], image_of(r[k], w, h));
        EXPECT_FALSE(fell_back && !denoiser.last_on_cpu())
            << "frame " << k << " back on the device after a failure";
        fell_back = fell_back || denoiser.last_on_cpu();
        all_on_cpu = all_on_cpu && denoiser.last_on_cpu();
        if (all_on_cpu) {
          EXPECT_EQ(out.rgb, expected[k].rgb) << "frame " << k;
          continue;
        }
        // The device's history differs from the CPU's in the last bits.
        for (size_t i = 0; i < out.rgb.size(); ++i)
          ASSERT_NEAR(out.rgb[i], expected[k].rgb[i], 1e-4f * (1.0f + expected[k].rgb[i]))
              << "frame " << k << ", value " << i;
      }
      // Three frames of 4 launches (temporal, variance, a-trous x iterations).
      EXPECT_EQ(fell_back, nth != 0 && nth <= 3 * (2 + svgf_default_params(w, h).iterations));
    }
    const SimDeviceReport rep = sim->report();
    EXPECT_TRUE(rep.hazards.empty()) << (rep.hazards.empty() ? "" : rep.hazards[0]);
    EXPECT_EQ(rep.live_device_allocations, 0u);
    EXPECT_EQ(rep.live_pinned_allocations, 0u);
    EXPECT_EQ(rep.live_streams, 0u);
  }
}

}  // namespace
}  // namespace tandem
