// The scene's cached bounds and the compiler's incremental light update
// against full recomputations: after random edits (instances moved,
// mesh vertices changed, objects added, materials and lights changed) the
// cache must give exactly what a walk over every triangle gives, and an
// incrementally compiled scene what a fresh compile gives.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

Mesh random_mesh(std::mt19937& rng, uint32_t triangles) {
  std::uniform_real_distribution<float> pos(-3.0f, 3.0f);
  Mesh m;
  for (uint32_t t = 0; t < triangles; ++t) {
    for (int k = 0; k < 3; ++k)
      m.positions.push_back({pos(rng), pos(rng), pos(rng)});
    m.triangles.push_back({3 * t, 3 * t + 1, 3 * t + 2});
    m.triangle_materials.push_back(0);
  }
  // A vertex no triangle uses: the bounds must ignore it.
  m.positions.push_back({100.0f, 100.0f, 100.0f});
  return m;
}

glm::mat4 random_transform(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const float tz = u(rng), ty = u(rng), tx = u(rng);
  glm::mat4 t = glm::translate(glm::mat4(1.0f), glm::vec3(10 * tx, 10 * ty, 10 * tz));
  const float az = u(rng), ay = u(rng), ax = u(rng), angle = u(rng);
  t = glm::rotate(t, 3.0f * angle, glm::normalize(glm::vec3(ax, ay, az) + 1e-3f));
  return glm::scale(t, glm::vec3(1.5f + u(rng)));
}

void expect_same_bounds(const SceneBounds& cached, const SceneBounds& full, int step) {
  ASSERT_EQ(cached.empty, full.empty) << "after edit " << step;
  if (full.empty) return;
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(cached.lo[a], full.lo[a]) << "after edit " << step << ", axis " << a;
    EXPECT_EQ(cached.hi[a], full.hi[a]) << "after edit " << step << ", axis " << a;
  }
}

TEST(SceneBoundsCache, EqualsAFullRecomputationAfterRandomEdits) {
  std::mt19937 rng(7);
  Scene scene;
  scene.add_material(Material{});
  EXPECT_TRUE(scene.bounds().empty);
  for (int m = 0; m < 5; ++m)
    scene.add_mesh(random_mesh(rng, 1 + m * 3));
  scene.add_mesh(Mesh{});  // instances of an empty mesh add nothing
  for (int i = 0; i < 37; ++i)
    scene.add_instance({"i", uint32_t(rng() % 6), random_transform(rng)});
  expect_same_bounds(scene.bounds(), compute_scene_bounds(scene.meshes(), scene.instances()), -1);
  for (int step = 0; step < 400; ++step) {
    const uint32_t what = rng() % 10;
    if (what < 6) {  // most frames move a few instances
      for (uint32_t k = 0, n = 1 + rng() % 4; k < n; ++k)
        scene.set_instance_transform(rng() % scene.instances().size(), random_transform(rng));
    } else if (what < 8) {
      const uint32_t m = rng() % 5;
      Mesh& mesh = scene.edit_mesh_vertices(m);
      mesh.positions[rng() % (mesh.positions.size() - 1)] *= 1.7f;
    } else if (what == 8) {
      scene.add_instance({"added", uint32_t(rng() % 6), random_transform(rng)});
    } else {
      const uint32_t m = scene.add_mesh(random_mesh(rng, 2));
      scene.add_instance({"added", m, random_transform(rng)});
    }
    // Not every edit is followed by a query: stale entries accumulate.
    if (rng() % 3 == 0) continue;
    expect_same_bounds(scene.bounds(), compute_scene_bounds(scene.meshes(), scene.instances()),
                       step);
    if (::testing::Test::HasFailure()) return;
  }
  // A copy carries its cache along and stays consistent on its own.
  Scene copy = scene;
  copy.set_instance_transform(0, random_transform(rng));
  expect_same_bounds(copy.bounds(), compute_scene_bounds(copy.meshes(), copy.instances()), 400);
  expect_same_bounds(scene.bounds(), compute_scene_bounds(scene.meshes(), scene.instances()), 400);
}

