// AccelStructure::update across frames: refit after deforming a mesh (same
// hits as a fresh build and as Embree on the deformed mesh), instance-only
// frames that rebuild just the TLAS, and the changed ranges it reports for
// delta uploads.
#include <glm/gtc/matrix_transform.hpp>

#include <cstring>

#include "accstruc_test_util.h"
#include "scenes/builtin_scenes.h"
#include "scenes/procedural_scenes.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

using namespace accstruc_test;

constexpr uint32_t kRays = 8000;

// Twists and ripples a mesh in place (vertex count kept): a real
// deformation, boxes change shape, not just position.
void deform(Mesh& m, float amount) {
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const glm::vec3& p : m.positions)
    lo = glm::min(lo, p), hi = glm::max(hi, p);
  const glm::vec3 c = 0.5f * (lo + hi);
  const float h = std::max(hi.y - lo.y, 1e-3f);
  for (glm::vec3& p : m.positions) {
    const float a = amount * (p.y - c.y) / h;
    const float x = p.x - c.x, z = p.z - c.z;
    p.x = c.x + x * std::cos(a) - z * std::sin(a);
    p.z = c.z + x * std::sin(a) + z * std::cos(a);
    p.y += 0.1f * amount * h * std::sin(7.0f * x / h);
  }
}

// Our closest hits in both layouts against a reference function.
void expect_same_hits(const TracedScene& s, const std::function<Hit(const RaySample&)>& reference,
                      const char* what) {
  const KernelData kd = s.kd();
  const DistanceTolerance tol = distance_tolerance(s.bounds);
  const auto primary = primary_rays(s, kRays, 11);
  const auto diffuse = diffuse_rays(s, kRays, 12);
  for (uint32_t layout = 0; layout < 2; ++layout) {
    auto ours = [&](const RaySample& r) { return bvh_intersect(kd, r.ray, r.alpha_key, layout); };
    const Agreement p = compare_closest(kd, tol, primary, ours, reference);
    const Agreement d = compare_closest(kd, tol, diffuse, ours, reference);
    std::printf("[accstruc] %-34s %-6s primary %s\n", what, layout_name(layout),
                p.summary().c_str());
    std::printf("[accstruc] %-34s %-6s diffuse %s\n", what, layout_name(layout),
                d.summary().c_str());
    EXPECT_GE(p.fraction(), 0.999) << what;
    EXPECT_GE(d.fraction(), 0.999) << what;
    EXPECT_GT(p.hits, kRays / 10) << what;
  }
}

TEST(AccelUpdate, RefitMatchesFreshBuildAndEmbree) {
  Scene scene = make_procedural_scene(150000, 21);
  // The largest instanced rock mesh and the (single-instance) terrain, built
  // as meshes that deform (without spatial splits, so that they can be refit).
  uint32_t rock = 0;
  for (uint32_t m = 0; m < scene.meshes().size(); ++m) {
    if (scene.meshes()[m].name == "rock") rock = m;
  }
  const uint32_t terrain = 0;
  ASSERT_EQ(scene.meshes()[terrain].name, "terrain");
  scene.set_mesh_deforms(rock);
  scene.set_mesh_deforms(terrain);
  TracedScene s(std::move(scene));
  const uint32_t rock_tris = uint32_t(s.scene.meshes()[rock].triangles.size());
  const double sah_before = s.accel.blas(rock).sah_cost;

  // Within the refit quality bound (refit_too_poor()): a twist of 1.5
  // radians degrades the rock's tree past it and rebuilds it instead.
  deform(s.scene.edit_mesh_vertices(rock), 0.4f);
  deform(s.scene.edit_mesh_vertices(terrain), 0.3f);
  const size_t nodes_before = s.ks.bvh_nodes.size();
  SceneDelta delta;
  const AccelUpdate up = s.recompile(&delta);
  EXPECT_EQ(up.blas_refit, 2u);
  EXPECT_EQ(up.blas_built, 0u);
  EXPECT_TRUE(up.tlas_rebuilt || up.tlas_refit);
  // Refit keeps sizes and places: no reallocation, only the two meshes'
  // node ranges and the TLAS are rewritten; no primitive order changes
  // except the TLAS's (and not even that when the TLAS was refit too).
  EXPECT_EQ(s.ks.bvh_nodes.size(), nodes_before);
  EXPECT_FALSE(up.delta.bvh_nodes.reallocated);
  EXPECT_FALSE(up.delta.bvh_prim_indices.reallocated);
  const uint32_t first_root =
      std::min(s.ks.blas_roots[rock].bvh_root, s.ks.blas_roots[terrain].bvh_root);
  EXPECT_EQ(up.delta.bvh_nodes.begin, first_root);
  EXPECT_EQ(up.delta.bvh_nodes.end,
            uint32_t(s.ks.bvh_nodes.size()) -
                (uint32_t(s.ks.instances.size()) - 1 - uint32_t(s.accel.tlas().nodes.size())));
  if (up.delta.bvh_prim_indices.any()) {
    EXPECT_GE(up.delta.bvh_prim_indices.begin,
              uint32_t(s.ks.bvh_prim_indices.size() - s.ks.instances.size()));
  }
  EXPECT_TRUE(delta.bvh_nodes.any());

  // The refit tree is valid and still holds the right primitives.
  EXPECT_TRUE(validate_layouts(s.accel.blas(rock), rock_tris));
  const double sah_after = s.accel.blas(rock).sah_cost;
  FreshBuild fresh(s.ks);
  std::printf(
      "[accstruc] refit: rock SAH cost as built %.2f; after deformation the fresh build gives "
      "%.2f\n",
      sah_before, fresh.accel.blas(rock).sah_cost);
  (void)sah_after;

  const KernelData fresh_kd = fresh.ks.view();
  expect_same_hits(
      s,
      [&](const RaySample& r) {
        return bvh_intersect(fresh_kd, r.ray, r.alpha_key, kBvhLayoutBinary);
      },
      "refit vs fresh build");
  expect_same_hits(
      s, [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); },
      "refit vs Embree");
}

