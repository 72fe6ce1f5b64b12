// Deforming meshes in AccelStructure and the Embree backend: a wave grid
// refit every frame for 100 frames (with the rebuild policy) hits what
// Embree (refitting too) and a fresh build of each frame hit, ray by ray;
// the rebuild policy fires under a large deformation and not under a small
// one; an edited vertex range rewrites and reports only the nodes above it.
#include <glm/gtc/matrix_transform.hpp>

#include <chrono>
#include <cstring>

#include "accstruc_test_util.h"
#include "scenes/deforming_grid.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

using namespace accstruc_test;

// Two instances of a wave grid (one tilted above the other) and a static
// floor grid, framed from above at an angle.
Scene wave_scene(const WaveGrid& g) {
  Scene s;
  s.add_material(Material{});
  s.add_mesh(make_wave_grid(g));
  s.add_mesh(make_wave_grid(WaveGrid{.cells = 8, .size = 10.0f, .amplitude = 0.0f}));
  s.add_instance({"wave", 0, glm::mat4(1.0f)});
  s.add_instance({"tilted", 0,
                  glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.5f, 1.5f, 0.0f)), 0.6f,
                              glm::vec3(1.0f, 0.0f, 0.2f))});
  s.add_instance({"floor", 1, glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, -1.0f, 0.0f))});
  Camera cam;
  cam.position = {0.0f, 5.0f, 6.0f};
  cam.forward = glm::normalize(glm::vec3(0.0f, -5.0f, -6.0f));
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  s.set_camera(cam);
  return s;
}

Agreement closest_agreement(const TracedScene& s, const std::vector<RaySample>& rays,
                            uint32_t layout,
                            const std::function<Hit(const RaySample&)>& reference) {
  const KernelData kd = s.kd();
  return compare_closest(
      kd, distance_tolerance(s.bounds), rays,
      [&](const RaySample& r) { return bvh_intersect(kd, r.ray, r.alpha_key, layout); }, reference);
}

TEST(AccelDeform, HundredRefitFramesHitLikeEmbreeAndAFreshBuild) {
  // The amplitude swells from 0.05 to 0.6 and back while the wave travels:
  // the refit tree degrades, so the policy rebuilds it now and then.
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.05f, .wavelength = 0.9f};
  TracedScene s(wave_scene(g));
  uint32_t refits = 0, policy_rebuilds = 0;
  for (uint32_t frame = 1; frame <= 100; ++frame) {
    g.amplitude = 0.05f + 0.55f * std::sin(3.14159265f * float(frame) / 100.0f);
    deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.03f * float(frame));
    SceneDelta delta;
    const AccelUpdate up = s.recompile(&delta);
    ASSERT_EQ(up.blas_refit + up.blas_refit_rebuilt, 1u) << "frame " << frame;
    ASSERT_FALSE(delta.positions.reallocated) << "frame " << frame;
    refits += up.blas_refit;
    policy_rebuilds += up.blas_refit_rebuilt;
    // The deformed grid's bounds grow and shrink: the rays must see them.
    s.bounds = s.scene.bounds();
    // Every frame some rays against Embree; every 20th frame more
    // rays and a fresh build of the same frame, which our refit tree must
    // match exactly (same triangles, same intersection code: only the
    // order of the boxes differs).
    const bool full_check = frame % 20 == 0;
    const uint32_t n = full_check ? 6000 : 800;
    const auto primary = primary_rays(s, n, 100 + frame);
    const auto diffuse = diffuse_rays(s, n, 200 + frame);
    std::unique_ptr<FreshBuild> fresh;
    if (full_check) fresh = std::make_unique<FreshBuild>(s.ks);
    for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
      for (const auto* rays : {&primary, &diffuse}) {
        const Agreement e = closest_agreement(s, *rays, layout, [&](const RaySample& r) {
          return s.embree.intersect(r.ray, r.alpha_key);
        });
        // 800 rays on most frames: at 99.9% fraction() would allow no
        // mismatch at all, where the other ray-by-ray tests (>= 20000 rays)
        // allow 1 in 1000. A mismatch that the long-double reference
        // decides for us is Embree's rounding, not a stale box of ours.
        EXPECT_GE(e.fraction_ours_right(), 0.999)
            << "frame " << frame << " vs Embree: " << e.summary();
        EXPECT_GT(e.hits, n / 4) << "frame " << frame;
        if (fresh) {
          const KernelData fkd = fresh->ks.view();
          const Agreement f = closest_agreement(s, *rays, layout, [&](const RaySample& r) {
            return bvh_intersect(fkd, r.ray, r.alpha_key, layout);
          });
          EXPECT_EQ(f.agree, f.rays) << "frame " << frame << " vs fresh build: " << f.summary();
          if (frame == 100 && layout == kBvhLayoutWide && rays == &diffuse) {
            std::printf("[accstruc] after 100 deformed frames, vs Embree %s\n",
                        e.summary().c_str());
            std::printf("[accstruc] after 100 deformed frames, vs fresh  %s\n",
                        f.summary().c_str());
          }
        }
      }
    }
    if (fresh) {
      const auto shadow = shadow_rays(s, n, 300 + frame);
      const KernelData kd = s.kd();
      const Agreement o = compare_occlusion(
          shadow, [&](const RaySample& r) { return bvh_occluded(kd, r.ray, r.alpha_key, 0); },
          [&](const RaySample& r) { return s.embree.occluded(r.ray, r.alpha_key); });
      EXPECT_GE(o.fraction(), 0.999) << "frame " << frame << " shadow: " << o.summary();
    }
  }
  std::printf("[accstruc] 100 deformed frames: %u refits, %u rebuilds by the quality policy\n",
              refits, policy_rebuilds);
  EXPECT_GT(refits, 50u);
  EXPECT_GT(policy_rebuilds, 0u);  // the swell degrades the tree past the bound
}

