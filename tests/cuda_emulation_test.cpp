// The GPU's branches of the kernel code run on the CPU: the simulated
// device's kernels are the .cu files compiled with the GPU's intrinsics and
// BVH loops (core/kernel/gpu_intrinsics.h), and their hits must be the host
// portable loops' bit for bit, in both layouts, for closest and any hit, on
// scenes with instancing and alpha cut-outs. (The images are compared bit
// for bit with the host backend's in cuda_pipeline_test.cpp and
// cuda_backend_test.cpp.)
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <memory>

#include "accstruc_test_util.h"
#include "backends/cuda/cuda_backend.h"
#include "backends/cuda/sim_device.h"
#include "core/kernel/bvh_traverse.h"
#include "scenes/builtin_scenes.h"
#include "scenes/scene_loader.h"

namespace tandem {
namespace {

using namespace accstruc_test;

bool same_bits(const Hit& a, const Hit& b) {
  return std::memcmp(&a, &b, sizeof(Hit)) == 0;
}

void expect_gpu_hits_are_the_portable_loops(TracedScene& s, const std::string& name) {
  std::vector<RaySample> samples = primary_rays(s, 1500, 21);
  for (const auto& more : {diffuse_rays(s, 1500, 22), shadow_rays(s, 1500, 23)})
    samples.insert(samples.end(), more.begin(), more.end());
  std::vector<Ray> rays;
  std::vector<uint32_t> keys;
  for (const RaySample& r : samples) {
    rays.push_back(r.ray);
    keys.push_back(r.alpha_key);
  }
  for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
    s.accel.set_layout(KBvhLayout(layout));
    s.recompile();
    const KernelData kd = s.kd();
    auto sim = std::make_shared<SimDevice>();
    {
      CudaBackend cuda(sim, CudaKernelVariant::kMegakernel, {});
      cuda.sync(s.ks, SceneDelta::everything());
      for (bool any_hit : {false, true}) {
        const std::vector<Hit> gpu = cuda.trace_rays(rays, keys, any_hit);
        size_t portable = 0, host = 0, hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
          const Hit p =
              bvh_trace_counted<false, true>(kd, rays[i], keys[i], layout, any_hit, nullptr);
          const Hit h = bvh_trace(kd, rays[i], keys[i], layout, any_hit);
          portable += same_bits(gpu[i], p);
          hits += hit_valid(p);
          // The host's own wide loop finds the same closest t but may report
          // another triangle at exactly that t.
          host += layout == kBvhLayoutWide
                      ? hit_valid(gpu[i]) == hit_valid(h) &&
                            (any_hit || std::memcmp(&gpu[i].t, &h.t, sizeof(float)) == 0)
                      : same_bits(gpu[i], h);
        }
        const std::string what =
            name + ", " + layout_name(layout) + (any_hit ? ", any hit" : ", closest hit");
        EXPECT_EQ(portable, rays.size()) << what;
        EXPECT_EQ(host, rays.size()) << what;
        EXPECT_GT(hits, rays.size() / 4) << what << ": too few hits to compare";
      }
    }
    const SimDeviceReport r = sim->report();
    EXPECT_TRUE(r.hazards.empty()) << name << ": " << (r.hazards.empty() ? "" : r.hazards[0]);
  }
}

TEST(CudaEmulation, GpuTraversalGivesThePortableLoopsHitsBitForBit) {
  for (const char* builtin : {"cornell-spheres", "arena"}) {
    TracedScene s(make_builtin_scene(builtin));
    expect_gpu_hits_are_the_portable_loops(s, builtin);
  }
  const std::filesystem::path dir = std::filesystem::path(TANDEM_SHARED_DIR) / "scenes" / "gltf";
  for (const char* model : {"SimpleInstancing", "FlightHelmet"}) {
    const std::filesystem::path file = dir / model / "glTF" / (std::string(model) + ".gltf");
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    TracedScene s(load_scene(file.string()));
    expect_gpu_hits_are_the_portable_loops(s, model);
  }
}

}  // namespace
}  // namespace tandem
