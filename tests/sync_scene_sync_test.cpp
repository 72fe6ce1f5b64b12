// SceneSync: one update brings the compiler's arrays and the BVH up to date,
// and every consumer gets exactly what changed since the generation it has.
#include <gtest/gtest.h>

#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <stdexcept>
#include <vector>

#include "core/kernel/bvh_traverse.h"
#include "scenes/deforming_grid.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

SceneSyncSettings no_disk_cache() {
  SceneSyncSettings s;
  s.accel.cache.enabled = false;  // tests never write to ~/.cache
  return s;
}

// Two flat grids side by side (x = -3 and x = +3), facing +z.
Scene two_grids() {
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(
      make_wave_grid(WaveGrid{.cells = 8, .size = 2.0f, .amplitude = 0.0f, .wavelength = 1.0f}));
  scene.add_instance({"left", 0, glm::translate(glm::mat4(1.0f), glm::vec3(-3, 0, 0))});
  scene.add_instance({"right", 0, glm::translate(glm::mat4(1.0f), glm::vec3(3, 0, 0))});
  return scene;
}

// The instance our BVH finds straight down the y axis above (x, z), or
// kInvalidIndex.
uint32_t instance_below(const SceneSync& sync, float x, float z) {
  const KernelData kd = sync.view();
  const Ray ray{{x, 10.0f, z}, 0.0f, {0.0f, -1.0f, 0.0f}, 100.0f};
  return BvhTracer{&kd}.intersect(ray, 0u).instance;
}

void move_instance(Scene& scene, uint32_t instance, glm::vec3 to) {
  scene.set_instance_transform(instance, glm::translate(glm::mat4(1.0f), to));
}

TEST(SceneSync, FirstUpdateIsEverythingAndAQuietOneIsNothing) {
  Scene scene = two_grids();
  SceneSync sync(no_disk_cache());
  EXPECT_EQ(sync.generation(), 0u);
  EXPECT_TRUE(sync.changes_since(0).full);
  const SceneSyncUpdate& first = sync.update(scene, RenderSettings{});
  EXPECT_EQ(first.generation, 1u);
  EXPECT_TRUE(first.changes.full);
  EXPECT_TRUE(first.changes.bvh_nodes.any()) << "the BVH's arrays are in the same changes";
  EXPECT_EQ(first.accel.blas_built, 1u);
  EXPECT_EQ(instance_below(sync, 3.0f, 0.0f), 1u);

  const SceneSyncUpdate& quiet = sync.update(scene, RenderSettings{});
  EXPECT_EQ(quiet.generation, 2u);
  EXPECT_FALSE(quiet.changes.any());
  EXPECT_FALSE(sync.changes_since(1).any());
  EXPECT_FALSE(sync.changes_since(2).any());
  EXPECT_TRUE(sync.changes_since(0).full) << "a consumer that has seen nothing gets everything";
}

TEST(SceneSync, EachConsumerGetsTheChangesSinceItsOwnGeneration) {
  Scene scene = two_grids();
  SceneSync sync(no_disk_cache());
  sync.update(scene, RenderSettings{});
  const uint64_t behind = sync.generation();  // a consumer that skips a frame

  move_instance(scene, 0, {-3, 0, 5});
  const SceneSyncUpdate& a = sync.update(scene, RenderSettings{});
  EXPECT_EQ(a.changes.instances_moved, std::vector<uint32_t>{0});
  EXPECT_TRUE(a.changes.instances.any());
  EXPECT_TRUE(a.changes.bvh_nodes.any()) << "the TLAS moved with it";
  const uint64_t ahead = sync.generation();  // a consumer that synced this one

  move_instance(scene, 1, {3, 0, 5});
  sync.update(scene, RenderSettings{});
  const SceneDelta late = sync.changes_since(ahead);
  EXPECT_EQ(late.instances_moved, std::vector<uint32_t>{1});
  EXPECT_FALSE(late.full);
  const SceneDelta both = sync.changes_since(behind);
  EXPECT_EQ(both.instances_moved, (std::vector<uint32_t>{0, 1}));
  EXPECT_TRUE(both.instances.any());
  EXPECT_FALSE(both.full);
  EXPECT_EQ(instance_below(sync, -3.0f, 5.0f), 0u);
  EXPECT_EQ(instance_below(sync, 3.0f, 5.0f), 1u);
  EXPECT_EQ(instance_below(sync, 3.0f, 0.0f), kInvalidIndex);
}