// A mesh whose every vertex moves is traced without leaf records, through
// its indices (kBlasNoLeafRecords): the same triangles' same floats, so the
// same hits bit for bit as with records, in both layouts, the host loops and
// the portable ones; and its delta holds no records.
TEST(AccelDeform, WithoutLeafRecordsTheHitsAreTheSameBits) {
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.05f, .wavelength = 0.9f};
  AccelSettings kept = test_settings();
  kept.deforming_leaf_records = true;
  TracedScene none(wave_scene(g)), with(wave_scene(g), kept);
  for (uint32_t frame = 1; frame <= 6; ++frame) {
    g.amplitude = 0.05f + 0.1f * float(frame);
    deform_wave_grid(none.scene.edit_mesh_vertices(0), g, 0.05f * float(frame));
    deform_wave_grid(with.scene.edit_mesh_vertices(0), g, 0.05f * float(frame));
    const AccelUpdate a = none.recompile(), b = with.recompile();
    ASSERT_EQ(none.ks.blas_roots[0].flags, uint32_t(kBlasNoLeafRecords));
    // Records kept: refit in the binary layout's order only, which the wide
    // layout then reads too (kBlasNoWideRecords) until the next layout.
    ASSERT_EQ(with.ks.blas_roots[0].flags & kBlasNoLeafRecords, 0u);
    if (b.blas_refit == 1u) {
      ASSERT_EQ(with.ks.blas_roots[0].flags, uint32_t(kBlasNoWideRecords));
    }
    if (a.blas_refit == 1u) {
      EXPECT_FALSE(a.delta.bvh_leaf_triangles.any()) << "frame " << frame;
    }
    if (b.blas_refit == 1u) {
      EXPECT_TRUE(b.delta.bvh_leaf_triangles.any()) << "frame " << frame;
    }
    const KernelData kn = none.kd(), kw = with.kd();
    uint32_t hits = 0;
    for (const RaySample& r : primary_rays(none, 2000, frame)) {
      for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
        for (bool any : {false, true}) {
          const Hit h0 = bvh_trace(kn, r.ray, r.alpha_key, layout, any);
          const Hit h1 = bvh_trace(kw, r.ray, r.alpha_key, layout, any);
          const Hit p0 =
              bvh_trace_counted<false, true>(kn, r.ray, r.alpha_key, layout, any, nullptr);
          const Hit p1 =
              bvh_trace_counted<false, true>(kw, r.ray, r.alpha_key, layout, any, nullptr);
          ASSERT_EQ(std::memcmp(&h0, &h1, sizeof h0), 0) << "frame " << frame;
          ASSERT_EQ(std::memcmp(&p0, &p1, sizeof p0), 0) << "frame " << frame;
          hits += hit_valid(h0) ? 1u : 0u;
        }
      }
    }
    EXPECT_GT(hits, 1000u) << "frame " << frame;
  }
}

