// Traversal work counters (the counting instantiation of the traversal that
// `tandem bench --accstruc` reports).
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include "accstruc_test_util.h"
#include "scenes/builtin_scenes.h"

namespace tandem {
namespace {

using accstruc_test::TracedScene;

// One triangle in the z = 0 plane, one instance of it.
Scene single_triangle_scene() {
  Scene scene;
  scene.add_material(Material{});
  Mesh m;
  m.name = "tri";
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  m.triangle_materials = {0};
  scene.add_instance({"tri", scene.add_mesh(std::move(m)), glm::mat4(1.0f)});
  return scene;
}

BvhCounters count(const KernelData& kd, const Ray& ray, uint32_t layout, bool any_hit,
                  Hit* hit_out = nullptr) {
  BvhCounters c;
  const Hit hit = bvh_trace_counted<true>(kd, ray, 0, layout, any_hit, &c);
  if (hit_out) *hit_out = hit;
  return c;
}

TEST(TraversalCounters, RayThroughEmptySpaceVisitsTheRootOnly) {
  TracedScene s(single_triangle_scene());
  const KernelData kd = s.kd();
  // Parallel to the triangle, far above it: misses the TLAS root's boxes.
  const Ray ray = {{-5, -5, 3}, 0.0f, {1, 0, 0}, kFloatMax};
  for (uint32_t layout = 0; layout < 2; ++layout) {
    for (const bool any_hit : {false, true}) {
      Hit hit;
      const BvhCounters c = count(kd, ray, layout, any_hit, &hit);
      EXPECT_FALSE(hit_valid(hit));
      EXPECT_EQ(c.nodes, 1u) << layout;
      EXPECT_EQ(c.blas_nodes, 0u);
      EXPECT_EQ(c.instances, 0u);
      EXPECT_EQ(c.triangles, 0u);
      // Binary: both child boxes of the root (one of them the empty slot of
      // a single-leaf tree); wide: the one live slot.
      EXPECT_EQ(c.boxes, layout == kBvhLayoutBinary ? 2u : 1u);
    }
  }
}

TEST(TraversalCounters, RayHittingASingleTriangleTestsExactlyOne) {
  TracedScene s(single_triangle_scene());
  const KernelData kd = s.kd();
  const Ray ray = {{0.25f, 0.25f, 2}, 0.0f, {0, 0, -1}, kFloatMax};
  for (uint32_t layout = 0; layout < 2; ++layout) {
    for (const bool any_hit : {false, true}) {
      Hit hit;
      const BvhCounters c = count(kd, ray, layout, any_hit, &hit);
      ASSERT_TRUE(hit_valid(hit)) << layout;
      EXPECT_NEAR(hit.t, 2.0f, 1e-6f);
      EXPECT_EQ(c.triangles, 1u) << layout;
      EXPECT_EQ(c.instances, 1u);
      EXPECT_EQ(c.nodes, 2u);  // TLAS root, BLAS root
      EXPECT_EQ(c.blas_nodes, 1u);
    }
  }
}

// Counting must not change what is found: the counted and the renderer's
// traversal agree hit by hit, and the counts add up as they must.
TEST(TraversalCounters, CountedTraversalFindsTheSameHits) {
  TracedScene s(make_builtin_scene("cornell"));
  const KernelData kd = s.kd();
  const auto rays = accstruc_test::diffuse_rays(s, 2000, 7);
  for (uint32_t layout = 0; layout < 2; ++layout) {
    BvhCounters total;
    for (const auto& r : rays) {
      const Hit plain = bvh_trace(kd, r.ray, 0, layout, false);
      const Hit counted = bvh_trace_counted<true>(kd, r.ray, 0, layout, false, &total);
      ASSERT_EQ(hit_valid(plain), hit_valid(counted));
      if (hit_valid(plain)) {
        EXPECT_EQ(plain.t, counted.t);
        EXPECT_EQ(plain.prim, counted.prim);
        EXPECT_EQ(plain.instance, counted.instance);
      }
    }
    EXPECT_GE(total.nodes, rays.size());
    EXPECT_LE(total.blas_nodes, total.nodes);
    EXPECT_GE(total.boxes, total.nodes);
    EXPECT_GT(total.triangles, 0u);
  }
}

}  // namespace
}  // namespace tandem