// A BLAS's wide leaf entries in the kernel arrays name the binary layout's
// leaf records (bvh.h), which hold the same triangle: checked entry by entry,
// as built and after a frame that refits one mesh and rebuilds another
// (whose arrays are emitted again).
void expect_wide_entries_name_leaf_records(const TracedScene& s, const char* what) {
  uint32_t base = 0;  // both layouts' primitive bases (layout_arrays: equal sizes)
  for (uint32_t m = 0; m < s.ks.meshes.size(); ++m) {
    const BvhLayouts& l = s.accel.blas(m);
    ASSERT_EQ(l.prims.size(), l.wide_prims.size()) << what;
    for (size_t j = 0; j < l.wide_prims.size(); ++j) {
      const uint32_t e = s.ks.bvh_wide_prim_indices[base + j];
      ASSERT_TRUE(e >= base && e < base + l.prims.size())
          << what << " mesh " << m << " entry " << j;
      ASSERT_EQ(s.ks.bvh_prim_indices[e], l.wide_prims[j]) << what << " mesh " << m;
      if (s.ks.blas_roots[m].flags & kBlasNoLeafRecords) continue;  // traced by index
      ASSERT_EQ(float_as_uint(s.ks.bvh_leaf_triangles[e].p0.w), l.wide_prims[j]) << what;
    }
    base += uint32_t(l.prims.size());
  }
}

TEST(AccelUpdate, WideEntriesNameTheBinaryLeafRecords) {
  TracedScene s(make_procedural_scene(40000, 5));
  expect_wide_entries_name_leaf_records(s, "as built");
  // A light deformation refits the terrain; a heavy one rebuilds the rock.
  uint32_t rock = 0;
  for (uint32_t m = 0; m < s.scene.meshes().size(); ++m) {
    if (s.scene.meshes()[m].name == "rock") rock = m;
  }
  deform(s.scene.edit_mesh_vertices(0), 0.2f);
  deform(s.scene.edit_mesh_vertices(rock), 3.0f);
  const AccelUpdate up = s.recompile();
  EXPECT_GE(up.blas_refit + up.blas_built, 2u);
  expect_wide_entries_name_leaf_records(s, "after a refit and a rebuild");
  expect_same_hits(
      s, [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); },
      "wide entries after an update vs Embree");
}