// A mesh the scene marks as deforming gets AccelSettings::deforming_blas:
// leaves of up to 8 triangles, far fewer nodes for the refit to sweep; the
// same mesh unmarked keeps the static leaves of at most 4, also after it was
// refit (its tree depends on the scene, not on its edits).
TEST(AccelDeform, MarkedDeformingMeshesGetLargerLeaves) {
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.05f, .wavelength = 0.9f};
  const auto largest_leaf = [](const BvhLayouts& l) {
    uint32_t most = 0;
    for (const KBvhNode& n : l.nodes) {
      for (uint32_t c = 0; c < 2; ++c) {
        if (n.child[c] & kBvhLeafFlag) most = std::max(most, n.count[c]);
      }
    }
    return most;
  };
  Scene marked_scene = wave_scene(g);
  marked_scene.set_mesh_deforms(0);
  TracedScene marked(std::move(marked_scene)), plain(wave_scene(g));
  for (uint32_t frame = 1; frame <= 2; ++frame) {
    for (TracedScene* s : {&marked, &plain}) {
      deform_wave_grid(s->scene.edit_mesh_vertices(0), g, 0.05f * float(frame));
      ASSERT_EQ(s->recompile().blas_refit, 1u) << "frame " << frame;
    }
  }
  const BvhLayouts &m = marked.accel.blas(0), &p = plain.accel.blas(0);
  EXPECT_GT(largest_leaf(m), 4u);
  EXPECT_LE(largest_leaf(m), AccelSettings{}.deforming_blas.max_leaf_size);
  EXPECT_LE(largest_leaf(p), 4u);
  EXPECT_LT(2 * m.nodes.size(), p.nodes.size())
      << m.nodes.size() << " nodes marked, " << p.nodes.size() << " unmarked";
}

// Arrays that only the host's loops trace (CoreTracer's host backends) keep
// a deforming mesh in the binary layout alone (kBlasBinaryOnly): the wide
// loop traverses its binary nodes and the static floor's wide ones, and
// finds the closest hits the binary layout finds, frame after frame, while
// the refit leaves the mesh's wide nodes alone.
TEST(AccelDeform, BinaryOnlyDeformingMeshesHitLikeTheBinaryLayout) {
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.05f, .wavelength = 0.9f};
  AccelSettings host = test_settings();
  host.layout = kBvhLayoutWide;
  host.refit_unused_layout = false;
  host.deforming_binary_only = true;
  Scene scene = wave_scene(g);
  scene.set_mesh_deforms(0);  // as a loader marks a skinned mesh
  TracedScene s(std::move(scene), host);
  const std::vector<KWideBvhNode> wide_before = s.ks.bvh_wide_nodes;
  for (uint32_t frame = 1; frame <= 8; ++frame) {
    // The wave travels at its build amplitude: refits, no policy rebuild.
    deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.05f * float(frame));
    const AccelUpdate up = s.recompile();
    ASSERT_EQ(up.blas_refit, 1u) << "frame " << frame;
    ASSERT_NE(s.ks.blas_roots[0].flags & kBlasBinaryOnly, 0u) << "frame " << frame;
    ASSERT_EQ(s.ks.blas_roots[1].flags & kBlasBinaryOnly, 0u) << "frame " << frame;
    EXPECT_FALSE(up.delta.bvh_wide_nodes.any() &&
                 up.delta.bvh_wide_nodes.begin < s.ks.blas_roots[1].wide_root)
        << "the deforming mesh's wide nodes were rewritten, frame " << frame;
    const KernelData kd = s.kd();
    uint32_t hits = 0;
    for (const RaySample& r : primary_rays(s, 2000, frame)) {
      for (const bool any : {false, true}) {
        const Hit wide = bvh_trace(kd, r.ray, r.alpha_key, kBvhLayoutWide, any);
        const Hit binary = bvh_trace(kd, r.ray, r.alpha_key, kBvhLayoutBinary, any);
        ASSERT_EQ(hit_valid(wide), hit_valid(binary)) << "frame " << frame;
        if (!any && hit_valid(wide)) {
          ASSERT_EQ(std::memcmp(&wide.t, &binary.t, sizeof(float)), 0) << "frame " << frame;
          hits += 1;
        }
      }
    }
    EXPECT_GT(hits, 1000u) << "frame " << frame;
  }
  // Its wide nodes are the build's, left alone.
  const uint32_t w0 = s.ks.blas_roots[0].wide_root, w1 = s.ks.blas_roots[1].wide_root;
  EXPECT_EQ(std::memcmp(s.ks.bvh_wide_nodes.data() + w0, wide_before.data() + w0,
                        (w1 - w0) * sizeof(KWideBvhNode)),
            0);
  expect_hits_like_embree(s, "binary-only deforming grid", 4000, 0.999);
}

