// BlasRefit, the per-frame refit of deforming meshes: the same nodes as the
// general refit (refit_layouts() + emit_refit_nodes()) in both layouts and
// the same quality, written into the kernel arrays with the same spans, for
// whole-mesh and partial deformations, over a tree large enough to be cut
// into many tasks; a member turning invalid (or a non-member valid) asks
// for a rebuild; AccelStructure's frames take this path.
#include <glm/gtc/matrix_transform.hpp>

#include <cmath>
#include <cstring>

#include "accstruc/blas_refit.h"
#include "accstruc/wide_bvh.h"
#include "accstruc_test_util.h"
#include "scenes/deforming_grid.h"

namespace tandem {
namespace {

using namespace accstruc_test;

// A BLAS over a mesh, and the kernel-array copies the two refits write.
struct Blas {
  std::vector<Vec3> positions;  // one extra, as KernelScene has
  std::vector<KTriangle> triangles;
  BvhLayouts layouts;
  LayoutBases bases{7, 11, 5, 13};  // not at the array starts
  std::vector<KBvhNode> nodes;
  std::vector<uint32_t> prims;
  std::vector<KWideBvhNode> wide;
  std::vector<uint32_t> wide_prims;

  explicit Blas(const Mesh& m) {
    for (const glm::vec3& p : m.positions)
      positions.push_back({p.x, p.y, p.z});
    positions.push_back({0, 0, 0});
    for (const glm::uvec3& t : m.triangles)
      triangles.push_back({t.x, t.y, t.z, 0});
    const std::vector<Aabb> boxes = triangle_boxes(geometry());
    layouts = make_layouts(build_bvh(boxes, BuildSettings{}), boxes, kWideMaxLeafPrims, 1.0f, 1.0f);
    nodes.resize(bases.node + layouts.nodes.size());
    prims.resize(bases.prim + layouts.prims.size());
    wide.resize(bases.wide_node + layouts.wide_nodes.size());
    wide_prims.resize(bases.wide_prim + layouts.wide_prims.size());
    emit_layouts(layouts, bases, nodes.data() + bases.node, prims.data() + bases.prim,
                 wide.data() + bases.wide_node, wide_prims.data() + bases.wide_prim);
  }
  MeshGeometry geometry() const {
    return {positions.data(), uint32_t(positions.size() - 1), triangles.data(),
            uint32_t(triangles.size())};
  }
  void set(const Mesh& m) {
    for (size_t v = 0; v < m.positions.size(); ++v)
      positions[v] = {m.positions[v].x, m.positions[v].y, m.positions[v].z};
  }
};

// Floats equal as numbers (a union taken in another order may give a zero
// the other sign), every other byte equal.
bool same_wide(const KWideBvhNode& a, const KWideBvhNode& b) {
  return a.origin.x == b.origin.x && a.origin.y == b.origin.y && a.origin.z == b.origin.z &&
         std::memcmp(a.exponent, b.exponent, 4) == 0 && a.child_base == b.child_base &&
         a.prim_base == b.prim_base && std::memcmp(a.meta, b.meta, 8 + 48) == 0;
}

void expect_same_arrays(const Blas& a, const Blas& b, const char* what) {
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  for (size_t i = 0; i < a.nodes.size(); ++i) {
    ASSERT_EQ(std::memcmp(&a.nodes[i], &b.nodes[i], sizeof(KBvhNode)), 0)
        << what << ": binary node " << i;
  }
  for (size_t i = 0; i < a.layouts.nodes.size(); ++i) {
    ASSERT_EQ(std::memcmp(&a.layouts.nodes[i], &b.layouts.nodes[i], sizeof(KBvhNode)), 0)
        << what << ": host binary node " << i;
  }
  ASSERT_EQ(a.wide.size(), b.wide.size());
  for (size_t i = 0; i < a.wide.size(); ++i)
    ASSERT_TRUE(same_wide(a.wide[i], b.wide[i])) << what << ": wide node " << i;
  for (size_t i = 0; i < a.layouts.wide_nodes.size(); ++i) {
    ASSERT_TRUE(same_wide(a.layouts.wide_nodes[i], b.layouts.wide_nodes[i]))
        << what << ": host wide node " << i;
  }
  EXPECT_EQ(std::memcmp(&a.layouts.bounds, &b.layouts.bounds, sizeof(Aabb)), 0) << what;
}

TEST(BlasRefit, EqualsTheGeneralRefitFrameAfterFrame) {
  // 2 x 180 x 180 triangles: a hundred tasks and nodes above them.
  WaveGrid g{.cells = 180, .size = 6.0f, .amplitude = 0.1f, .wavelength = 1.3f};
  Mesh mesh = make_wave_grid(g);
  Blas general(mesh), fast(mesh);
  BlasRefit refit;
  ASSERT_TRUE(refit.index(fast.layouts, fast.geometry()));
  for (uint32_t frame = 1; frame <= 6; ++frame) {
    if (frame < 6) {
      g.amplitude = 0.1f + 0.3f * float(frame);
      deform_wave_grid(mesh, g, 0.1f * float(frame));
    } else {
      // A partial edit: one run of vertices; most of the tree keeps its boxes.
      for (uint32_t v = 9000; v < 9040; ++v)
        mesh.positions[v].y *= 0.5f;
    }
    general.set(mesh);
    fast.set(mesh);
    const double q_general = refit_layouts(general.layouts, triangle_boxes(general.geometry()));
    const NodeSpans s_general =
        emit_refit_nodes(general.layouts, general.bases, general.nodes.data() + general.bases.node,
                         general.wide.data() + general.bases.wide_node);
    const BlasRefit::Result r =
        refit.refit(fast.layouts, fast.geometry(), fast.bases, fast.nodes.data() + fast.bases.node,
                    fast.wide.data() + fast.bases.wide_node);
    EXPECT_FALSE(r.members_changed) << "frame " << frame;
    EXPECT_NEAR(r.quality, q_general, 1e-9 * q_general) << "frame " << frame;
    EXPECT_NEAR(r.quality, refit_quality(fast.layouts), 1e-9 * q_general) << "frame " << frame;
    EXPECT_EQ(r.spans.nodes.begin, s_general.nodes.begin) << "frame " << frame;
    EXPECT_EQ(r.spans.nodes.end, s_general.nodes.end) << "frame " << frame;
    EXPECT_EQ(r.spans.wide_nodes.begin, s_general.wide_nodes.begin) << "frame " << frame;
    EXPECT_EQ(r.spans.wide_nodes.end, s_general.wide_nodes.end) << "frame " << frame;
    expect_same_arrays(general, fast, "frame");
    if (frame == 6) {
      EXPECT_LT(r.spans.nodes.end - r.spans.nodes.begin, fast.layouts.nodes.size() / 4);
    }
  }
  // The same pose again: nothing to write, empty spans.
  const BlasRefit::Result again =
      refit.refit(fast.layouts, fast.geometry(), fast.bases, fast.nodes.data() + fast.bases.node,
                  fast.wide.data() + fast.bases.wide_node);
  EXPECT_EQ(again.spans.nodes.end, 0u);
  EXPECT_EQ(again.spans.wide_nodes.end, 0u);
}

TEST(BlasRefit, SmallTreesAndSplitLeavesToo) {
  // From a single leaf (one node, an empty second child) to a few nodes:
  // the wide leaves split binary leaves of four into three and one.
  for (uint32_t cells : {1u, 2u, 3u, 5u, 9u}) {
    WaveGrid g{.cells = cells, .size = 2.0f, .amplitude = 0.2f, .wavelength = 0.7f};
    Mesh mesh = make_wave_grid(g);
    Blas general(mesh), fast(mesh);
    BlasRefit refit;
    ASSERT_TRUE(refit.index(fast.layouts, fast.geometry())) << cells;
    deform_wave_grid(mesh, g, 0.3f);
    general.set(mesh);
    fast.set(mesh);
    refit_layouts(general.layouts, triangle_boxes(general.geometry()));
    emit_refit_nodes(general.layouts, general.bases, general.nodes.data() + general.bases.node,
                     general.wide.data() + general.bases.wide_node);
    refit.refit(fast.layouts, fast.geometry(), fast.bases, fast.nodes.data() + fast.bases.node,
                fast.wide.data() + fast.bases.wide_node);
    expect_same_arrays(general, fast, "small grid");
  }
}

TEST(BlasRefit, MembersChangingAskForARebuild) {
  WaveGrid g{.cells = 20, .size = 2.0f, .amplitude = 0.2f, .wavelength = 0.7f};
  Mesh mesh = make_wave_grid(g);
  // Vertex 0 starts as NaN: its triangle is left out of the build.
  mesh.positions[0].x = std::nanf("");
  Blas fast(mesh);
  ASSERT_EQ(fast.layouts.prims.size(), mesh.triangles.size() - 1);
  BlasRefit refit;
  ASSERT_TRUE(refit.index(fast.layouts, fast.geometry()));
  const auto run = [&] {
    return refit.refit(fast.layouts, fast.geometry(), fast.bases,
                       fast.nodes.data() + fast.bases.node,
                       fast.wide.data() + fast.bases.wide_node);
  };
  EXPECT_FALSE(run().members_changed);
  // The left-out triangle becomes valid: it must join, by a rebuild.
  fast.positions[0].x = -1.0f;
  EXPECT_TRUE(run().members_changed);
  fast.positions[0].x = std::nanf("");
  EXPECT_FALSE(run().members_changed);
  // A member becomes invalid (infinite, or beyond kMaxCoordinate).
  fast.positions[200].y = INFINITY;
  EXPECT_TRUE(run().members_changed);
  fast.positions[200].y = 2.0f * kMaxCoordinate;
  EXPECT_TRUE(run().members_changed);
  fast.positions[200].y = 0.0f;
  EXPECT_FALSE(run().members_changed);
}

TEST(BlasRefit, AccelStructureRefitsThroughItAndReportsWhatItWrote) {
  WaveGrid g{.cells = 100, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(make_wave_grid(g));
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  TracedScene s(std::move(scene));
  for (uint32_t frame = 1; frame <= 3; ++frame) {
    const KernelScene before = s.ks;
    deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.1f * float(frame));
    SceneDelta delta;
    const AccelUpdate up = s.recompile(&delta);
    ASSERT_EQ(up.blas_refit, 1u);
    // The arrays hold exactly the refit host copy ...
    const BvhLayouts& l = s.accel.blas(0);
    const uint32_t root = s.ks.blas_roots[0].bvh_root, wroot = s.ks.blas_roots[0].wide_root;
    std::vector<KBvhNode> nodes(s.ks.bvh_nodes.size());
    std::vector<uint32_t> prims(s.ks.bvh_prim_indices.size());
    std::vector<KWideBvhNode> wide(s.ks.bvh_wide_nodes.size());
    std::vector<uint32_t> wide_prims(s.ks.bvh_wide_prim_indices.size());
    emit_layouts(l, {root, 0, wroot, 0}, nodes.data() + root, prims.data(), wide.data() + wroot,
                 wide_prims.data());
    EXPECT_EQ(std::memcmp(nodes.data() + root, s.ks.bvh_nodes.data() + root,
                          l.nodes.size() * sizeof(KBvhNode)),
              0);
    EXPECT_EQ(std::memcmp(wide.data() + wroot, s.ks.bvh_wide_nodes.data() + wroot,
                          l.wide_nodes.size() * sizeof(KWideBvhNode)),
              0);
    // ... which is what a refit of the last frame's from scratch gives.
    BvhLayouts expected = l;
    refit_layouts(expected, triangle_boxes(mesh_geometry(s.ks, 0)));
    for (size_t i = 0; i < l.nodes.size(); ++i)
      ASSERT_EQ(std::memcmp(&expected.nodes[i], &l.nodes[i], sizeof(KBvhNode)), 0) << i;
    for (size_t i = 0; i < l.wide_nodes.size(); ++i)
      ASSERT_TRUE(same_wide(expected.wide_nodes[i], l.wide_nodes[i])) << i;
    // Every BLAS node outside the reported span kept its bytes.
    ASSERT_TRUE(up.delta.bvh_nodes.any());
    std::vector<uint8_t> reported(s.ks.bvh_nodes.size(), 0);
    up.delta.bvh_nodes.for_each_range([&](uint32_t b, uint32_t e) {
      for (uint32_t i = b; i < e; ++i)
        reported[i] = 1;
    });
    for (uint32_t i = root; i < root + l.nodes.size(); ++i) {
      if (!reported[i]) {
        ASSERT_EQ(std::memcmp(&before.bvh_nodes[i], &s.ks.bvh_nodes[i], sizeof(KBvhNode)), 0);
      }
    }
  }
}

}  // namespace
}  // namespace tandem
