// The GPU's branches of the kernel code run on the CPU: the simulated
// device's kernels are the .cu files compiled with the GPU's intrinsics and
// BVH loops (core/kernel/gpu_intrinsics.h), and their hits must be the host
// portable loops' bit for bit, in both layouts, for closest and any hit, on
// scenes with instancing, alpha cut-outs and refit deforming meshes; and its
// images the host backend's bit for bit (also in cuda_pipeline_test.cpp and
// cuda_backend_test.cpp).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <memory>

#include "accstruc_test_util.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cuda/cuda_backend.h"
#include "backends/cuda/sim_device.h"
#include "core/kernel/bvh_traverse.h"
#include "core/render/offline_render.h"
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
  {
    // Deforming meshes whose every vertex moved are refit without leaf
    // records and traced through their indices (kBlasNoLeafRecords).
    Scene scene = make_builtin_scene("cornell-spheres");
    for (uint32_t m = 0; m < scene.meshes().size(); ++m)
      scene.set_mesh_deforms(m);
    TracedScene s(std::move(scene));
    for (uint32_t m = 0; m < s.scene.meshes().size(); ++m)
      for (glm::vec3& p : s.scene.edit_mesh_vertices(m).positions)
        p *= 1.01f;
    s.recompile();
    expect_gpu_hits_are_the_portable_loops(s, "deformed cornell-spheres");
  }
  const std::filesystem::path dir = std::filesystem::path(TANDEM_SHARED_DIR) / "scenes" / "gltf";
  for (const char* model : {"SimpleInstancing", "FlightHelmet"}) {
    const std::filesystem::path file = dir / model / "glTF" / (std::string(model) + ".gltf");
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    TracedScene s(load_scene(file.string()));
    expect_gpu_hits_are_the_portable_loops(s, model);
  }
}

// A model with sheen, clear coat, transmission-free glass and alpha
// cut-outs (ToyCar): the simulated device's megakernel and wavefront give the
// host backend's image bit for bit, which takes the GPU's table lookups
// (sRGB texels, the sheen albedo) through the read-only path.
TEST(CudaEmulation, ShadingTablesGiveTheHostBackendsImage) {
  const std::filesystem::path file =
      std::filesystem::path(TANDEM_SHARED_DIR) / "scenes/gltf/ToyCar/glTF/ToyCar.gltf";
  ASSERT_TRUE(std::filesystem::exists(file)) << file;
  Scene scene = load_scene(file.string());
  const uint32_t width = 40, height = 24;
  scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, float(width) / float(height)));
  TracedScene s(std::move(scene));
  s.settings.width = width;
  s.settings.height = height;
  SceneDelta delta;
  s.recompile(&delta);
  CpuBackend host{CpuTraversal::kTandemBvh};
  host.sync(s.ks, SceneDelta::everything());
  OfflineRenderOptions options;
  options.spp = 2;
  const ImageRGB reference = render_offline(host, width, height, options).image;
  auto sim = std::make_shared<SimDevice>();
  {
    CudaBackend cuda(sim, CudaKernelVariant::kMegakernel, {});
    cuda.sync(s.ks, SceneDelta::everything());
    for (CudaKernelVariant v : {CudaKernelVariant::kMegakernel, CudaKernelVariant::kWavefront}) {
      cuda.set_variant(v);
      const ImageRGB image = render_offline(cuda, width, height, options).image;
      EXPECT_EQ(image.rgb, reference.rgb) << kernel_variant_name(v);
    }
  }
  const SimDeviceReport r = sim->report();
  EXPECT_TRUE(r.hazards.empty()) << (r.hazards.empty() ? "" : r.hazards[0]);
}

}  // namespace
}  // namespace tandem