TEST(AccelDeform, RebuildPolicyFiresOnlyUnderALargeDeformation) {
  WaveGrid g{.cells = 80, .size = 4.0f, .amplitude = 0.02f, .wavelength = 1.0f};
  TracedScene s(wave_scene(g));
  const double built = refit_quality(s.accel.blas(0));
  // Small: the wave travels two wavelengths at its build amplitude.
  for (uint32_t frame = 1; frame <= 40; ++frame) {
    deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.05f * float(frame));
    const AccelUpdate up = s.recompile();
    ASSERT_EQ(up.blas_refit, 1u) << "frame " << frame;
    ASSERT_EQ(up.blas_refit_rebuilt, 0u) << "frame " << frame;
  }
  const double small = refit_quality(s.accel.blas(0));
  EXPECT_FALSE(refit_too_poor(small, built));
  // Large: a wave of 60% of the grid's size on short wavelengths.
  WaveGrid big = g;
  big.amplitude = 2.4f;
  big.wavelength = 0.5f;
  deform_wave_grid(s.scene.edit_mesh_vertices(0), big, 0.0f);
  const AccelUpdate up = s.recompile();
  EXPECT_EQ(up.blas_refit, 0u);
  EXPECT_EQ(up.blas_refit_rebuilt, 1u);
  EXPECT_EQ(up.blas_built, 1u);
  EXPECT_TRUE(up.tlas_rebuilt);
  EXPECT_TRUE(validate_layouts(s.accel.blas(0), 2 * big.cells * big.cells));
  const double rebuilt = refit_quality(s.accel.blas(0));
  std::printf(
      "[accstruc] refit quality: %.2f as built, %.2f after a small deformation, %.2f rebuilt "
      "after the large one\n",
      built, small, rebuilt);
  // The next frame refits the new tree again.
  deform_wave_grid(s.scene.edit_mesh_vertices(0), big, 0.02f);
  const AccelUpdate next = s.recompile();
  EXPECT_EQ(next.blas_refit, 1u);
  EXPECT_EQ(next.blas_refit_rebuilt, 0u);
  s.bounds = s.scene.bounds();
  const auto rays = primary_rays(s, 4000, 9);
  const Agreement e = closest_agreement(s, rays, kBvhLayoutWide, [&](const RaySample& r) {
    return s.embree.intersect(r.ray, r.alpha_key);
  });
  EXPECT_GE(e.fraction(), 0.999) << e.summary();
}

