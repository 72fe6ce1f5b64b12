// Deforming meshes in the scene compiler: an edited vertex range is all a
// compile converts and all its delta holds (and SceneDelta::bytes() counts),
// ranges merge, and the light tables of a deforming emissive mesh are
// updated in place yet equal a fresh compile of the deformed scene.
#include <gtest/gtest.h>

#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <stdexcept>

#include "core/world/kernel_scene.h"
#include "core/world/mesh_pose.h"
#include "scenes/deforming_grid.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

const WaveGrid kGrid{.cells = 48, .size = 4.0f, .amplitude = 0.2f, .wavelength = 1.3f};

// A wave grid (mesh 0, two instances) and a small static box-ish grid
// (mesh 1), both compiled once. The grid emits when `emissive`.
Scene grid_scene(bool emissive) {
  Scene s;
  Material m;
  m.base_color = glm::vec4(0.7f, 0.6f, 0.5f, 1.0f);
  if (emissive) m.emissive = glm::vec3(2.0f, 1.5f, 1.0f);
  s.add_material(m);
  s.add_material(Material{});
  s.add_mesh(make_wave_grid(kGrid));
  s.add_mesh(make_wave_grid(WaveGrid{.cells = 4, .size = 1.0f}, 1));
  s.add_instance({"a", 0, glm::mat4(1.0f)});
  s.add_instance({"b", 0,
                  glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 2.0f, 0.0f)), 0.7f,
                              glm::vec3(1.0f, 0.0f, 0.0f))});
  s.add_instance({"c", 1, glm::translate(glm::mat4(1.0f), glm::vec3(3.0f, 0.0f, 0.0f))});
  Light l;
  l.type = LightType::kPoint;
  l.position = glm::vec3(0.0f, 5.0f, 0.0f);
  l.intensity = 20.0f;
  s.add_light(l);
  return s;
}

TEST(SceneDeform, VertexRangeDeltaHoldsExactlyThatRange) {
  Scene scene = grid_scene(false);
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  compile_taking_changes(compiler, scene, settings, ks);
  const KMesh km = ks.meshes[0];
  const KernelScene before = ks;

  // One row and a half of the grid, somewhere in the middle.
  const uint32_t first = 1000, count = 75;
  Mesh& mesh = scene.edit_mesh_vertices(0, first, count);
  deform_wave_grid(mesh, kGrid, 0.37f, first, count);
  const SceneDelta d = compile_taking_changes(compiler, scene, settings, ks);

  const uint32_t b = km.vertex_offset + first, e = b + count;
  for (const ArrayChange* c : {&d.positions, &d.normals, &d.uv0}) {
    EXPECT_FALSE(c->reallocated);
    EXPECT_EQ(c->begin, b);
    EXPECT_EQ(c->end, e);
  }
  EXPECT_FALSE(d.full);
  EXPECT_FALSE(d.tangents.any() || d.uv1.any() || d.triangles.any() || d.meshes.any() ||
               d.instances.any() || d.lights.any() || d.light_alias.any());
  ASSERT_EQ(d.meshes_refit, std::vector<uint32_t>{0});
  EXPECT_TRUE(d.instances_changed());
  // What an upload of the delta moves: the range of three arrays and the
  // constants (the scene's bounds may have changed).
  EXPECT_EQ(d.bytes(ks), size_t(count) * (sizeof(Vec3) + sizeof(Vec3) + sizeof(Vec2)) +
                             (d.constants ? sizeof(KernelConstants) : 0));
  // Only those vertices were rewritten, and they hold the new positions.
  for (uint32_t v = 0; v < ks.vertex_count(); ++v) {
    const bool in = v >= b && v < e;
    const Vec3 p = ks.positions[v], q = before.positions[v];
    if (!in) {
      ASSERT_EQ(std::memcmp(&p, &q, sizeof p), 0) << "vertex " << v;
    } else {
      const glm::vec3& w = mesh.positions[v - km.vertex_offset];
      ASSERT_EQ(p.y, w.y) << "vertex " << v;
    }
  }
  EXPECT_TRUE(same_bytes(ks.triangles, before.triangles));

  // Two ranges of one frame merge into their bounding range; the arrays
  // then equal a fresh compile of the edited scene.
  scene.edit_mesh_vertices(0, 40, 10);
  deform_wave_grid(scene.edit_mesh_vertices(0, 2000, 5), kGrid, 0.5f, 2000, 5);
  deform_wave_grid(scene.edit_mesh_vertices(0, 40, 10), kGrid, 0.5f, 40, 10);
  scene.edit_mesh_vertices(0, 45, 0);  // marks nothing
  const SceneDelta d2 = compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_EQ(d2.positions.begin, km.vertex_offset + 40);
  EXPECT_EQ(d2.positions.end, km.vertex_offset + 2005);
  Scene copy = scene;
  KernelScene fresh;
  SceneCompiler fresh_compiler;
  compile_taking_changes(fresh_compiler, copy, settings, fresh);
  EXPECT_TRUE(same_bytes(ks.positions, fresh.positions));
  EXPECT_TRUE(same_bytes(ks.normals, fresh.normals));
  EXPECT_TRUE(same_bytes(ks.uv0, fresh.uv0));

  // The whole-mesh form still means every vertex; a bad range is refused.
  scene.edit_mesh_vertices(0);
  const SceneDelta d3 = compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_EQ(d3.positions.begin, km.vertex_offset);
  EXPECT_EQ(d3.positions.end, km.vertex_offset + km.vertex_count);
  EXPECT_THROW(scene.edit_mesh_vertices(0, kGrid.vertex_count() - 2, 3), std::out_of_range);
  EXPECT_THROW(scene.edit_mesh_vertices(7, 0, 1), std::out_of_range);
}

