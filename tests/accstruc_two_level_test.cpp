// The single-loop two-level traversal (core/kernel/bvh_traverse.h) against
// the loop-per-level traversal it replaced (accstruc_nested_traversal.h):
// the GPU needs the single loop for its registers, but it must change
// nothing else. Every hit must be the same bits (t, u, v, instance, prim),
// every occlusion answer the same, and the traversal counters equal, which
// shows that the nodes, instances and triangles were visited in the same
// order and number.
//
// The host has its own loop over the binary layout (bvh_traverse_host.h, what
// bvh_trace runs outside nvcc): it must find the same bits as the single
// loop, and visit no more nodes. Its loop over the wide layout visits
// children in distance order instead of octant order: the closest hit's t
// must be the same bits and any-hit queries the same answer; a different
// triangle may win only a tie at exactly equal t, and over all rays it must
// do no more work (within 5%).
#include <cstring>
#include <filesystem>

#include "accstruc_nested_traversal.h"
#include "accstruc_test_util.h"
#include "scenes/builtin_scenes.h"
#include "scenes/procedural_scenes.h"

namespace tandem {
namespace {

using namespace accstruc_test;

constexpr uint32_t kRaysPerKind = 3000;

bool same_bits(const Hit& a, const Hit& b) {
  return std::memcmp(&a, &b, sizeof(Hit)) == 0;
}

bool same_counters(const BvhCounters& a, const BvhCounters& b) {
  return a.nodes == b.nodes && a.boxes == b.boxes && a.triangles == b.triangles &&
         a.instances == b.instances && a.blas_nodes == b.blas_nodes;
}

// Rays of every kind through `s`, both layouts, closest and any hit.
void expect_same_traversal(const TracedScene& s, const std::string& name) {
  const KernelData kd = s.kd();
  std::vector<RaySample> rays = primary_rays(s, kRaysPerKind, 11);
  for (const auto& list : {diffuse_rays(s, kRaysPerKind, 12), shadow_rays(s, kRaysPerKind, 13)})
    rays.insert(rays.end(), list.begin(), list.end());
  for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
    const bool wide = layout == kBvhLayoutWide;
    uint32_t hits = 0, mismatches = 0, ties = 0;
    uint64_t host_nodes = 0, portable_nodes = 0, host_triangles = 0, portable_triangles = 0;
    for (const bool any_hit : {false, true}) {
      for (const RaySample& r : rays) {
        BvhCounters ours, reference;
        const Hit a = bvh_trace_counted<true, true>(kd, r.ray, r.alpha_key, layout, any_hit, &ours);
        const Hit b = nested_reference::nested_trace_counted<true>(kd, r.ray, r.alpha_key, layout,
                                                                   any_hit, &reference);
        // The renderer's (uncounted) instantiation too, the host's own loop
        // on this machine, and that loop counted.
        const Hit c = bvh_trace(kd, r.ray, r.alpha_key, layout, any_hit);
        BvhCounters host;
        const Hit d = bvh_trace_counted<true>(kd, r.ray, r.alpha_key, layout, any_hit, &host);
        hits += hit_valid(a) ? 1u : 0u;
        host_nodes += host.nodes;
        portable_nodes += ours.nodes;
        host_triangles += host.triangles;
        portable_triangles += ours.triangles;
        bool host_agrees = same_bits(a, c) && same_bits(a, d);
        if (wide && !host_agrees) {
          // Same answer: the same closest t (any hit: a hit or not); the
          // host loop's own two queries agree with each other.
          const bool same_answer = hit_valid(a) == hit_valid(d) &&
                                   (any_hit || std::memcmp(&a.t, &d.t, sizeof(float)) == 0) &&
                                   same_bits(c, d);
          const bool same_triangle = a.instance == d.instance && a.prim == d.prim;
          host_agrees = same_answer && (any_hit || !same_triangle);
          ties += host_agrees && !any_hit ? 1u : 0u;
        }
        if (!same_bits(a, b) || !host_agrees || !same_counters(ours, reference) ||
            (!wide && (host.nodes > ours.nodes || host.triangles > ours.triangles))) {
          if (++mismatches <= 5) {
            ADD_FAILURE() << name << " " << layout_name(layout) << (any_hit ? " any" : " closest")
                          << ": t " << a.t << " vs " << b.t << ", prim " << a.prim << " vs "
                          << b.prim << ", instance " << a.instance << " vs " << b.instance
                          << ", nodes " << ours.nodes << " vs " << reference.nodes << ", triangles "
                          << ours.triangles << " vs " << reference.triangles << ", host loop t "
                          << d.t << ", prim " << d.prim << ", nodes " << host.nodes;
          }
        }
      }
    }
    EXPECT_EQ(mismatches, 0u) << name << " " << layout_name(layout);
    if (wide) {
      // Distance order must not cost more work over the whole set than
      // octant order (0.83-0.99 of its nodes on most scenes, 1.02 on
      // cornell-spheres, where the two orders rarely differ and any-hit
      // queries favour neither), and a different winner is a tie, which is
      // rare.
      EXPECT_LE(double(host_nodes), 1.05 * double(portable_nodes)) << name;
      EXPECT_LE(double(host_triangles), 1.05 * double(portable_triangles)) << name;
      EXPECT_LE(ties, rays.size() / 50) << name;
    }
    // A comparison where nothing is hit proves nothing.
    EXPECT_GT(hits, 0u) << name << " " << layout_name(layout);
    std::printf(
        "[two-level] %s %s: host loop visits %.3f of the portable loop's nodes, tests %.3f of "
        "its triangles; %u closest hits won by another triangle at equal t\n",
        name.c_str(), layout_name(layout),
        portable_nodes ? double(host_nodes) / double(portable_nodes) : 1.0,
        portable_triangles ? double(host_triangles) / double(portable_triangles) : 1.0, ties);
  }
}

class TwoLevelTraversal : public ::testing::TestWithParam<std::string> {};

// The built-in scenes: one instance (cornell), several instanced spheres
// (cornell-spheres) and the arena's many instances.
TEST_P(TwoLevelTraversal, BuiltinSceneSameAsLoopPerLevel) {
  const TracedScene s(make_builtin_scene(GetParam()));
  expect_same_traversal(s, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Builtin, TwoLevelTraversal,
                         ::testing::Values("cornell", "cornell-spheres", "arena"),
                         [](const auto& info) {
                           std::string n = info.param;
                           for (char& ch : n)
                             if (ch == '-') ch = '_';
                           return n;
                         });

// glTF models with instancing (SimpleInstancing) and alpha-tested materials
// (FlightHelmet, ToyCar), where the any-hit path skips cut-out texels.
TEST(TwoLevelTraversalGltf, ModelsSameAsLoopPerLevel) {
  const std::filesystem::path dir = std::filesystem::path(TANDEM_SHARED_DIR) / "scenes" / "gltf";
  for (const char* model : {"SimpleInstancing", "FlightHelmet", "ToyCar"}) {
    const std::filesystem::path file = dir / model / "glTF" / (std::string(model) + ".gltf");
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    const TracedScene s(load_scene(file.string()));
    expect_same_traversal(s, model);
  }
}

// Thousands of overlapping instances, slivers and the soup of random
// triangles (a smaller builtin:procedural), where the host loop's culling of
// waiting nodes matters most.
TEST(TwoLevelTraversalProcedural, SameAsLoopPerLevel) {
  const TracedScene s(make_procedural_scene(60'000, 3));
  expect_same_traversal(s, "procedural");
}

// The host's wide loop runs in AVX2 where the CPU has it and in SSE2
// elsewhere (bvh_wide_host.h): the same box and triangle tests lane for
// lane, so the same hits bit for bit and the same work, on every query.
class HostWideIsa {
 public:
  explicit HostWideIsa(bool avx2) : saved_(host_wide_isa.avx2) { host_wide_isa.avx2 = avx2; }
  ~HostWideIsa() { host_wide_isa.avx2 = saved_; }

 private:
  bool saved_;
};

TEST(TwoLevelTraversalProcedural, Sse2AndAvx2LoopsAgreeBitForBit) {
  const TracedScene s(make_procedural_scene(60'000, 3));
  {
    const HostWideIsa sse2(false);
    expect_same_traversal(s, "procedural, SSE2 loop");
  }
  if (!host_cpu_has_avx2()) GTEST_SKIP() << "this CPU has no AVX2: only the SSE2 loop ran";
  const KernelData kd = s.kd();
  std::vector<RaySample> rays = primary_rays(s, kRaysPerKind, 21);
  for (const auto& list : {diffuse_rays(s, kRaysPerKind, 22), shadow_rays(s, kRaysPerKind, 23)})
    rays.insert(rays.end(), list.begin(), list.end());
  uint32_t hits = 0;
  for (const bool any_hit : {false, true}) {
    for (const RaySample& r : rays) {
      BvhCounters c_sse2, c_avx2;
      Hit sse2, avx2;
      {
        const HostWideIsa isa(false);
        sse2 = bvh_trace_counted<true>(kd, r.ray, r.alpha_key, kBvhLayoutWide, any_hit, &c_sse2);
      }
      {
        const HostWideIsa isa(true);
        avx2 = bvh_trace_counted<true>(kd, r.ray, r.alpha_key, kBvhLayoutWide, any_hit, &c_avx2);
      }
      ASSERT_TRUE(same_bits(sse2, avx2)) << "t " << sse2.t << " vs " << avx2.t;
      ASSERT_TRUE(same_counters(c_sse2, c_avx2));
      hits += hit_valid(avx2) ? 1u : 0u;
    }
  }
  EXPECT_GT(hits, rays.size() / 2);
}

}  // namespace
}  // namespace tandem
