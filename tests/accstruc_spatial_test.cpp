// Spatial splits in the BLAS builder (build_bvh_spatial, accstruc/spatial_bvh.cpp):
// the tree lists every triangle, within the duplication budget, with boxes
// inside the triangles' own; traced through both layouts it finds Embree's
// hits; a mesh built with splits that starts to deform is rebuilt without
// them and refit from then on.
#include <tbb/task_arena.h>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "accstruc_test_util.h"
#include "scenes/procedural_scenes.h"

namespace tandem {
namespace {

using namespace accstruc_test;

// Long thin triangles at random orientations in a box: the case where
// boxes of whole triangles overlap most.
void sliver_soup(uint32_t n, uint32_t seed, std::vector<Vec3>* positions,
                 std::vector<KTriangle>* triangles) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f), s(-4.0f, 4.0f), w(-0.05f, 0.05f);
  for (uint32_t i = 0; i < n; ++i) {
    const Vec3 a{u(rng), u(rng), u(rng)};
    const Vec3 d{s(rng), s(rng), s(rng)};
    const Vec3 e{w(rng), w(rng), w(rng)};
    const uint32_t v = uint32_t(positions->size());
    positions->push_back(a);
    positions->push_back(a + d);
    positions->push_back(a + d * 0.5f + e);
    triangles->push_back({v, v + 1, v + 2, 0});
  }
}

bool inside(const Aabb& in, const Aabb& out) {
  return in.lo.x >= out.lo.x && in.lo.y >= out.lo.y && in.lo.z >= out.lo.z && in.hi.x <= out.hi.x &&
         in.hi.y <= out.hi.y && in.hi.z <= out.hi.z;
}

TEST(SpatialBvh, ListsEveryTriangleWithinTheBudget) {
  std::vector<Vec3> positions;
  std::vector<KTriangle> triangles;
  sliver_soup(20000, 5, &positions, &triangles);
  const MeshGeometry g{positions.data(), uint32_t(positions.size()), triangles.data(),
                       uint32_t(triangles.size())};
  const std::vector<Aabb> boxes = triangle_boxes(g);
  BuildSettings s;
  s.spatial_split_budget = 0.3f;
  const BuildTree tree = build_bvh_spatial(boxes, positions, triangles, s);
  const BuildTree plain = build_bvh(boxes, s);
  ASSERT_FALSE(tree.empty());
  ASSERT_EQ(tree.ref_boxes.size(), tree.prims.size());
  const size_t n = triangles.size();
  EXPECT_GT(tree.prims.size(), n);  // some triangles were split
  EXPECT_LE(tree.prims.size(), n + size_t(0.3 * double(n)));
  std::vector<uint32_t> seen(n, 0);
  for (size_t e = 0; e < tree.prims.size(); ++e) {
    ASSERT_LT(tree.prims[e], n);
    ++seen[tree.prims[e]];
    EXPECT_TRUE(inside(tree.ref_boxes[e], boxes[tree.prims[e]])) << e;
  }
  for (size_t t = 0; t < n; ++t)
    ASSERT_GE(seen[t], 1u) << t;
  // Ranges: a subtree's entries are contiguous and its box holds them; a
  // leaf never lists a triangle twice.
  for (const BuildNode& node : tree.nodes) {
    for (uint32_t e = node.first; e < node.first + node.count; ++e)
      ASSERT_TRUE(inside(tree.ref_boxes[e], node.box));
    if (node.is_leaf()) {
      EXPECT_LE(node.count, s.max_leaf_size);
      std::vector<uint32_t> ids(tree.prims.begin() + node.first,
                                tree.prims.begin() + node.first + node.count);
      std::sort(ids.begin(), ids.end());
      EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
    } else {
      const BuildNode& l = tree.nodes[node.child[0]];
      const BuildNode& r = tree.nodes[node.child[1]];
      EXPECT_EQ(l.first, node.first);
      EXPECT_EQ(r.first, l.first + l.count);
      EXPECT_EQ(l.count + r.count, node.count);
    }
  }
  // Not worse by the SAH than the tree without splits (on this soup the
  // budget buys few splits: most slivers straddle the planes at the levels
  // where they would pay).
  EXPECT_LE(sah_cost(tree, 1.0f, 1.0f), sah_cost(plain, 1.0f, 1.0f));
  // Layouts and their structural check accept it.
  const BvhLayouts layouts = make_layouts(tree, boxes, kWideMaxLeafPrims, 1.0f, 1.0f);
  EXPECT_TRUE(validate_layouts(layouts, uint32_t(n)));
}

// The budget is handed down by sizes, not claimed by whichever task comes
// first: the same tree on one thread as on several (the BVH cache relies
// on it).
TEST(SpatialBvh, SameTreeWhateverTheThreads) {
  std::vector<Vec3> positions;
  std::vector<KTriangle> triangles;
  sliver_soup(30000, 7, &positions, &triangles);
  const MeshGeometry g{positions.data(), uint32_t(positions.size()), triangles.data(),
                       uint32_t(triangles.size())};
  const std::vector<Aabb> boxes = triangle_boxes(g);
  BuildSettings s;
  s.spatial_split_budget = 1.0f;
  BuildTree one, many;
  tbb::task_arena(1).execute([&] { one = build_bvh_spatial(boxes, positions, triangles, s); });
  tbb::task_arena(4).execute([&] { many = build_bvh_spatial(boxes, positions, triangles, s); });
  EXPECT_GT(one.prims.size(), triangles.size());
  EXPECT_EQ(one.prims, many.prims);
  ASSERT_EQ(one.ref_boxes.size(), many.ref_boxes.size());
  EXPECT_EQ(0, std::memcmp(one.ref_boxes.data(), many.ref_boxes.data(),
                           one.ref_boxes.size() * sizeof(Aabb)));
}