TEST(AccelUpdate, MovingInstancesRebuildsOnlyTheTlas) {
  TracedScene s(make_procedural_scene(80000, 22));
  const std::vector<KBvhNode> blas_nodes(s.ks.bvh_nodes.begin(), s.ks.bvh_nodes.end());
  const uint32_t instances = uint32_t(s.ks.instances.size());
  for (uint32_t i = 0; i < instances; i += 7) {
    const glm::mat4 t = s.scene.instances()[i].transform;
    s.scene.set_instance_transform(
        i, glm::translate(glm::mat4(1.0f), glm::vec3(3.0f, 1.0f, -2.0f)) * t);
  }
  const AccelUpdate up = s.recompile();
  EXPECT_EQ(up.blas_built + up.blas_refit + up.blas_loaded, 0u);
  EXPECT_TRUE(up.tlas_rebuilt || up.tlas_refit);
  EXPECT_FALSE(up.delta.bvh_nodes.reallocated);
  EXPECT_FALSE(up.delta.blas_roots.any());
  // Only the TLAS region (the end of each array) changed.
  const uint32_t tlas_nodes_begin = uint32_t(s.ks.bvh_nodes.size()) - (instances - 1);
  EXPECT_GE(up.delta.bvh_nodes.begin, tlas_nodes_begin);
  if (up.delta.bvh_prim_indices.any()) {  // a refit keeps the leaves' order
    EXPECT_GE(up.delta.bvh_prim_indices.begin, uint32_t(s.ks.bvh_prim_indices.size()) - instances);
  }
  EXPECT_GE(up.delta.bvh_wide_nodes.begin, uint32_t(s.ks.bvh_wide_nodes.size()) - (instances - 1));
  EXPECT_EQ(0, std::memcmp(blas_nodes.data(), s.ks.bvh_nodes.data(),
                           tlas_nodes_begin * sizeof(KBvhNode)));
  expect_same_hits(
      s, [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); },
      "moved instances vs Embree");
}

TEST(AccelUpdate, UnchangedFrameTouchesNothingAndLayoutSwitches) {
  TracedScene s(make_procedural_scene(20000, 23));
  AccelUpdate up = s.recompile();
  EXPECT_FALSE(up.tlas_rebuilt);
  EXPECT_FALSE(up.delta.bvh_nodes.any() || up.delta.bvh_wide_nodes.any() ||
               up.delta.blas_roots.any() || up.delta.bvh_constants);
  s.accel.set_layout(kBvhLayoutWide);
  up = s.recompile();
  EXPECT_TRUE(up.delta.bvh_constants);
  EXPECT_EQ(s.ks.bvh.layout, uint32_t(kBvhLayoutWide));
  const KernelData kd = s.kd();
  const BvhTracer tracer{&kd};
  for (const RaySample& r : primary_rays(s, 500, 5)) {
    EXPECT_EQ(tracer.intersect(r.ray, r.alpha_key).prim,
              bvh_intersect(kd, r.ray, r.alpha_key, kBvhLayoutWide).prim);
  }
}

TEST(AccelUpdate, TlasOfThousandsOfInstances) {
  // Many instances of a few meshes, then every instance moves each frame.
  Scene scene;
  scene.add_material(Material{});
  const uint32_t a = scene.add_mesh(make_uv_sphere(1.0f, 8, 16, 0, false));
  const uint32_t b = scene.add_mesh(make_uv_sphere(0.5f, 4, 8, 0, true));
  TestRandom rng(3);
  for (uint32_t i = 0; i < 5000; ++i) {
    const float uz = rng.uniform(), uy = rng.uniform(), ux = rng.uniform();
    const glm::vec3 p(ux * 200.0f, uy * 20.0f, uz * 200.0f);
    scene.add_instance({"i", i % 3 ? a : b, glm::translate(glm::mat4(1.0f), p)});
  }
  TracedScene s(std::move(scene));
  // Instances drifting together: the TLAS is refit, not rebuilt.
  for (int frame = 0; frame < 3; ++frame) {
    for (uint32_t i = 0; i < 5000; ++i) {
      const glm::mat4 t = s.scene.instances()[i].transform;
      s.scene.set_instance_transform(
          i, glm::translate(glm::mat4(1.0f), glm::vec3(0.5f, 0.0f, 0.25f)) * t);
    }
    const AccelUpdate up = s.recompile();
    EXPECT_TRUE(up.tlas_refit);
    EXPECT_FALSE(up.tlas_rebuilt);
    EXPECT_FALSE(up.delta.bvh_prim_indices.any());
    std::printf("[accstruc] TLAS refit of 5000 instances (binary + wide): %.3f ms\n",
                up.tlas_seconds * 1e3);
  }
  expect_same_hits(
      s, [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); },
      "5000 refit instances vs Embree");
  // Instances scattering: a refit tree would overlap badly, so it is rebuilt.
  for (uint32_t i = 0; i < 5000; ++i) {
    const float uz = rng.uniform(), uy = rng.uniform(), ux = rng.uniform();
    const glm::vec3 p(ux * 200.0f, uy * 20.0f, uz * 200.0f);
    s.scene.set_instance_transform(i, glm::translate(glm::mat4(1.0f), p));
  }
  const AccelUpdate up = s.recompile();
  EXPECT_TRUE(up.tlas_rebuilt);
  std::printf("[accstruc] TLAS rebuild of 5000 instances (binary + wide): %.3f ms\n",
              up.tlas_seconds * 1e3);
  EXPECT_TRUE(validate_layouts(s.accel.tlas(), 5000));
  expect_same_hits(
      s, [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); },
      "5000 rebuilt instances vs Embree");
}

}  // namespace
}  // namespace tandem