TEST(SceneBoundsCache, BoxesFromTheCompilersVertexCopyEqualTheTriangleWalk) {
  // Mesh 0 uses every vertex (its box can come from the compiler's copy of
  // the positions); mesh 1 leaves one far vertex unused (it cannot); both
  // hold zeros of both signs, whose order must not matter.
  std::mt19937 rng(3);
  Scene scene;
  scene.add_material(Material{});
  Mesh used = random_mesh(rng, 40);
  used.positions.pop_back();
  scene.add_mesh(used);
  scene.add_mesh(random_mesh(rng, 40));
  scene.add_instance({"a", 0, random_transform(rng)});
  scene.add_instance({"b", 1, glm::mat4(1.0f)});
  KernelScene ks;
  SceneCompiler compiler;
  const RenderSettings settings;
  compile_taking_changes(compiler, scene, settings, ks);
  const auto same_bits = [](const SceneBounds& a, const SceneBounds& b) {
    return a.empty == b.empty && std::memcmp(&a.lo, &b.lo, sizeof(a.lo)) == 0 &&
           std::memcmp(&a.hi, &b.hi, sizeof(a.hi)) == 0;
  };
  for (int frame = 0; frame < 20; ++frame) {
    for (uint32_t m = 0; m < 2; ++m) {
      Mesh& mesh = scene.edit_mesh_vertices(m);
      for (size_t v = 0; v + (m == 1 ? 1 : 0) < mesh.positions.size(); ++v) {
        mesh.positions[v] *= 0.9f + 0.2f * float(rng() % 100) / 100.0f;
        if (rng() % 7 == 0) mesh.positions[v].x = (rng() % 2) ? 0.0f : -0.0f;
      }
      if (frame == 10) mesh.positions.back().y = 50.0f;
    }
    // The compile copies every vertex of both meshes; its constants read
    // its own bounds, from the boxes it took as it copied.
    compile_taking_changes(compiler, scene, settings, ks);
    const SceneBounds cached = scene.bounds();
    const SceneBounds full = compute_scene_bounds(scene.meshes(), scene.instances());
    ASSERT_TRUE(same_bits(cached, full)) << "frame " << frame;
    ASSERT_EQ(ks.constants.scene_radius, full.radius()) << "frame " << frame;
    ASSERT_EQ(ks.constants.scene_center.x, full.center().x) << "frame " << frame;
  }
  // A box handed over and then outdated by another edit is not used; nor
  // is one for a mesh with unused vertices.
  const SceneBounds bogus{glm::vec3(-1000.0f), glm::vec3(1000.0f), false};
  SceneBoundsCache cache;
  for (uint32_t m = 0; m < 2; ++m)
    cache.mesh_added();
  for (const Instance& inst : scene.instances())
    cache.instance_added(inst.mesh);
  cache.bounds(scene.meshes(), scene.instances());  // learns which vertices are used
  scene.edit_mesh_vertices(0).positions[0] = glm::vec3(9.0f);
  cache.mesh_changed(0);
  cache.mesh_vertex_bounds(0, bogus);
  scene.edit_mesh_vertices(0).positions[1] = glm::vec3(-9.0f);
  cache.mesh_changed(0);
  scene.edit_mesh_vertices(1).positions[0] = glm::vec3(8.0f);
  cache.mesh_changed(1);
  cache.mesh_vertex_bounds(1, bogus);
  const SceneBounds cached = cache.bounds(scene.meshes(), scene.instances());
  EXPECT_TRUE(same_bits(cached, compute_scene_bounds(scene.meshes(), scene.instances())));
  EXPECT_LT(cached.hi.y, 1000.0f);
}

TEST(SceneDirtyLists, ListEachMarkedObjectOnceAndClearWithTheMasks) {
  Scene scene;
  scene.add_material(Material{});
  const uint32_t mesh = scene.add_mesh(Mesh{});
  for (int i = 0; i < 5; ++i)
    scene.add_instance({"i", mesh, glm::mat4(1.0f)});
  EXPECT_EQ(scene.dirty_instances().size(), 5u);
  scene.clear_dirty();
  EXPECT_FALSE(scene.any_dirty());
  scene.set_instance_transform(3, glm::mat4(2.0f));
  scene.set_instance_transform(1, glm::mat4(2.0f));
  scene.set_instance_transform(3, glm::mat4(3.0f));
  EXPECT_EQ(scene.dirty_instances(), (std::vector<uint32_t>{3, 1}));
  EXPECT_EQ(scene.instance_dirty()[3], uint32_t(kDirtyTransform));
  EXPECT_TRUE(scene.any_dirty());
  scene.clear_dirty();
  EXPECT_TRUE(scene.dirty_instances().empty());
  EXPECT_EQ(scene.instance_dirty()[3], 0u);
}

// Lights, materials and the environment changed one at a time (no instance
// moves, whose light-power refresh is deliberately lazy): the incremental
// compile must produce exactly the arrays of a fresh compile.
TEST(SceneCompilerIncremental, LightAndMaterialEditsGiveWhatAFreshCompileGives) {
  std::mt19937 rng(11);
  Scene scene = make_builtin_scene("cornell");
  Light sun;
  sun.type = LightType::kDirectional;
  sun.direction = {0.3f, -1.0f, 0.2f};
  scene.add_light(sun);
  Light spot;
  spot.type = LightType::kSpot;
  spot.position = {0.0f, 1.5f, 0.0f};
  scene.add_light(spot);
  scene.edit_environment().color = glm::vec3(0.2f);
  RenderSettings settings;
  settings.width = settings.height = 64;
  SceneCompiler incremental;
  KernelScene ks;
  compile_taking_changes(incremental, scene, settings, ks);
  std::uniform_real_distribution<float> u(0.1f, 2.0f);
  for (int step = 0; step < 60; ++step) {
    const uint32_t what = rng() % 4;
    if (what == 0) {
      scene.edit_light(rng() % scene.lights().size()).intensity = u(rng);
    } else if (what == 1) {
      const float green = u(rng), red = u(rng);
      scene.edit_light(rng() % scene.lights().size()).color = glm::vec3(red, green, 1.0f);
    } else if (what == 2) {
      scene.edit_material(rng() % scene.materials().size()).roughness = 0.5f * u(rng);
    } else {
      scene.edit_environment().intensity = u(rng);
    }
    const SceneDelta delta = compile_taking_changes(incremental, scene, settings, ks);
    EXPECT_FALSE(delta.full) << step;
    Scene copy = scene;
    SceneCompiler fresh;
    KernelScene fresh_ks;
    compile_taking_changes(fresh, copy, settings, fresh_ks);
    expect_same_scene_arrays(ks, fresh_ks, step);
    if (::testing::Test::HasFailure()) return;
  }
}

}  // namespace
}  // namespace tandem