TEST(SceneSync, AConsumerBeyondTheHistoryGetsEverythingAndNoneIsAhead) {
  Scene scene = two_grids();
  SceneSync sync(no_disk_cache());
  sync.update(scene, RenderSettings{});
  for (int i = 0; i < 40; ++i) {
    move_instance(scene, 0, {-3, 0, float(i)});
    sync.update(scene, RenderSettings{});
  }
  EXPECT_TRUE(sync.changes_since(1).full);
  EXPECT_FALSE(sync.changes_since(sync.generation() - 1).full);
  EXPECT_THROW(sync.changes_since(sync.generation() + 1), std::logic_error);
}

// While no consumer traces the BVH it is left alone; the first update that
// needs it again brings it to the scene as every skipped update would have.
TEST(SceneSync, ABvhNotNeededCatchesUpWhenNeededAgain) {
  Scene scene = two_grids();
  SceneSync sync(no_disk_cache());
  sync.update(scene, RenderSettings{});
  const std::vector<KBvhNode> nodes = sync.kernel_scene().bvh_nodes;
  sync.set_bvh_needed(false);
  move_instance(scene, 0, {-3, 0, 5});
  const SceneSyncUpdate& skipped = sync.update(scene, RenderSettings{});
  EXPECT_TRUE(skipped.changes.instances.any());
  EXPECT_FALSE(skipped.changes.bvh_nodes.any());
  ASSERT_EQ(sync.kernel_scene().bvh_nodes.size(), nodes.size());
  EXPECT_EQ(std::memcmp(nodes.data(), sync.kernel_scene().bvh_nodes.data(),
                        nodes.size() * sizeof(KBvhNode)),
            0)
      << "the BVH was not touched";
  WaveGrid moved{.cells = 8, .size = 2.0f, .amplitude = 0.3f, .wavelength = 1.0f};
  deform_wave_grid(scene.edit_mesh_vertices(0), moved, 0.25f);
  sync.update(scene, RenderSettings{});

  sync.set_bvh_needed(true);
  const SceneSyncUpdate& caught_up = sync.update(scene, RenderSettings{});
  EXPECT_TRUE(caught_up.changes.bvh_nodes.any());
  EXPECT_EQ(caught_up.accel.blas_refit + caught_up.accel.blas_built, 1u)
      << "the deformation it missed";
  EXPECT_EQ(instance_below(sync, -3.0f, 5.0f), 0u);
  EXPECT_EQ(instance_below(sync, -3.0f, 0.0f), kInvalidIndex);

  // The same as a scene synced from scratch, ray for ray.
  Scene copy = scene;
  SceneSync fresh(no_disk_cache());
  fresh.update(copy, RenderSettings{});
  for (float x = -4.0f; x <= 4.0f; x += 0.37f) {
    for (float z = -1.5f; z <= 6.5f; z += 0.41f)
      EXPECT_EQ(instance_below(sync, x, z), instance_below(fresh, x, z)) << x << ", " << z;
  }
}

TEST(SceneSync, ArraysOnlyBuildsNoBvh) {
  Scene scene = two_grids();
  SceneSync sync(SceneSyncSettings::arrays_only());
  const SceneSyncUpdate& up = sync.update(scene, RenderSettings{});
  EXPECT_FALSE(sync.has_bvh());
  EXPECT_EQ(sync.accel(), nullptr);
  EXPECT_TRUE(up.changes.instances.any());
  EXPECT_TRUE(sync.kernel_scene().bvh_nodes.empty());
  EXPECT_EQ(up.accstruc_seconds, 0.0);
}

}  // namespace
}  // namespace tandem