TEST(AccelDeform, VertexRangeRewritesOnlyTheNodesAboveIt) {
  WaveGrid g{.cells = 128, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  TracedScene s(wave_scene(g));
  const KernelScene before = s.ks;
  const uint32_t root = s.ks.blas_roots[0].bvh_root;
  const uint32_t blas_nodes = uint32_t(s.accel.blas(0).nodes.size());
  // A short run of one row, flattened halfway: inside the wave's extremes,
  // so boxes far above it keep their size. (Rows and columns off the
  // grid's halves and quarters, where the top splits of the tree lie.)
  const uint32_t first = 37 * (g.cells + 1) + 41, count = 16;
  Mesh& mesh = s.scene.edit_mesh_vertices(0, first, count);
  for (uint32_t v = first; v < first + count; ++v)
    mesh.positions[v].y *= 0.5f;
  SceneDelta delta;
  const AccelUpdate up = s.recompile(&delta);
  ASSERT_EQ(up.blas_refit, 1u);
  // The vertex delta is exactly the range.
  const uint32_t vbase = s.ks.meshes[0].vertex_offset;
  EXPECT_EQ(delta.positions.begin, vbase + first);
  EXPECT_EQ(delta.positions.end, vbase + first + count);
  // The BLAS's reported nodes: a small part of its region (the TLAS, at the
  // end of the array, is a range of its own), and every node outside the
  // report kept its bytes.
  ASSERT_TRUE(up.delta.bvh_nodes.any());
  EXPECT_GE(up.delta.bvh_nodes.begin, root);
  const uint32_t blas_end = root + blas_nodes;
  std::vector<uint8_t> reported(s.ks.bvh_nodes.size(), 0);
  uint32_t reported_in_blas = 0;
  up.delta.bvh_nodes.for_each_range([&](uint32_t b, uint32_t e) {
    for (uint32_t i = b; i < e; ++i) {
      reported[i] = 1;
      reported_in_blas += i < blas_end ? 1 : 0;
    }
  });
  std::printf("[accstruc] %u-vertex edit of a %u-vertex grid: %u of its %u BVH nodes sent\n", count,
              g.vertex_count(), reported_in_blas, blas_nodes);
  EXPECT_GT(reported_in_blas, 0u);
  EXPECT_LT(reported_in_blas, blas_nodes / 10);
  EXPECT_EQ(up.delta.bytes(s.ks) - (up.delta.bvh_constants ? sizeof(KBvhConstants) : 0),
            up.delta.bvh_nodes.element_count() * sizeof(KBvhNode) +
                up.delta.bvh_wide_nodes.element_count() * sizeof(KWideBvhNode) +
                up.delta.bvh_prim_indices.element_count() * sizeof(uint32_t) +
                up.delta.bvh_wide_prim_indices.element_count() * sizeof(uint32_t) +
                up.delta.bvh_leaf_triangles.element_count() * sizeof(KLeafTriangle) +
                up.delta.blas_roots.element_count() * sizeof(KBlasRoot));
  // The leaf records (vertices in leaf order): those of the triangles around
  // the edited vertices are rewritten, few are sent, and every record,
  // reported or not, holds its triangle's current vertices.
  const uint32_t blas_prims = uint32_t(s.accel.blas(0).prims.size());
  ASSERT_TRUE(up.delta.bvh_leaf_triangles.any());
  EXPECT_FALSE(up.delta.bvh_leaf_triangles.reallocated);
  EXPECT_GE(up.delta.bvh_leaf_triangles.element_count(), count);
  EXPECT_LT(up.delta.bvh_leaf_triangles.element_count(), blas_prims / 10);
  std::vector<uint8_t> leaf_reported(s.ks.bvh_leaf_triangles.size(), 0);
  up.delta.bvh_leaf_triangles.for_each_range([&](uint32_t b, uint32_t e) {
    std::fill(leaf_reported.begin() + b, leaf_reported.begin() + e, uint8_t(1));
  });
  const MeshGeometry geo = mesh_geometry(s.ks, 0);
  for (uint32_t i = 0; i < blas_prims; ++i) {
    const uint32_t prim = s.accel.blas(0).prims[i];
    const KTriangle& t = geo.triangles[prim];
    const KLeafTriangle& lt = s.ks.bvh_leaf_triangles[i];
    const Vec3 p[3] = {geo.positions[t.v0], geo.positions[t.v1], geo.positions[t.v2]};
    const Vec4 q[3] = {lt.p0, lt.p1, lt.p2};
    ASSERT_EQ(float_as_uint(lt.p0.w), prim) << "record " << i;
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(q[k].x == p[k].x && q[k].y == p[k].y && q[k].z == p[k].z)
          << "record " << i << " vertex " << k;
    }
    if (!leaf_reported[i]) {
      ASSERT_EQ(std::memcmp(&before.bvh_leaf_triangles[i], &lt, sizeof lt), 0) << "record " << i;
    }
  }
  for (uint32_t i = root; i < blas_end; ++i) {
    if (reported[i]) continue;
    ASSERT_EQ(std::memcmp(&before.bvh_nodes[i], &s.ks.bvh_nodes[i], sizeof(KBvhNode)), 0)
        << "node " << i;
  }
  // And the arrays hold exactly the refit tree (nothing changed was skipped).
  std::vector<KBvhNode> nodes(s.ks.bvh_nodes.size());
  std::vector<uint32_t> prims(s.ks.bvh_prim_indices.size());
  std::vector<KWideBvhNode> wide(s.ks.bvh_wide_nodes.size());
  std::vector<uint32_t> wide_prims(s.ks.bvh_wide_prim_indices.size());
  const LayoutBases b{root, 0, s.ks.blas_roots[0].wide_root, 0};
  emit_layouts(s.accel.blas(0), b, nodes.data() + b.node, prims.data(), wide.data() + b.wide_node,
               wide_prims.data());
  EXPECT_EQ(
      std::memcmp(nodes.data() + root, s.ks.bvh_nodes.data() + root, blas_nodes * sizeof(KBvhNode)),
      0);
  EXPECT_EQ(std::memcmp(wide.data() + b.wide_node, s.ks.bvh_wide_nodes.data() + b.wide_node,
                        s.accel.blas(0).wide_nodes.size() * sizeof(KWideBvhNode)),
            0);
  EXPECT_FALSE(up.delta.bvh_prim_indices.any() && up.delta.bvh_prim_indices.begin < blas_end);
}

}  // namespace
}  // namespace tandem

