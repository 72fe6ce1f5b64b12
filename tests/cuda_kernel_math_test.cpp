// The kernels' own math gives the same bits on the GPU as on the CPU: the
// point of sincos_pi (core/kernel/trig.h) and of the sRGB decode table
// (core/kernel/srgb_table.h), which the CPU-side tests check for accuracy.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "backends/backend_factory.h"
#include "core/kernel/sheen_albedo.h"
#include "core/kernel/srgb_table.h"
#include "core/world/light_tree_build.h"
#include "cuda_test_util.h"
#include "tests/cuda_kernel_math.h"

#if TANDEM_TESTS_HAVE_CUDA_DEVICE
namespace tandem {
namespace {

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

TEST(CudaGpu, SinCosPiMatchesHostBitForBit) {
  TANDEM_REQUIRE_REAL_GPU();
  // Every 193rd float of [-2, 2] (all binades), the samplers' grid k / 2^20,
  // and large arguments.
  std::vector<float> x;
  for (uint32_t u = 0; u <= 0x40000000u; u += 193) {
    float f;
    std::memcpy(&f, &u, sizeof f);
    x.push_back(f);
    x.push_back(-f);
  }
  for (int k = -(2 << 20); k <= (2 << 20); ++k)
    x.push_back(float(k) * 0x1p-20f);
  for (float f : {3.0f, 100.25f, -1234.567f, 4194303.5f, 0x1p22f})
    x.push_back(f);
  std::vector<SinCos> device;
  device_sincos_pi(x, &device);
  ASSERT_EQ(device.size(), x.size());
  size_t differ = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const SinCos host = sincos_pi(x[i]);
    if (bits(host.sin) != bits(device[i].sin) || bits(host.cos) != bits(device[i].cos)) {
      if (++differ <= 5) {
        ADD_FAILURE() << std::hexfloat << "x " << x[i] << ": host " << host.sin << ", " << host.cos
                      << " device " << device[i].sin << ", " << device[i].cos;
      }
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << x.size() << " arguments";
}

TEST(CudaGpu, Atan2PiMatchesHostBitForBit) {
  TANDEM_REQUIRE_REAL_GPU();
  // Directions all round the circle at several magnitudes, and the signed
  // zeros and infinities.
  std::vector<float> y, x;
  for (int k = 0; k < (1 << 20); ++k) {
    const SinCos a = sincos_pi(float(k) * 0x1p-19f);
    const float scale = std::ldexp(1.0f, (k % 61) - 30);
    y.push_back(a.sin * scale);
    x.push_back(a.cos * scale);
  }
  for (float yy : {0.0f, -0.0f, 1.0f, -1.0f, INFINITY, -INFINITY}) {
    for (float xx : {0.0f, -0.0f, 1.0f, -1.0f, INFINITY, -INFINITY}) {
      y.push_back(yy);
      x.push_back(xx);
    }
  }
  std::vector<float> device;
  device_atan2_pi(y, x, &device);
  ASSERT_EQ(device.size(), x.size());
  size_t differ = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const float host = atan2_pi(y[i], x[i]);
    if (bits(host) != bits(device[i]) && ++differ <= 5) {
      ADD_FAILURE() << std::hexfloat << "(" << y[i] << ", " << x[i] << "): host " << host
                    << " device " << device[i];
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << x.size() << " arguments";
}

TEST(CudaGpu, SrgbDecodeTableMatchesHostBitForBit) {
  TANDEM_REQUIRE_REAL_GPU();
  std::vector<float> device;
  device_srgb8_to_linear(&device);
  ASSERT_EQ(device.size(), 256u);
  for (uint32_t i = 0; i < 256; ++i)
    EXPECT_EQ(bits(device[i]), bits(kSrgb8ToLinear[i])) << i;
}

TEST(CudaGpu, SheenLobeMatchesHostBitForBit) {
  TANDEM_REQUIRE_REAL_GPU();
  // A grid of view and light directions and roughness values; the lobe's
  // powers and exponentials are plain-float code (core/kernel/exp_log.h).
  std::vector<Vec3> wo, wi;
  std::vector<float> alpha;
  for (int a = 0; a < 8; ++a) {
    for (int i = 1; i < 40; ++i) {
      for (int j = 1; j < 40; ++j) {
        const float ti = 1.5707f * float(i) / 40.0f, tj = 1.5707f * float(j) / 40.0f;
        wo.push_back(make_vec3(std::sin(ti), 0.0f, std::cos(ti)));
        wi.push_back(make_vec3(-std::sin(tj) * 0.6f, std::sin(tj) * 0.8f, std::cos(tj)));
        alpha.push_back(0.07f + 0.93f * float(a) / 7.0f);
      }
    }
  }
  std::vector<float> brdf, albedo;
  device_sheen(wo, wi, alpha, &brdf, &albedo);
  ASSERT_EQ(brdf.size(), wo.size());
  size_t differ = 0;
  for (size_t i = 0; i < wo.size(); ++i) {
    const float h_brdf = sheen_brdf(wo[i], wi[i], alpha[i]);
    const float h_albedo = sheen_albedo(wo[i].z, alpha[i]);
    if ((bits(h_brdf) != bits(brdf[i]) || bits(h_albedo) != bits(albedo[i])) && ++differ <= 5) {
      ADD_FAILURE() << std::hexfloat << "case " << i << ": host " << h_brdf << ", " << h_albedo
                    << " device " << brdf[i] << ", " << albedo[i];
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << wo.size() << " cases";
}

// The light tree chooses the same light with the same pmf on the GPU as
// on the CPU, for the same point and number (so a frame split between
// them is one image).
TEST(CudaGpu, LightTreeChoicesMatchHostBitForBit) {
  TANDEM_REQUIRE_REAL_GPU();
  std::mt19937 gen(4);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<LightTreeInput> lights;
  for (uint32_t i = 0; i < 2000; ++i) {
    LightTreeInput l;
    const glm::vec3 c(20.0f * unit(gen) - 10.0f, 5.0f * unit(gen), 20.0f * unit(gen) - 10.0f);
    l.lo = c - glm::vec3(0.05f), l.hi = c + glm::vec3(0.05f);
    l.axis = glm::normalize(glm::vec3(unit(gen) - 0.5f, unit(gen) - 0.5f, unit(gen) - 0.5f));
    l.cos_theta_o = unit(gen);
    l.power = 0.1f + 10.0f * unit(gen);
    l.two_sided = i % 3 == 0;
    l.light = i;
    lights.push_back(l);
  }
  const LightTree tree = build_light_tree(lights, 2000);
  std::vector<Vec3> p, n;
  std::vector<float> u;
  std::vector<uint64_t> trails;
  std::vector<uint32_t> trail_lights;
  for (uint32_t i = 0; i < 20000; ++i) {
    p.push_back(make_vec3(20.0f * unit(gen) - 10.0f, 5.0f * unit(gen), 20.0f * unit(gen) - 10.0f));
    n.push_back(i % 2 ? make_vec3(0.0f, 1.0f, 0.0f) : make_vec3(0.0f));
    u.push_back(unit(gen));
    trails.push_back(tree.trails[i % 2000]);
    trail_lights.push_back(i % 2000);
  }
  std::vector<uint32_t> lights_gpu;
  std::vector<float> pmfs, trail_pmfs;
  device_light_tree(tree.nodes, p, n, u, trails, trail_lights, &lights_gpu, &pmfs, &trail_pmfs);
  size_t differ = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    float pmf = 0.0f;
    const uint32_t light =
        light_tree_sample(tree.nodes.data(), uint32_t(tree.nodes.size()), p[i], n[i], u[i], &pmf);
    const float trail_pmf = light_tree_pmf(tree.nodes.data(), uint32_t(tree.nodes.size()),
                                           trails[i], trail_lights[i], p[i], n[i]);
    if ((light != lights_gpu[i] || bits(pmf) != bits(pmfs[i]) ||
         bits(trail_pmf) != bits(trail_pmfs[i])) &&
        ++differ <= 5) {
      ADD_FAILURE() << std::hexfloat << "case " << i << ": host " << light << " " << pmf << " "
                    << trail_pmf << ", device " << lights_gpu[i] << " " << pmfs[i] << " "
                    << trail_pmfs[i];
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << p.size() << " cases";
}

}  // namespace
}  // namespace tandem
#endif  // TANDEM_TESTS_HAVE_CUDA_DEVICE