namespace tandem {
namespace {

// The TLAS refit of only the moved instances' paths against the full refit
// of every instance: the same kernel arrays bit for bit, frame after frame,
// and the same decision to rebuild once the instances scatter.
TEST(AccelUpdate, PartialTlasRefitEqualsTheFullRefit) {
  Scene scene;
  scene.add_material(Material{});
  const uint32_t a = scene.add_mesh(make_uv_sphere(1.0f, 6, 8, 0, false));
  const uint32_t b = scene.add_mesh(make_uv_sphere(0.5f, 4, 6, 0, true));
  TestRandom rng(5);
  for (uint32_t i = 0; i < 700; ++i) {
    const float uz = rng.uniform(), uy = rng.uniform(), ux = rng.uniform();
    const glm::vec3 p(ux * 80.0f, uy * 8.0f, uz * 80.0f);
    scene.add_instance({"i", i % 4 ? a : b, glm::translate(glm::mat4(1.0f), p)});
  }
  Scene full_scene = scene;
  RenderSettings settings;
  SceneCompiler partial_compiler, full_compiler;
  KernelScene partial_ks, full_ks;
  AccelStructure partial_accel, full_accel;
  partial_accel.update(partial_ks,
                       compile_taking_changes(partial_compiler, scene, settings, partial_ks));
  full_accel.update(full_ks, compile_taking_changes(full_compiler, full_scene, settings, full_ks));
  for (int frame = 0; frame < 40; ++frame) {
    const bool scatter = frame == 30;
    const uint32_t moves = scatter ? 700 : 1 + uint32_t(rng.uniform() * 60.0f);
    for (uint32_t k = 0; k < moves; ++k) {
      const uint32_t i = scatter ? k : std::min(699u, uint32_t(rng.uniform() * 700.0f));
      const float uz = rng.uniform(), ux = rng.uniform();
      const glm::vec3 step = scatter ? glm::vec3(ux * 80.0f - 40.0f, 0.0f, uz * 80.0f - 40.0f)
                                     : glm::vec3(ux - 0.5f, 0.0f, uz - 0.5f);
      const glm::mat4 t = glm::translate(glm::mat4(1.0f), step) * scene.instances()[i].transform;
      scene.set_instance_transform(i, t);
      full_scene.set_instance_transform(i, t);
    }
    const SceneDelta partial_delta =
        compile_taking_changes(partial_compiler, scene, settings, partial_ks);
    SceneDelta full_delta = compile_taking_changes(full_compiler, full_scene, settings, full_ks);
    ASSERT_FALSE(partial_delta.instances_moved.empty());
    full_delta.instances_moved.clear();  // the updater then refits every instance
    const AccelUpdate p = partial_accel.update(partial_ks, partial_delta);
    const AccelUpdate f = full_accel.update(full_ks, full_delta);
    ASSERT_EQ(p.tlas_refit, f.tlas_refit) << "frame " << frame;
    ASSERT_EQ(p.tlas_rebuilt, f.tlas_rebuilt) << "frame " << frame;
    if (scatter) {
      EXPECT_TRUE(p.tlas_rebuilt);
    }
    if (frame == 0) {
      EXPECT_TRUE(p.tlas_refit);
    }
#define TANDEM_EXPECT_SAME_BVH(T, name)                              \
  ASSERT_EQ(partial_ks.name.size(), full_ks.name.size()) << #name;   \
  EXPECT_EQ(std::memcmp(partial_ks.name.data(), full_ks.name.data(), \
                        partial_ks.name.size() * sizeof(T)),         \
            0)                                                       \
      << #name << " differs in frame " << frame;
    TANDEM_BVH_ARRAYS(TANDEM_EXPECT_SAME_BVH)
#undef TANDEM_EXPECT_SAME_BVH
    EXPECT_EQ(std::memcmp(&partial_ks.bvh, &full_ks.bvh, sizeof(KBvhConstants)), 0);
    if (::testing::Test::HasFailure()) return;
    // The partial refit reports at most the full refit's ranges.
    if (p.tlas_refit) {
      EXPECT_GE(p.delta.bvh_nodes.begin, f.delta.bvh_nodes.begin);
      EXPECT_LE(p.delta.bvh_nodes.end, f.delta.bvh_nodes.end);
    }
  }
}

}  // namespace
}  // namespace tandem
