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
#include "tests/world_compile_util.h"

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
  std::vector<KLeafTriangle> leaf;  // bvh_leaf_triangles, at bases.prim

  explicit Blas(const Mesh& m, const BuildSettings& build = {}) {
    for (const glm::vec3& p : m.positions)
      positions.push_back({p.x, p.y, p.z});
    positions.push_back({0, 0, 0});
    for (const glm::uvec3& t : m.triangles)
      triangles.push_back({t.x, t.y, t.z, 0});
    const std::vector<Aabb> boxes = triangle_boxes(geometry());
    layouts = make_layouts(build_bvh(boxes, build), boxes, kWideMaxLeafPrims, 1.0f, 1.0f);
    nodes.resize(bases.node + layouts.nodes.size());
    prims.resize(bases.prim + layouts.prims.size());
    wide.resize(bases.wide_node + layouts.wide_nodes.size());
    wide_prims.resize(bases.wide_prim + layouts.wide_prims.size());
    emit_layouts(layouts, bases, nodes.data() + bases.node, prims.data() + bases.prim,
                 wide.data() + bases.wide_node, wide_prims.data() + bases.wide_prim);
    leaf = expected_leaf_records();
  }
  // The records as AccelStructure writes them at a layout (and its second
  // pass over the leaves rewrote them after a refit): the binary leaves'
  // triangles in order, with their current vertices and index.
  std::vector<KLeafTriangle> expected_leaf_records() const {
    std::vector<KLeafTriangle> r(bases.prim + layouts.prims.size());
    for (size_t e = 0; e < layouts.prims.size(); ++e) {
      const uint32_t t = layouts.prims[e];
      const Vec3 a = positions[triangles[t].v0], b = positions[triangles[t].v1],
                 c = positions[triangles[t].v2];
      r[bases.prim + e] = {
          {a.x, a.y, a.z, uint_as_float(t)}, {b.x, b.y, b.z, 0}, {c.x, c.y, c.z, 0}};
    }
    return r;
  }
  BlasRefit::Result refit_with(const BlasRefit& refit, bool records = true,
                               bool overwrite = false) {
    return refit.refit(layouts, geometry(), bases, nodes.data() + bases.node,
                       wide.data() + bases.wide_node, records ? leaf.data() + bases.prim : nullptr,
                       overwrite);
  }
  void sync_host() {
    BlasRefit::copy_boxes_to_host(layouts, nodes.data() + bases.node,
                                  wide.data() + bases.wide_node);
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
    const std::vector<KLeafTriangle> leaf_before = fast.leaf;
    const BlasRefit::Result r = fast.refit_with(refit);
    // The refit leaves the host copy as it was; copied back, it is what the
    // general (eager) refit made of its own.
    if (frame < 6) {
      EXPECT_NE(std::memcmp(&fast.layouts.nodes[0], &general.layouts.nodes[0], sizeof(KBvhNode)), 0)
          << "frame " << frame;
    }
    fast.sync_host();
    EXPECT_FALSE(r.members_changed) << "frame " << frame;
    EXPECT_NEAR(r.quality, q_general, 1e-9 * q_general) << "frame " << frame;
    EXPECT_NEAR(r.quality, refit_quality(fast.layouts), 1e-9 * q_general) << "frame " << frame;
    EXPECT_EQ(r.spans.nodes.begin, s_general.nodes.begin) << "frame " << frame;
    EXPECT_EQ(r.spans.nodes.end, s_general.nodes.end) << "frame " << frame;
    EXPECT_EQ(r.spans.wide_nodes.begin, s_general.wide_nodes.begin) << "frame " << frame;
    EXPECT_EQ(r.spans.wide_nodes.end, s_general.wide_nodes.end) << "frame " << frame;
    expect_same_arrays(general, fast, "frame");
    // The leaf records written in the leaf pass are the second pass's, and
    // every record outside the reported spans kept its bytes.
    const std::vector<KLeafTriangle> records = fast.expected_leaf_records();
    ASSERT_EQ(std::memcmp(records.data(), fast.leaf.data(), records.size() * sizeof(KLeafTriangle)),
              0)
        << "frame " << frame;
    std::vector<uint8_t> reported(fast.layouts.prims.size(), 0);
    for (const NodeSpan& span : r.leaf_spans) {
      for (uint32_t e = span.begin; e < span.end; ++e)
        reported[e] = 1;
    }
    for (size_t e = 0; e < reported.size(); ++e) {
      if (!reported[e]) {
        ASSERT_EQ(std::memcmp(&leaf_before[fast.bases.prim + e], &fast.leaf[fast.bases.prim + e],
                              sizeof(KLeafTriangle)),
                  0)
            << "frame " << frame << ", record " << e;
      }
    }
    ASSERT_FALSE(r.leaf_spans.empty());
    if (frame == 6) {
      size_t count = 0;
      for (uint8_t x : reported)
        count += x;
      EXPECT_LT(count, fast.layouts.prims.size() / 4);
      EXPECT_LT(r.spans.nodes.end - r.spans.nodes.begin, fast.layouts.nodes.size() / 4);
    }
  }
  // The same pose again: nothing to write, empty spans.
  const BlasRefit::Result again = fast.refit_with(refit);
  EXPECT_EQ(again.spans.nodes.end, 0u);
  EXPECT_EQ(again.spans.wide_nodes.end, 0u);
  EXPECT_TRUE(again.leaf_spans.empty());
}

