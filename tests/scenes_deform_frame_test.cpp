// The deformer in a frame loop: an unchanged pose is neither skinned nor
// refit again, and a pose skinned by the compiler straight into the kernel
// arrays gives the compiler's copy bit for bit while the Scene's own copy
// waits for a reader.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/kernel/host_isa.h"
#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/mesh_deformer.h"
#include "scenes/procedural_rigs.h"
#include "scenes/scene_animator.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

TEST(MeshDeformer, AnUnchangedPoseIsNeitherSkinnedNorRefitAgain) {
  Scene scene = make_skinned_grid_scene(40);
  auto animator = make_scene_animator(scene);
  SceneSync sync(SceneSyncSettings::arrays_only());
  const RenderSettings settings;
  sync.update(scene, settings);
  animator->pose(0.5, scene);
  ASSERT_TRUE(scene.mesh_dirty()[0] & kDirtyVertices);
  const uint64_t version = scene.mesh_vertex_version(0);
  EXPECT_EQ(sync.update(scene, settings).changes.meshes_refit.size(), 1u);
  // The same time again: the palette is bit for bit the last one and the
  // mesh holds what it wrote, so nothing is skinned, marked or refit.
  animator->pose(0.5, scene);
  EXPECT_TRUE(scene.dirty_meshes().empty());
  EXPECT_EQ(scene.mesh_vertex_version(0), version);
  const SceneDelta same = sync.update(scene, settings).changes;
  EXPECT_TRUE(same.meshes_refit.empty());
  EXPECT_FALSE(same.positions.any());
  // Someone else writes the mesh: the same pose is then written again.
  const std::vector<glm::vec3> posed = scene.meshes()[0].positions;
  scene.edit_mesh_vertices(0, 7, 1).positions[7].y += 1.0f;
  sync.update(scene, settings).changes;
  animator->pose(0.5, scene);
  EXPECT_TRUE(scene.mesh_dirty()[0] & kDirtyVertices);
  EXPECT_EQ(scene.meshes()[0].positions, posed);
  sync.update(scene, settings).changes;
  // Another time moves it as before.
  animator->pose(0.6, scene);
  EXPECT_TRUE(scene.mesh_dirty()[0] & kDirtyVertices);
  EXPECT_NE(scene.meshes()[0].positions, posed);
  // A copy of the scene holds the pose too: not written again there.
  sync.update(scene, settings).changes;
  Scene copy = scene;
  animator->pose(0.6, copy);
  EXPECT_TRUE(copy.dirty_meshes().empty());
}