// Light list, triangle lights, alias tables and total power of `a` and
// `b`, bit for bit; the trees by what they bound (a refit keeps its build's
// shape).
void expect_same_light_tables(const KernelScene& a, const KernelScene& b, const char* what) {
  EXPECT_TRUE(same_bytes(a.lights, b.lights)) << what;
  EXPECT_TRUE(same_bytes(a.light_alias, b.light_alias)) << what;
  EXPECT_TRUE(same_bytes(a.triangle_lights, b.triangle_lights)) << what;
  EXPECT_TRUE(same_bytes(a.triangle_light_alias, b.triangle_light_alias)) << what;
  EXPECT_EQ(a.constants.total_light_power, b.constants.total_light_power) << what;
  EXPECT_EQ(a.constants.light_tree_fraction, b.constants.light_tree_fraction) << what;
  expect_light_trees_bound_their_lights(a, 0);
  expect_light_trees_bound_their_lights(b, 0);
}

class SceneDeformSampler : public ::testing::TestWithParam<LightSampler> {};

INSTANTIATE_TEST_SUITE_P(Samplers, SceneDeformSampler,
                         ::testing::Values(LightSampler::kPower, LightSampler::kTree),
                         [](const auto& info) {
                           return info.param == LightSampler::kTree ? "tree" : "power";
                         });