// Spatial splits on for the AccelStructures made in its scope; the
// environment's value comes back after it.
class SpatialSplitsOn {
 public:
  SpatialSplitsOn() {
    if (const char* v = std::getenv("TANDEM_BVH_SPATIAL_SPLITS")) old_ = v, had_ = true;
    ::setenv("TANDEM_BVH_SPATIAL_SPLITS", "0.3", 1);
  }
  ~SpatialSplitsOn() {
    if (had_) {
      ::setenv("TANDEM_BVH_SPATIAL_SPLITS", old_.c_str(), 1);
    } else {
      ::unsetenv("TANDEM_BVH_SPATIAL_SPLITS");
    }
  }

 private:
  std::string old_;
  bool had_ = false;
};

void expect_embree_hits(TracedScene& s, const std::string& name) {
  expect_hits_like_embree(s, "spatial " + name, 10000, 0.999);
}

TEST(SpatialBvh, SameHitsAsEmbree) {
  const SpatialSplitsOn on;
  {
    TracedScene s(make_procedural_scene(60'000, 3));
    // Some BLAS were split: more entries than triangles.
    size_t entries = 0;
    for (uint32_t m = 0; m < s.ks.meshes.size(); ++m)
      entries += s.accel.blas(m).prims.size();
    EXPECT_GT(entries, s.scene.triangle_count_unique());
    expect_embree_hits(s, "procedural");
  }
  const std::filesystem::path file = std::filesystem::path(TANDEM_SHARED_DIR) / "scenes" / "gltf" /
                                     "FlightHelmet" / "glTF" / "FlightHelmet.gltf";
  ASSERT_TRUE(std::filesystem::exists(file));
  TracedScene s(load_scene(file.string()));
  expect_embree_hits(s, "FlightHelmet");
}

// A scene of one sliver soup mesh of `tris` triangles (which gets split
// references), marked as deforming or not.
Scene sliver_soup_scene(uint32_t tris, bool deforms) {
  std::vector<Vec3> positions;
  std::vector<KTriangle> triangles;
  sliver_soup(tris, 9, &positions, &triangles);
  Mesh soup;
  soup.name = "soup";
  for (const Vec3& p : positions)
    soup.positions.push_back({p.x, p.y, p.z});
  for (const KTriangle& t : triangles)
    soup.triangles.push_back({t.v0, t.v1, t.v2});
  soup.triangle_materials.assign(triangles.size(), 0);
  Scene scene;
  scene.add_material(Material{});
  const uint32_t mesh = scene.add_mesh(std::move(soup));
  if (deforms) scene.set_mesh_deforms(mesh);
  scene.add_instance({"soup", mesh, glm::mat4(1.0f)});
  return scene;
}

void wave_soup(Scene& scene, uint32_t frame) {
  for (glm::vec3& p : scene.edit_mesh_vertices(0).positions)
    p.y += 0.01f * std::sin(p.x + float(frame));
}

TEST(SpatialBvh, ADeformingMeshIsRebuiltWithoutSplitsThenRefit) {
  const SpatialSplitsOn on;
  TracedScene s(sliver_soup_scene(20000, false));
  const size_t tris = 20000;
  ASSERT_GT(s.accel.blas(0).prims.size(), tris);  // split
  for (uint32_t frame = 1; frame <= 4; ++frame) {
    wave_soup(s.scene, frame);
    const AccelUpdate up = s.recompile();
    if (frame == 1) {
      // Rebuilt once, without splits: each triangle listed once.
      EXPECT_EQ(up.blas_refit_rebuilt, 1u);
      EXPECT_EQ(up.blas_refit, 0u);
      EXPECT_EQ(s.accel.blas(0).prims.size(), tris);
    } else {
      EXPECT_EQ(up.blas_refit, 1u) << frame;
      EXPECT_EQ(up.blas_refit_rebuilt, 0u) << frame;
    }
  }
  expect_embree_hits(s, "soup");
}

// Splits are the default for static meshes; a mesh its loader marks as
// deforming (Scene::set_mesh_deforms, kMeshDeforms) is built without them
// from the start, so its first deformed frame is a refit, not a rebuild.
TEST(SpatialBvh, StaticMeshesAreSplitByDefaultAndMarkedDeformingOnesBuiltToRefit) {
  ASSERT_EQ(std::getenv("TANDEM_BVH_SPATIAL_SPLITS"), nullptr) << "the test checks the default";
  const uint32_t tris = 20000;
  TracedScene fixed(sliver_soup_scene(tris, false));
  EXPECT_GT(fixed.accel.blas(0).prims.size(), tris);
  TracedScene moving(sliver_soup_scene(tris, true));
  EXPECT_NE(moving.ks.meshes[0].flags & kMeshDeforms, 0u);
  EXPECT_EQ(moving.accel.blas(0).prims.size(), tris);
  for (uint32_t frame = 1; frame <= 3; ++frame) {
    wave_soup(moving.scene, frame);
    const AccelUpdate up = moving.recompile();
    EXPECT_EQ(up.blas_refit, 1u) << frame;
    EXPECT_EQ(up.blas_refit_rebuilt, 0u) << frame;
  }
  expect_embree_hits(moving, "deforming soup");
}

}  // namespace
}  // namespace tandem