namespace tandem {
namespace {

// Not a test: the per-frame cost of a deforming mesh of a million vertices
// (run with --gtest_also_run_disabled_tests
// --gtest_filter=*MillionVertexFrameTimes). Prints the median over 20
// frames of each step: the deformation itself (standing in for skinning),
// SceneCompiler (vertex conversion), AccelStructure (BLAS refit + TLAS) and
// the Embree backend's refit commit.
TEST(AccelDeform, DISABLED_MillionVertexFrameTimes) {
  using Clock = std::chrono::steady_clock;
  const auto ms = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  WaveGrid g{.cells = 999, .size = 40.0f, .amplitude = 0.3f, .wavelength = 5.0f};
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(make_wave_grid(g));
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  TracedScene s(std::move(scene));
  std::vector<double> deform, compile, refit, embree, total, bytes;
  for (uint32_t frame = 1; frame <= 20; ++frame) {
    const auto t0 = Clock::now();
    deform_wave_grid(s.scene.edit_mesh_vertices(0), g, 0.01f * float(frame));
    const auto t1 = Clock::now();
    SceneDelta delta = compile_taking_changes(s.compiler, s.scene, s.settings, s.ks);
    const auto t2 = Clock::now();
    const AccelUpdate up = s.accel.update(s.ks, delta);
    const auto t3 = Clock::now();
    delta.merge(up.delta);
    s.embree.sync(s.ks, delta);
    const auto t4 = Clock::now();
    deform.push_back(ms(t0, t1));
    compile.push_back(ms(t1, t2));
    refit.push_back(ms(t2, t3));
    embree.push_back(ms(t3, t4));
    total.push_back(ms(t0, t3));
    bytes.push_back(double(delta.bytes(s.ks)) / (1024.0 * 1024.0));
    EXPECT_EQ(up.blas_refit, 1u);
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "[accstruc] %u vertices, %u triangles, median of 20 frames: deform %.2f ms, compile "
      "(vertex conversion) %.2f ms, BVH refit + TLAS %.2f ms (deform + compile + refit %.2f ms); "
      "Embree refit %.2f ms; delta %.2f MiB/frame\n",
      g.vertex_count(), 2 * g.cells * g.cells, median(deform), median(compile), median(refit),
      median(total), median(embree), median(bytes));
}

}  // namespace
}  // namespace tandem