TEST_P(SceneDeformSampler, EmissiveLightTablesFollowTheDeformation) {
  Scene scene = grid_scene(true);
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  settings.light_sampler = GetParam();
  const bool tree = GetParam() == LightSampler::kTree;
  compile_taking_changes(compiler, scene, settings, ks);
  const std::vector<KAliasEntry> alias_before = ks.triangle_light_alias;
  const std::vector<KLightTreeNode> tree_before = ks.light_tree_nodes;
  const size_t light_count = ks.triangle_lights.size();
  ASSERT_EQ(light_count, 2u * 48 * 48);  // every grid triangle, once for both instances
  ASSERT_EQ(ks.lights.size(), 2u + 1u);  // the two instances and a punctual light

  for (int frame = 1; frame <= 5; ++frame) {
    // A growing wave: the triangles' areas (and so their powers) change.
    WaveGrid g = kGrid;
    g.amplitude = 0.2f + 0.15f * float(frame);
    deform_wave_grid(scene.edit_mesh_vertices(0), g, 0.1f * float(frame));
    const SceneDelta d = compile_taking_changes(compiler, scene, settings, ks);
    // Updated in place: the light lists keep their sizes and order, the
    // deformed triangles' cached vertices and normals, the instances'
    // powers and the mesh's table (or its tree, refit) are rewritten.
    EXPECT_TRUE(d.triangle_lights.any() && d.lights.any()) << "frame " << frame;
    EXPECT_FALSE(d.lights.reallocated || d.triangle_lights.reallocated) << "frame " << frame;
    EXPECT_TRUE((tree ? d.light_tree_nodes : d.triangle_light_alias).any()) << "frame " << frame;
    EXPECT_FALSE(d.light_alias.reallocated || d.light_tree_nodes.reallocated) << "frame " << frame;
    EXPECT_EQ(ks.triangle_lights.size(), light_count);
    Scene copy = scene;
    KernelScene fresh;
    SceneCompiler fresh_compiler;
    compile_taking_changes(fresh_compiler, copy, settings, fresh);
    expect_same_light_tables(ks, fresh, "deformed");
  }
  // The test saw a change.
  EXPECT_FALSE(tree ? same_bytes(tree_before, ks.light_tree_nodes)
                    : same_bytes(alias_before, ks.triangle_light_alias));

  // A triangle collapsing to zero area leaves the light list: the tables
  // are then rebuilt, and still equal a fresh compile.
  Mesh& m = scene.edit_mesh_vertices(0, 0, 2);
  m.positions[1] = m.positions[0];
  const SceneDelta d = compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_TRUE(d.triangle_lights.any());
  EXPECT_LT(ks.triangle_lights.size(), light_count);
  Scene copy = scene;
  KernelScene fresh;
  SceneCompiler fresh_compiler;
  compile_taking_changes(fresh_compiler, copy, settings, fresh);
  expect_same_light_tables(ks, fresh, "collapsed triangle");

  // A non-emissive mesh's deformation leaves the light tables alone.
  deform_wave_grid(scene.edit_mesh_vertices(1), WaveGrid{.cells = 4, .size = 1.0f}, 0.3f);
  const SceneDelta d4 = compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_TRUE(d4.positions.any());
  EXPECT_FALSE(d4.lights.any() || d4.light_alias.any() || d4.light_tree_nodes.any() ||
               d4.triangle_lights.any());
}

}  // namespace
}  // namespace tandem