TEST(BlasRefit, OverwrittenRecordsAreTheComparedOnesAndAllReported) {
  // Every vertex moved (AccelStructure's case when the delta holds the
  // mesh's whole vertex range): the streamed records, boxes and node spans
  // are those of the compared refit, and the spans cover every record.
  WaveGrid g{.cells = 180, .size = 6.0f, .amplitude = 0.1f, .wavelength = 1.3f};
  Mesh mesh = make_wave_grid(g);
  Blas compared(mesh), streamed(mesh);
  BlasRefit refit;
  ASSERT_TRUE(refit.index(streamed.layouts, streamed.geometry()));
  for (uint32_t frame = 1; frame <= 4; ++frame) {
    g.amplitude = 0.1f + 0.3f * float(frame);
    deform_wave_grid(mesh, g, 0.1f * float(frame));
    compared.set(mesh);
    streamed.set(mesh);
    const BlasRefit::Result a = compared.refit_with(refit);
    const BlasRefit::Result b = streamed.refit_with(refit, true, true);
    compared.sync_host();
    streamed.sync_host();
    EXPECT_FALSE(b.members_changed) << "frame " << frame;
    EXPECT_EQ(a.quality, b.quality) << "frame " << frame;
    EXPECT_EQ(a.spans.nodes.begin, b.spans.nodes.begin) << "frame " << frame;
    EXPECT_EQ(a.spans.nodes.end, b.spans.nodes.end) << "frame " << frame;
    expect_same_arrays(compared, streamed, "frame");
    const std::vector<KLeafTriangle> records = streamed.expected_leaf_records();
    ASSERT_EQ(
        std::memcmp(records.data(), streamed.leaf.data(), records.size() * sizeof(KLeafTriangle)),
        0)
        << "frame " << frame;
    std::vector<uint8_t> reported(streamed.layouts.prims.size(), 0);
    for (const NodeSpan& span : b.leaf_spans) {
      for (uint32_t e = span.begin; e < span.end; ++e)
        reported[e] = 1;
    }
    for (size_t e = 0; e < reported.size(); ++e)
      ASSERT_TRUE(reported[e]) << "frame " << frame << ", record " << e;
  }
}