// A posed mesh (Scene::pose_mesh, the animators' path) is skinned by the
// compiler straight into the kernel arrays, giving bit for bit the arrays,
// the delta and the bounds of the compiler's copy of the same vertices
// written into the Scene, while the Scene's own copy waits for a reader;
// and the copy is taken when the mesh had another edit since the last
// compile.
TEST(MeshDeformer, APoseSkinnedIntoTheKernelArraysEqualsTheCompilersCopy) {
  const DeformIsaChoice saved = deform_isa;
  for (const bool avx2 : {false, true})
    for (const char* name : {"skinned-grid", "arena"}) {
      if (avx2 && !host_cpu_has_avx2()) continue;
      deform_isa.avx2 = avx2;
      SCOPED_TRACE(std::string(name) + (avx2 ? " AVX2" : " baseline"));
      auto make = [&] {
        return std::string(name) == "arena" ? make_builtin_scene("arena")
                                            : make_skinned_grid_scene(60);
      };
      Scene a = make(), b = make();
      uint32_t rig = 0;  // a deforming mesh
      while (rig + 1 < a.meshes().size() && a.meshes()[rig].name.rfind("rig.", 0) != 0)
        ++rig;
      auto anim_a = make_scene_animator(a), anim_b = make_scene_animator(b);
      SceneSync sa(SceneSyncSettings::arrays_only()), sb(SceneSyncSettings::arrays_only());
      const KernelScene &ka = sa.kernel_scene(), &kb = sb.kernel_scene();
      const RenderSettings settings;
      size_t direct = 0;
      for (int f = 0; f < 6; ++f) {
        const double t = 0.1 + 0.23 * f;
        if (f == 3) {  // an edit before the pose: the copy path
          for (Scene* s : {&a, &b})
            s->edit_mesh_vertices(rig, 5, 2).positions[5].x += 0.25f;
        }
        anim_a->pose(t, a);
        anim_b->pose(t, b);
        // Scene a: every posed mesh written into the Scene (an edit of the
        // whole mesh writes the pose), so its compiler copies them.
        for (uint32_t m : std::vector<uint32_t>(a.dirty_meshes())) {
          if (a.mesh_pose_unwritten(m)) a.edit_mesh_vertices(m);
        }
        std::vector<uint32_t> posed;
        for (uint32_t m = 0; m < b.mesh_count() && f > 0; ++m) {
          if (b.compiled_pose(m) == nullptr) continue;
          EXPECT_FALSE(f == 3 && m == rig) << "the mesh had another edit";
          posed.push_back(m);
        }
        const SceneDelta da = sa.update(a, settings).changes;
        const SceneDelta db = sb.update(b, settings).changes;
        for (uint32_t m : posed) {
          ++direct;
          // The compile did not write the Scene's copy.
          EXPECT_TRUE(b.mesh_pose_unwritten(m)) << m;
        }
        auto same_bytes = [](const auto& x, const auto& y) {
          // (memcmp of an empty vector's null data() is undefined.)
          return x.size() == y.size() &&
                 (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0);
        };
        EXPECT_TRUE(same_bytes(ka.positions, kb.positions)) << f;
        EXPECT_TRUE(same_bytes(ka.normals, kb.normals)) << f;
        EXPECT_TRUE(same_bytes(ka.tangents, kb.tangents)) << f;
        EXPECT_TRUE(same_bytes(ka.uv0, kb.uv0)) << f;
        auto same_change = [](const ArrayChange& x, const ArrayChange& y) {
          std::vector<uint32_t> rx, ry;
          x.for_each_range([&](uint32_t b0, uint32_t e0) { rx.insert(rx.end(), {b0, e0}); });
          y.for_each_range([&](uint32_t b0, uint32_t e0) { ry.insert(ry.end(), {b0, e0}); });
          return rx == ry && x.reallocated == y.reallocated;
        };
        EXPECT_TRUE(same_change(da.positions, db.positions)) << f;
        EXPECT_TRUE(same_change(da.normals, db.normals)) << f;
        EXPECT_TRUE(same_change(da.tangents, db.tangents)) << f;
        EXPECT_EQ(da.meshes_refit, db.meshes_refit) << f;
        EXPECT_EQ(da.bytes(ka), db.bytes(kb)) << f;
        // The compiler's bounds (the constants) from the boxes it took.
        EXPECT_EQ(std::memcmp(&ka.constants, &kb.constants, sizeof ka.constants), 0) << f;
        const SceneBounds ba = a.bounds(), bb = b.bounds();
        EXPECT_EQ(std::memcmp(&ba.lo, &bb.lo, sizeof(ba.lo)), 0) << f;
        EXPECT_EQ(std::memcmp(&ba.hi, &bb.hi, sizeof(ba.hi)), 0) << f;
        for (uint32_t m = 0; m < a.meshes().size(); ++m)
          EXPECT_EQ(a.meshes()[m].positions, b.meshes()[m].positions) << m;
      }
      EXPECT_GT(direct, 0u) << "the direct path was never taken";
    }
  deform_isa = saved;
}

// The Scene's unwritten copy of a pose holds what it needs: read after the
// animator that posed it is gone, it is the pose, bit for bit that of a
// scene whose pose was written at once.
TEST(MeshDeformer, TheScenesCopyOfAPoseOutlivesItsAnimator) {
  Scene a = make_skinned_grid_scene(50), b = make_skinned_grid_scene(50);
  SceneSync sb(SceneSyncSettings::arrays_only());
  sb.update(b, RenderSettings{});
  make_scene_animator(a)->pose(0.7, a);
  a.meshes();
  make_scene_animator(b)->pose(0.7, b);
  sb.update(b, RenderSettings{});
  ASSERT_TRUE(b.mesh_pose_unwritten(0));
  EXPECT_EQ(a.meshes()[0].positions, b.meshes()[0].positions);
  EXPECT_EQ(a.meshes()[0].normals, b.meshes()[0].normals);
  EXPECT_FALSE(b.mesh_pose_unwritten(0));
  EXPECT_NE(b.meshes()[0].positions, make_skinned_grid_scene(50).meshes()[0].positions)
      << "not the bind pose";
}

}  // namespace
}  // namespace tandem