namespace tandem {
namespace {

TEST(SceneDeform, ArrayChangeKeepsRangesApartAndMergesTheClosest) {
  ArrayChange c;
  c.mark(100, 110);
  c.mark(500, 520);
  c.mark(108, 130);  // overlaps the first
  c.mark(130, 140);  // touches it
  EXPECT_EQ(c.begin, 100u);
  EXPECT_EQ(c.end, 520u);
  ASSERT_EQ(c.range_count, 2u);
  EXPECT_EQ(c.ranges[0].end, 140u);
  EXPECT_EQ(c.element_count(), 40u + 20u);
  // Past kMaxRanges the two closest ranges merge: never an element lost.
  ArrayChange many;
  for (uint32_t i = 0; i < ArrayChange::kMaxRanges + 3; ++i)
    many.mark(1000 * i, 1000 * i + 10 + i);
  EXPECT_EQ(many.range_count, ArrayChange::kMaxRanges);
  std::vector<uint8_t> covered(20000, 0);
  many.for_each_range([&](uint32_t b, uint32_t e) {
    for (uint32_t i = b; i < e; ++i)
      covered[i] = 1;
  });
  for (uint32_t i = 0; i < ArrayChange::kMaxRanges + 3; ++i)
    for (uint32_t k = 1000 * i; k < 1000 * i + 10 + i; ++k)
      ASSERT_TRUE(covered[k]) << k;
  // Merging deltas keeps the ranges.
  SceneDelta a, b;
  a.positions.mark(0, 10);
  b.positions.mark(90, 100);
  a.merge(b);
  EXPECT_EQ(a.positions.element_count(), 20u);
  KernelScene ks;
  ks.positions.resize(100);
  EXPECT_EQ(a.bytes(ks), 20u * sizeof(Vec3));
}

// A wave-grid pose for Scene::pose_mesh, counting its writes: into the
// Scene's mesh, and into the kernel arrays (converted as the compiler
// converts a Mesh). `fail_kernel_write` makes the latter refuse, as a pose
// with a position that is not finite does.
class WaveGridPose final : public MeshPose {
 public:
  WaveGridPose(Mesh rest, float t, int* mesh_writes, int* kernel_writes,
               bool fail_kernel_write = false)
      : rest_(std::move(rest)),
        t_(t),
        mesh_writes_(mesh_writes),
        kernel_writes_(kernel_writes),
        fail_(fail_kernel_write) {}
  size_t vertex_count() const override { return rest_.positions.size(); }
  void write(Mesh& out) const override {
    ++*mesh_writes_;
    deform_wave_grid(out, kGrid, t_);
  }
  bool write(const MeshVertexTarget& target, SceneBounds* box) const override {
    ++*kernel_writes_;
    if (fail_) return false;
    Mesh posed = rest_;
    deform_wave_grid(posed, kGrid, t_);
    bool finite = true;
    *box = vertex_bounds(posed.positions.data(), posed.positions.size(), &finite);
    for (size_t v = 0; v < target.vertex_count; ++v) {
      target.positions[v] = {posed.positions[v].x, posed.positions[v].y, posed.positions[v].z};
      if (target.normals != nullptr)
        target.normals[v] = {posed.normals[v].x, posed.normals[v].y, posed.normals[v].z};
    }
    return finite;
  }