TEST(BlasRefit, WithoutTheWideLayoutTheBinaryNodesAndRecordsAreTheSame) {
  // No wide nodes to re-quantise: the leaf pass keeps one box per binary
  // leaf instead of one per triangle. The binary nodes, records (the
  // triangle's index in p0.w included), spans, bounds and quality are those
  // of the refit with both layouts, compared and streamed, frame after frame
  // (a hundred tasks, the nodes above them, leaves of one to four).
  WaveGrid g{.cells = 180, .size = 6.0f, .amplitude = 0.1f, .wavelength = 1.3f};
  Mesh mesh = make_wave_grid(g);
  for (const bool overwrite : {false, true}) {
    Blas both(mesh), binary(mesh);
    BlasRefit refit;
    ASSERT_TRUE(refit.index(binary.layouts, binary.geometry()));
    for (uint32_t frame = 1; frame <= 4; ++frame) {
      g.amplitude = 0.1f + 0.3f * float(frame);
      deform_wave_grid(mesh, g, 0.1f * float(frame));
      both.set(mesh);
      binary.set(mesh);
      const BlasRefit::Result a = both.refit_with(refit, true, overwrite);
      const BlasRefit::Result b = refit.refit(binary.layouts, binary.geometry(), binary.bases,
                                              binary.nodes.data() + binary.bases.node, nullptr,
                                              binary.leaf.data() + binary.bases.prim, overwrite);
      EXPECT_FALSE(b.members_changed) << frame;
      EXPECT_EQ(a.quality, b.quality) << frame;
      EXPECT_EQ(a.spans.nodes.begin, b.spans.nodes.begin) << frame;
      EXPECT_EQ(a.spans.nodes.end, b.spans.nodes.end) << frame;
      EXPECT_EQ(b.spans.wide_nodes.end, 0u) << frame;
      ASSERT_EQ(a.leaf_spans.size(), b.leaf_spans.size()) << frame;
      for (size_t i = 0; i < a.leaf_spans.size(); ++i) {
        EXPECT_EQ(a.leaf_spans[i].begin, b.leaf_spans[i].begin) << frame;
        EXPECT_EQ(a.leaf_spans[i].end, b.leaf_spans[i].end) << frame;
      }
      ASSERT_EQ(
          std::memcmp(both.nodes.data(), binary.nodes.data(), both.nodes.size() * sizeof(KBvhNode)),
          0)
          << "overwrite " << overwrite << ", frame " << frame;
      const std::vector<KLeafTriangle> records = binary.expected_leaf_records();
      ASSERT_EQ(
          std::memcmp(records.data(), binary.leaf.data(), records.size() * sizeof(KLeafTriangle)),
          0)
          << "overwrite " << overwrite << ", frame " << frame;
      EXPECT_EQ(std::memcmp(&both.layouts.bounds, &binary.layouts.bounds, sizeof(Aabb)), 0);
    }
    // A vertex gone to NaN still asks for a rebuild.
    binary.positions[binary.triangles[7].v1].y = std::nanf("");
    EXPECT_TRUE(refit
                    .refit(binary.layouts, binary.geometry(), binary.bases,
                           binary.nodes.data() + binary.bases.node, nullptr,
                           binary.leaf.data() + binary.bases.prim, overwrite)
                    .members_changed);
  }
}

TEST(BlasRefit, WithoutRecordsOrWideNodesEachLeafsVerticesGiveTheSameBits) {
  // A mesh that deforms whole and is traced in binary alone: the leaf pass
  // takes each binary leaf's box from its distinct vertices, once each. The
  // nodes, spans, bounds and quality are the general refit's bit for bit,
  // for the default leaves and the deforming meshes' larger ones, also when
  // a leaf's box meets +0 and -0 on an axis (minps keeps the last of equal
  // inputs, so the vertices' order decides which zero a box keeps).
  const BuildSettings deforming = AccelSettings{}.deforming_blas;
  for (const BuildSettings& build : {BuildSettings{}, deforming}) {
    WaveGrid g{.cells = 150, .size = 6.0f, .amplitude = 0.1f, .wavelength = 1.3f};
    Mesh mesh = make_wave_grid(g);
    Blas general(mesh, build), fast(mesh, build);
    BlasRefit refit;
    ASSERT_TRUE(refit.index(fast.layouts, fast.geometry()));
    for (uint32_t frame = 1; frame <= 4; ++frame) {
      g.amplitude = 0.1f + 0.3f * float(frame);
      deform_wave_grid(mesh, g, 0.1f * float(frame));
      if (frame % 2 == 0) {
        // Flat, with zeros of both signs mixed (a hash of the vertex).
        for (size_t v = 0; v < mesh.positions.size(); ++v) {
          const uint32_t h = uint32_t(v) * 2654435761u;
          mesh.positions[v].y = (h >> 7) & 1u ? -0.0f : 0.0f;
          if ((h >> 9) & 1u) mesh.positions[v].x = (h >> 11) & 1u ? -0.0f : 0.0f;
        }
      }
      general.set(mesh);
      fast.set(mesh);
      const double q = refit_layouts(general.layouts, triangle_boxes(general.geometry()));
      const NodeSpans spans = emit_refit_nodes(general.layouts, general.bases,
                                               general.nodes.data() + general.bases.node,
                                               general.wide.data() + general.bases.wide_node);
      const BlasRefit::Result r =
          refit.refit(fast.layouts, fast.geometry(), fast.bases,
                      fast.nodes.data() + fast.bases.node, nullptr, nullptr, true);
      EXPECT_FALSE(r.members_changed) << frame;
      EXPECT_NEAR(r.quality, q, 1e-9 * q) << frame;
      EXPECT_EQ(r.spans.nodes.begin, spans.nodes.begin) << frame;
      EXPECT_EQ(r.spans.nodes.end, spans.nodes.end) << frame;
      EXPECT_TRUE(r.leaf_spans.empty()) << frame;
      for (size_t i = 0; i < fast.nodes.size(); ++i) {
        ASSERT_EQ(std::memcmp(&general.nodes[i], &fast.nodes[i], sizeof(KBvhNode)), 0)
            << "leaves of up to " << build.max_leaf_size << ", frame " << frame << ", node " << i;
      }
      EXPECT_EQ(std::memcmp(&general.layouts.bounds, &fast.layouts.bounds, sizeof(Aabb)), 0);
    }
    // A vertex gone to NaN, or beyond kMaxCoordinate, asks for a rebuild.
    for (const float bad : {std::nanf(""), 2.0f * kMaxCoordinate}) {
      const float kept = fast.positions[fast.triangles[7].v1].y;
      fast.positions[fast.triangles[7].v1].y = bad;
      EXPECT_TRUE(refit
                      .refit(fast.layouts, fast.geometry(), fast.bases,
                             fast.nodes.data() + fast.bases.node, nullptr, nullptr, true)
                      .members_changed);
      fast.positions[fast.triangles[7].v1].y = kept;
    }
  }
}

