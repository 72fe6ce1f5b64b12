// Ray-by-ray comparison of Tandem's BVH (both layouts) with Embree on every
// shared glTF model, the built-in scenes and a procedural scene of over a
// million triangles: primary, shadow and diffuse rays must give the same
// hit (instance, primitive, distance) or the same occlusion for >= 99.9%.
#include <algorithm>
#include <filesystem>

#include "accstruc/content_hash.h"
#include "accstruc_test_util.h"
#include "scenes/builtin_scenes.h"
#include "scenes/procedural_scenes.h"

namespace tandem {
namespace {

using namespace accstruc_test;

constexpr double kRequiredAgreement = 0.999;
constexpr uint32_t kRaysPerKind = 20000;

std::vector<std::string> gltf_files() {
  std::vector<std::string> files;
  const std::filesystem::path dir = std::filesystem::path(TANDEM_SHARED_DIR) / "scenes" / "gltf";
  std::error_code ec;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
       !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    const std::string ext = it->path().extension().string();
    if (ext == ".gltf" || ext == ".glb") files.push_back(it->path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

void compare_scene(TracedScene& s, const std::string& name) {
  expect_hits_like_embree(s, name, kRaysPerKind, kRequiredAgreement);
  const KernelData kd = s.kd();
  // The tracer wrapper follows kd.bvh.layout.
  const auto primary = primary_rays(s, 200, 1);
  KernelData wide_kd = kd;
  wide_kd.bvh.layout = kBvhLayoutWide;
  const BvhTracer tracer{&wide_kd};
  for (size_t i = 0; i < std::min<size_t>(primary.size(), 200); ++i) {
    const Hit a = tracer.intersect(primary[i].ray, primary[i].alpha_key);
    const Hit b = bvh_intersect(kd, primary[i].ray, primary[i].alpha_key, kBvhLayoutWide);
    EXPECT_EQ(a.prim, b.prim);
    EXPECT_EQ(tracer.occluded(primary[i].ray, 0),
              bvh_occluded(kd, primary[i].ray, 0, kBvhLayoutWide));
  }
}

class GltfVsEmbree : public ::testing::TestWithParam<std::string> {};

TEST_P(GltfVsEmbree, SameHitsAsEmbree) {
  TracedScene s(load_scene(GetParam()));
  ASSERT_GT(s.scene.triangle_count_instanced(), 0u);
  compare_scene(s, std::filesystem::path(GetParam()).filename().string());
}

std::string param_name(const ::testing::TestParamInfo<std::string>& info) {
  const std::filesystem::path p(info.param);
  std::string name = p.parent_path().filename().string() + "_" + p.stem().string();
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(SharedModels, GltfVsEmbree, ::testing::ValuesIn(gltf_files()), param_name);
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(GltfVsEmbree);

TEST(BuiltinVsEmbree, SameHitsAsEmbree) {
  for (const char* name : {"cornell", "cornell-spheres", "furnace", "sky-plane"}) {
    TracedScene s(make_builtin_scene(name));
    compare_scene(s, std::string("builtin:") + name);
  }
}

TEST(ProceduralVsEmbree, MillionTriangles) {
  TracedScene s(make_procedural_scene(1'000'000, 1));
  ASSERT_GE(s.scene.triangle_count_unique(), 1'000'000u);
  std::printf("[accstruc] procedural: %zu unique triangles, %zu instanced, %zu instances\n",
              s.scene.triangle_count_unique(), s.scene.triangle_count_instanced(),
              s.scene.instances().size());
  compare_scene(s, "builtin:procedural (1M)");
}

// A seed means the same scene and the same test rays on every compiler:
// the generators draw their random numbers in named steps, never two in
// the arguments of one call (whose order is unspecified: g++ evaluates them
// right to left, clang left to right, so clang once built a different
// procedural scene, and every ray-by-ray and exact-equality test saw other
// data than under g++). The values are those of g++ 12 and clang 14 on
// x86-64 (glibc's libm); a libm that rounds sin/cos/exp/log differently may
// change them too, by design of this check: look at what moved first.
TEST(ProceduralScene, SeedGivesTheSameSceneAndRaysOnEveryCompiler) {
  TracedScene s(make_procedural_scene(20000, 10));
  const auto hash = [](const auto& v) {
    return content_hash(v.data(), v.size() * sizeof(v[0]), 1);
  };
  EXPECT_EQ(hash(s.ks.positions), 0x82b612efdb5aeb61ull);
  EXPECT_EQ(hash(s.ks.instances), 0xf3189b72788dabafull);
  const auto ray_hash = [](const std::vector<RaySample>& rays) {
    std::vector<Ray> r;
    for (const RaySample& x : rays)
      r.push_back(x.ray);
    return content_hash(r.data(), r.size() * sizeof(Ray), 2);
  };
  EXPECT_EQ(ray_hash(primary_rays(s, 1000, 11)), 0xc36103b1df42d802ull);
  EXPECT_EQ(ray_hash(diffuse_rays(s, 1000, 12)), 0xb31bf86f14eddfebull);
  EXPECT_EQ(ray_hash(shadow_rays(s, 1000, 13)), 0xa8f37223329a2a1aull);
}

}  // namespace
}  // namespace tandem