 private:
  Mesh rest_;
  float t_;
  int *mesh_writes_, *kernel_writes_;
  bool fail_;
};

// Scene::pose_mesh(): the compiler writes the pose straight into the kernel
// arrays (bit for bit the copy of the written mesh, its bounds included)
// and the Scene's copy is written once, only when something reads it
// (meshes(), an edit, bounds(), a copy of the scene); after another edit
// since the last compile, or a pose the kernel arrays cannot take, the
// compiler copies the written mesh instead.
TEST(SceneDeform, APoseIsWrittenIntoTheKernelArraysAndTheScenesCopyOnlyWhenRead) {
  Scene scene = grid_scene(false);
  SceneCompiler compiler;
  KernelScene ks;
  const RenderSettings settings;
  compile_taking_changes(compiler, scene, settings, ks);
  scene.bounds();  // the cache knows every vertex of the grid is used
  const Mesh rest = scene.meshes()[0];
  Mesh expected = rest;
  deform_wave_grid(expected, kGrid, 0.4f);
  int mesh_writes = 0, kernel_writes = 0;
  auto pose = [&](float t, bool fail = false) {
    return std::make_shared<WaveGridPose>(rest, t, &mesh_writes, &kernel_writes, fail);
  };

  const uint64_t version = scene.mesh_vertex_version(0);
  scene.pose_mesh(0, pose(0.9f));
  scene.pose_mesh(0, pose(0.4f));  // replaces the first
  EXPECT_TRUE(scene.mesh_pose_unwritten(0));
  EXPECT_NE(scene.compiled_pose(0), nullptr);
  EXPECT_NE(scene.mesh_vertex_version(0), version);
  EXPECT_TRUE(scene.mesh_dirty()[0] & kDirtyVertices);
  EXPECT_EQ(scene.mesh_dirty_vertices(0).end, scene.mesh_vertex_count(0));
  EXPECT_EQ(scene.mesh_count(), 2u);
  EXPECT_EQ(mesh_writes, 0) << "nothing read the vertices yet";
  EXPECT_THROW(scene.pose_mesh(1, pose(0.4f)), std::invalid_argument) << "another vertex count";

  // A copy holds the unwritten pose too, written on its own.
  Scene copy = scene;
  // The compiler writes the pose into `ks`, not into the Scene.
  const SceneDelta posed = compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_EQ(kernel_writes, 1);
  EXPECT_EQ(mesh_writes, 0);
  EXPECT_TRUE(scene.mesh_pose_unwritten(0));
  EXPECT_EQ(scene.compiled_pose(0), nullptr) << "taken by the compile";
  EXPECT_EQ(posed.meshes_refit, std::vector<uint32_t>{0});
  const KMesh& km = ks.meshes[0];
  EXPECT_EQ(std::memcmp(&ks.positions[km.vertex_offset + 7], &expected.positions[7], sizeof(Vec3)),
            0);
  // Bit for bit a fresh compile of the written mesh, bounds (constants)
  // included, though the compiler never looked at the Scene's copy.
  {
    Scene written = copy;
    written.meshes();
    SceneCompiler fresh_compiler;
    KernelScene fresh;
    compile_taking_changes(fresh_compiler, written, settings, fresh);
    EXPECT_TRUE(same_bytes(ks.positions, fresh.positions));
    EXPECT_TRUE(same_bytes(ks.normals, fresh.normals));
    EXPECT_EQ(std::memcmp(&ks.constants, &fresh.constants, sizeof ks.constants), 0);
  }
  EXPECT_EQ(mesh_writes, 1) << "the copy's pose";
  EXPECT_TRUE(same_bytes(scene.meshes()[0].positions, expected.positions));
  EXPECT_TRUE(same_bytes(scene.meshes()[0].normals, expected.normals));
  EXPECT_EQ(mesh_writes, 2) << "written once";
  scene.meshes();
  EXPECT_EQ(mesh_writes, 2);
  EXPECT_TRUE(copy.mesh_pose_unwritten(0));
  EXPECT_TRUE(same_bytes(copy.meshes()[0].positions, expected.positions));
  EXPECT_EQ(mesh_writes, 3);

  // An edit of a few vertices starts from the posed ones; the compile then
  // copies the mesh, and so does it for a pose after such an edit.
  scene.pose_mesh(0, pose(0.4f));
  scene.edit_mesh_vertices(0, 3, 1).positions[3].y += 1.0f;
  EXPECT_EQ(mesh_writes, 4);
  EXPECT_EQ(scene.compiled_pose(0), nullptr);
  EXPECT_EQ(scene.meshes()[0].positions[3].y, expected.positions[3].y + 1.0f);
  EXPECT_EQ(scene.meshes()[0].positions[4], expected.positions[4]);
  scene.pose_mesh(0, pose(0.4f));
  EXPECT_EQ(scene.compiled_pose(0), nullptr) << "another edit since the last compile";
  compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_EQ(kernel_writes, 1);
  EXPECT_EQ(mesh_writes, 5);
  EXPECT_EQ(std::memcmp(&ks.positions[km.vertex_offset + 3], &expected.positions[3], sizeof(Vec3)),
            0);
  scene.pose_mesh(0, pose(0.4f));
  EXPECT_EQ(scene.edit_mesh_vertices(0).positions[3], expected.positions[3]);  // the whole mesh
  EXPECT_EQ(mesh_writes, 6);
  compile_taking_changes(compiler, scene, settings, ks);

  // A pose the kernel arrays refuse: the compiler copies the written mesh.
  scene.pose_mesh(0, pose(0.9f, /*fail=*/true));
  compile_taking_changes(compiler, scene, settings, ks);
  EXPECT_EQ(kernel_writes, 2);
  EXPECT_EQ(mesh_writes, 7);
  EXPECT_EQ(std::memcmp(&ks.positions[km.vertex_offset + 7], &scene.meshes()[0].positions[7],
                        sizeof(Vec3)),
            0);

  // bounds() reads an unwritten pose.
  scene.pose_mesh(0, pose(0.4f));
  const SceneBounds b = scene.bounds();
  EXPECT_EQ(mesh_writes, 8);
  EXPECT_FALSE(scene.mesh_pose_unwritten(0));
  EXPECT_FALSE(b.empty);
}

}  // namespace
}  // namespace tandem