TEST(BlasRefit, SmallTreesAndSplitLeavesToo) {
  // From a single leaf (one node, an empty second child) to a few nodes:
  // the wide leaves split binary leaves of four into three and one (and,
  // with the deforming meshes' leaves of up to eight, into up to three
  // slots), up to a grid big enough for those larger leaves.
  for (const BuildSettings& build : {BuildSettings{}, AccelSettings{}.deforming_blas})
    for (uint32_t cells : {1u, 2u, 3u, 5u, 9u, 24u}) {
      WaveGrid g{.cells = cells, .size = 2.0f, .amplitude = 0.2f, .wavelength = 0.7f};
      Mesh mesh = make_wave_grid(g);
      Blas general(mesh, build), fast(mesh, build);
      BlasRefit refit;
      ASSERT_TRUE(refit.index(fast.layouts, fast.geometry())) << cells;
      deform_wave_grid(mesh, g, 0.3f);
      general.set(mesh);
      fast.set(mesh);
      refit_layouts(general.layouts, triangle_boxes(general.geometry()));
      emit_refit_nodes(general.layouts, general.bases, general.nodes.data() + general.bases.node,
                       general.wide.data() + general.bases.wide_node);
      fast.refit_with(refit);
      fast.sync_host();
      expect_same_arrays(general, fast, "small grid");
      const std::vector<KLeafTriangle> records = fast.expected_leaf_records();
      EXPECT_EQ(
          std::memcmp(records.data(), fast.leaf.data(), records.size() * sizeof(KLeafTriangle)), 0)
          << cells;
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
  const auto run = [&] { return fast.refit_with(refit); };
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

// A wave grid (mesh 0) and a still one (mesh 1), one instance each.
Scene two_grids(const WaveGrid& g) {
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(make_wave_grid(g));
  WaveGrid other = g;
  other.cells = 8;
  scene.add_mesh(make_wave_grid(other));
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  scene.add_instance({"still", 1, glm::translate(glm::mat4(1.0f), glm::vec3(5, 0, 0))});
  return scene;
}
// A delta that rebuilds mesh 1 alone, so lays the arrays out anew.
SceneDelta rebuild_mesh_1() {
  SceneDelta d;
  d.meshes_rebuilt = {1};
  return d;
}

TEST(BlasRefit, AStaleHostCopyIsBroughtBackBeforeARelayout) {
  // Refit frames leave the boxes only in the kernel arrays; a relayout
  // (here: another mesh rebuilt, as when its refit got too poor) emits
  // every BLAS from its host copy, which must then hold the refit boxes,
  // not the build's. With leaf records kept, the records are the refit's
  // too; without (the default for a mesh whose every vertex moved), the
  // relayout keeps the mesh flagged and writes none of its records.
  for (const bool keep_records : {false, true}) {
    SCOPED_TRACE(keep_records ? "records kept" : "no records");
    WaveGrid g{.cells = 60, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
    AccelSettings settings = test_settings();
    settings.deforming_leaf_records = keep_records;
    TracedScene s(two_grids(g), settings);
    for (uint32_t frame = 1; frame <= 2; ++frame) {
      g.amplitude = 0.05f + 0.01f * float(frame);
      deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.1f * float(frame));
      ASSERT_EQ(s.recompile().blas_refit, 1u);
    }
    const uint32_t root = s.ks.blas_roots[0].bvh_root, wroot = s.ks.blas_roots[0].wide_root;
    const std::vector<KBvhNode> nodes = s.ks.bvh_nodes;
    const std::vector<KWideBvhNode> wide = s.ks.bvh_wide_nodes;
    const std::vector<KLeafTriangle> leaf = s.ks.bvh_leaf_triangles;
    const AccelUpdate up = s.accel.update(s.ks, rebuild_mesh_1());
    ASSERT_EQ(up.blas_built, 1u);
    ASSERT_TRUE(up.delta.bvh_nodes.reallocated);
    ASSERT_EQ(s.ks.blas_roots[0].bvh_root, root);
    ASSERT_EQ(s.ks.blas_roots[0].wide_root, wroot);
    const size_t n = s.accel.blas(0).nodes.size(), wn = s.accel.blas(0).wide_nodes.size();
    EXPECT_EQ(std::memcmp(nodes.data() + root, s.ks.bvh_nodes.data() + root, n * sizeof(KBvhNode)),
              0);
    EXPECT_EQ(std::memcmp(wide.data() + wroot, s.ks.bvh_wide_nodes.data() + wroot,
                          wn * sizeof(KWideBvhNode)),
              0);
    const size_t records = s.accel.blas(0).prims.size();
    EXPECT_EQ(s.ks.blas_roots[1].flags, 0u);
    if (keep_records) {
      EXPECT_EQ(s.ks.blas_roots[0].flags, 0u);
      EXPECT_EQ(
          std::memcmp(leaf.data(), s.ks.bvh_leaf_triangles.data(), records * sizeof(KLeafTriangle)),
          0);
    } else {
      EXPECT_EQ(s.ks.blas_roots[0].flags, uint32_t(kBlasNoLeafRecords));
      const std::vector<KLeafTriangle> zero(records, KLeafTriangle{});
      EXPECT_EQ(
          std::memcmp(zero.data(), s.ks.bvh_leaf_triangles.data(), records * sizeof(KLeafTriangle)),
          0);
    }
    // And blas() (the lazily copied host copy) is what an eager refit of the
    // build's host copy to this pose gives.
    BvhLayouts eager = s.accel.blas(0);
    refit_layouts(eager, triangle_boxes(mesh_geometry(s.ks, 0)));
    EXPECT_EQ(std::memcmp(eager.nodes.data(), s.accel.blas(0).nodes.data(), n * sizeof(KBvhNode)),
              0);
    for (size_t i = 0; i < wn; ++i)
      ASSERT_TRUE(same_wide(eager.wide_nodes[i], s.accel.blas(0).wide_nodes[i])) << i;
  }
}

// A scene's kernel arrays kept by an AccelStructure with given settings.
struct Updated {
  KernelScene ks;
  SceneCompiler compiler;
  RenderSettings settings;
  AccelStructure accel;
  explicit Updated(AccelSettings a) : accel(a) {}
  AccelUpdate update(Scene& scene, SceneDelta* out = nullptr) {
    SceneDelta delta = compile_taking_changes(compiler, scene, settings, ks);
    const AccelUpdate up = accel.update(ks, delta);
    if (out) {
      *out = delta;
      out->merge(up.delta);
    }
    return up;
  }
};

TEST(BlasRefit, TheLayoutNotInUseIsLeftAloneAndCatchesUpWhenSelected) {
  WaveGrid g{.cells = 60, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(make_wave_grid(g));
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  Scene same = scene;
  AccelSettings both = test_settings(), in_use = test_settings();
  in_use.refit_unused_layout = false;  // binary in use
  Updated eager(both), lazy(in_use);
  eager.update(scene);
  lazy.update(same);
  const std::vector<KWideBvhNode> built = lazy.ks.bvh_wide_nodes;
  const size_t wn = lazy.accel.blas(0).wide_nodes.size();
  const uint32_t wroot = lazy.ks.blas_roots[0].wide_root;
  const auto same_wide_region = [&](const std::vector<KWideBvhNode>& a,
                                    const std::vector<KWideBvhNode>& b) {
    return std::memcmp(a.data() + wroot, b.data() + wroot, wn * sizeof(KWideBvhNode)) == 0;
  };
  for (uint32_t frame = 1; frame <= 3; ++frame) {
    g.amplitude = 0.05f + 0.01f * float(frame);
    deform_wave_grid(scene.edit_mesh_vertices(0), g, 0.1f * float(frame));
    deform_wave_grid(same.edit_mesh_vertices(0), g, 0.1f * float(frame));
    eager.update(scene);
    SceneDelta delta;
    ASSERT_EQ(lazy.update(same, &delta).blas_refit, 1u);
    // The binary layout (in use) and the leaf records as the eager one's;
    // the wide nodes not touched, nor sent.
    EXPECT_EQ(lazy.ks.bvh_nodes.size(), eager.ks.bvh_nodes.size());
    EXPECT_EQ(std::memcmp(lazy.ks.bvh_nodes.data(), eager.ks.bvh_nodes.data(),
                          lazy.ks.bvh_nodes.size() * sizeof(KBvhNode)),
              0);
    EXPECT_EQ(std::memcmp(lazy.ks.bvh_leaf_triangles.data(), eager.ks.bvh_leaf_triangles.data(),
                          lazy.ks.bvh_leaf_triangles.size() * sizeof(KLeafTriangle)),
              0);
    EXPECT_TRUE(same_wide_region(built, lazy.ks.bvh_wide_nodes)) << frame;
    EXPECT_FALSE(same_wide_region(built, eager.ks.bvh_wide_nodes)) << frame;
    bool wide_sent = false;
    delta.bvh_wide_nodes.for_each_range(
        [&](uint32_t b, uint32_t e) { wide_sent = wide_sent || (b < wroot + wn && e > wroot); });
    EXPECT_FALSE(wide_sent) << frame;
  }
  // blas() is current in both layouts all the same.
  for (size_t i = 0; i < wn; ++i)
    ASSERT_TRUE(same_wide(eager.accel.blas(0).wide_nodes[i], lazy.accel.blas(0).wide_nodes[i]))
        << i;
  // The wide layout selected: the next update brings it up and sends it.
  lazy.accel.set_layout(kBvhLayoutWide);
  SceneDelta delta;
  lazy.update(same, &delta);
  EXPECT_TRUE(same_wide_region(eager.ks.bvh_wide_nodes, lazy.ks.bvh_wide_nodes));
  EXPECT_TRUE(delta.bvh_wide_nodes.any());
  EXPECT_TRUE(delta.bvh_constants);
  EXPECT_EQ(lazy.ks.bvh.layout, uint32_t(kBvhLayoutWide));
  // And with the wide layout in use both are refit every frame.
  deform_wave_grid(scene.edit_mesh_vertices(0), g, 0.7f);
  deform_wave_grid(same.edit_mesh_vertices(0), g, 0.7f);
  eager.update(scene);
  lazy.update(same);
  EXPECT_TRUE(same_wide_region(eager.ks.bvh_wide_nodes, lazy.ks.bvh_wide_nodes));
}

TEST(BlasRefit, ARelayoutEmitsTheWideNodesASkippedRefitLeftBehind) {
  WaveGrid g{.cells = 40, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  Scene scene = two_grids(g), same = two_grids(g);
  AccelSettings in_use = test_settings();
  in_use.refit_unused_layout = false;
  Updated eager(test_settings()), lazy(in_use);
  eager.update(scene);
  lazy.update(same);
  for (uint32_t frame = 1; frame <= 2; ++frame) {
    g.amplitude = 0.05f + 0.01f * float(frame);
    deform_wave_grid(scene.edit_mesh_vertices(0), g, 0.2f * float(frame));
    deform_wave_grid(same.edit_mesh_vertices(0), g, 0.2f * float(frame));
    eager.update(scene);
    lazy.update(same);
  }
  // Mesh 1 rebuilt: the arrays are laid out anew from the host copies.
  ASSERT_EQ(eager.accel.update(eager.ks, rebuild_mesh_1()).blas_built, 1u);
  ASSERT_EQ(lazy.accel.update(lazy.ks, rebuild_mesh_1()).blas_built, 1u);
  const uint32_t wroot = lazy.ks.blas_roots[0].wide_root;
  const size_t wn = lazy.accel.blas(0).wide_nodes.size();
  ASSERT_EQ(eager.ks.blas_roots[0].wide_root, wroot);
  // (The general refit made lazy's host copy: zeros may differ in sign.)
  for (size_t i = wroot; i < wroot + wn; ++i)
    ASSERT_TRUE(same_wide(eager.ks.bvh_wide_nodes[i], lazy.ks.bvh_wide_nodes[i])) << i;
}

}  // namespace
}  // namespace tandem
