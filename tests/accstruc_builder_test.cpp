// The BVH builder and layouts on their own: SAH quality against a median
// split, structural invariants of both layouts (every primitive exactly once,
// every box containing its subtree, conservative quantisation), degenerate
// input, determinism across thread counts, and the robustness of the ray
// tests (zero direction components, watertight edges and vertices, alpha).
#include <tbb/global_control.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "accstruc/wide_bvh.h"
#include "accstruc_test_util.h"
#include "scenes/builtin_scenes.h"
#include "scenes/procedural_scenes.h"

namespace tandem {
namespace {

using namespace accstruc_test;

Mesh grid_mesh(uint32_t n, float jitter, uint32_t seed) {
  TestRandom rng(seed);
  Mesh m;
  m.name = "grid";
  for (uint32_t j = 0; j <= n; ++j) {
    for (uint32_t i = 0; i <= n; ++i) {
      const bool border = i == 0 || j == 0 || i == n || j == n;
      const float jx = border ? 0.0f : jitter * (rng.uniform() - 0.5f);
      const float jy = border ? 0.0f : jitter * (rng.uniform() - 0.5f);
      m.positions.push_back({float(i) + jx, float(j) + jy, 0.0f});
    }
  }
  for (uint32_t j = 0; j < n; ++j) {
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.push_back({a, b, d});
      m.triangles.push_back({a, d, c});
      m.triangle_materials.insert(m.triangle_materials.end(), {0u, 0u});
    }
  }
  return m;
}

std::vector<Aabb> mesh_boxes(const Mesh& m) {
  std::vector<Vec3> pos;
  for (const glm::vec3& p : m.positions)
    pos.push_back({p.x, p.y, p.z});
  std::vector<KTriangle> tris;
  for (const glm::uvec3& t : m.triangles)
    tris.push_back({t.x, t.y, t.z, 0});
  MeshGeometry g{pos.data(), uint32_t(pos.size()), tris.data(), uint32_t(tris.size())};
  return triangle_boxes(g);
}

bool contains(const Aabb& outer, const Aabb& inner) {
  return outer.lo.x <= inner.lo.x && outer.lo.y <= inner.lo.y && outer.lo.z <= inner.lo.z &&
         outer.hi.x >= inner.hi.x && outer.hi.y >= inner.hi.y && outer.hi.z >= inner.hi.z;
}

// Checks both layouts of `l` against the primitive boxes they were built
// from: each valid primitive appears exactly once per layout and every box
// (exact in the binary layout, decoded in the wide one) contains everything
// below it.
void check_layouts(const BvhLayouts& l, const std::vector<Aabb>& boxes) {
  ASSERT_TRUE(validate_layouts(l, uint32_t(boxes.size())));
  size_t valid = 0;
  for (const Aabb& b : boxes)
    valid += aabb_valid(b) ? 1 : 0;
  ASSERT_EQ(l.prims.size(), valid);
  ASSERT_EQ(l.wide_prims.size(), valid);
  std::vector<uint8_t> seen(boxes.size(), 0), seen_wide(boxes.size(), 0);
  for (uint32_t p : l.prims)
    ++seen[p];
  for (uint32_t p : l.wide_prims)
    ++seen_wide[p];
  for (size_t i = 0; i < boxes.size(); ++i) {
    ASSERT_EQ(seen[i], aabb_valid(boxes[i]) ? 1 : 0) << i;
    ASSERT_EQ(seen_wide[i], aabb_valid(boxes[i]) ? 1 : 0) << i;
  }
  // Binary: box of child c of node i must contain its whole subtree.
  std::function<Aabb(uint32_t)> subtree = [&](uint32_t i) {
    const KBvhNode& n = l.nodes[i];
    Aabb all;
    for (uint32_t c = 0; c < 2; ++c) {
      const Vec4& xy = c == 0 ? n.c0_xy : n.c1_xy;
      Aabb box{{xy.x, xy.z, c == 0 ? n.c01_z.x : n.c01_z.z},
               {xy.y, xy.w, c == 0 ? n.c01_z.y : n.c01_z.w}};
      Aabb content;
      if (n.child[c] & kBvhLeafFlag) {
        const uint32_t first = n.child[c] & ~kBvhLeafFlag;
        for (uint32_t k = first; k < first + n.count[c]; ++k)
          content.grow(boxes[l.prims[k]]);
      } else {
        content = subtree(n.child[c]);
      }
      if (!content.empty()) {
        EXPECT_TRUE(contains(box, content)) << "binary node " << i << " child " << c;
      }
      all.grow(content);
    }
    return all;
  };
  subtree(0);
  // Wide: decoded slot boxes must contain their content.
  std::function<Aabb(uint32_t)> wide_subtree = [&](uint32_t i) {
    const KWideBvhNode& n = l.wide_nodes[i];
    Aabb all;
    uint32_t rank = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      if (n.meta[s] == 0) continue;
      Aabb content;
      if ((n.imask >> s) & 1u) {
        content = wide_subtree(n.child_base + rank++);
      } else {
        const uint32_t unary = n.meta[s] >> 5, count = unary == 7 ? 3 : (unary == 3 ? 2 : 1);
        for (uint32_t k = 0; k < count; ++k)
          content.grow(boxes[l.wide_prims[n.prim_base + (n.meta[s] & 31u) + k]]);
      }
      EXPECT_TRUE(contains(wide_slot_box(n, s), content)) << "wide node " << i << " slot " << s;
      all.grow(content);
    }
    return all;
  };
  wide_subtree(0);
}

BvhLayouts build_layouts(const std::vector<Aabb>& boxes, const BuildSettings& s = {}) {
  const BuildTree tree = build_bvh(boxes, s);
  return make_layouts(tree, boxes, kWideMaxLeafPrims, s.traversal_cost, s.intersection_cost);
}

// ---------------------------------------------------------------------------
// SAH quality

// The planes of one slot and axis as the wide layout's quantisation defines
// them (a reference kept apart from accstruc/wide_bvh.cpp's vector code):
// floor and ceil of the scaled distances from the origin, clamped to
// [0, 255], then stepped until the decoded plane holds the box.
void reference_planes(float o, float sc, float lo, float hi, uint8_t* qlo_out, uint8_t* qhi_out) {
  const float inv = uint_as_float(uint32_t(254 - int((float_as_uint(sc) >> 23) & 0xffu)) << 23);
  const auto decode = [&](uint32_t q) { return o + float(q) * sc; };
  float f = (lo - o) * inv;
  uint32_t qlo = f > 0.0f ? (f >= 255.0f ? 255u : uint32_t(f)) : 0u;
  while (qlo > 0 && decode(qlo) > lo)
    --qlo;
  f = (hi - o) * inv;
  uint32_t qhi = 0;
  if (f > 0.0f) {
    qhi = f >= 255.0f ? 255u : uint32_t(f);
    qhi += qhi < 255u && float(qhi) < f ? 1u : 0u;
  }
  while (qhi < 255 && decode(qhi) < hi)
    ++qhi;
  *qlo_out = uint8_t(qlo);
  *qhi_out = uint8_t(qhi);
}

// quantize_wide_node() (the refit's per-frame quantisation, four slots at a
// time in SSE) gives every plane the reference's byte, and decoded boxes
// that contain the slots' boxes, on random and awkward boxes: tiny, huge,
// flat, far from the origin, slots empty or unused.
TEST(BvhBuilder, WideQuantisationMatchesTheReferenceByteForByte) {
  std::mt19937 rng(77);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const float magnitudes[] = {1e-6f, 1e-2f, 1.0f, 37.0f, 1e4f, 1e12f};
  uint32_t planes = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const float mag = magnitudes[trial % 6];
    const Vec3 center = {(unit(rng) - 0.5f) * mag * 50.0f, (unit(rng) - 0.5f) * mag,
                         (unit(rng) - 0.5f) * mag * 3.0f};
    Aabb boxes[kWideBvhWidth];
    uint32_t used = 0;
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      if (unit(rng) < 0.85f) used |= 1u << s;
      if (unit(rng) < 0.05f) continue;  // an empty box
      Vec3 a = center + Vec3{unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f} * mag;
      Vec3 b = a + Vec3{unit(rng), unit(rng), unit(rng)} * (mag * unit(rng));
      if (unit(rng) < 0.1f) b.y = a.y;  // flat
      boxes[s] = Aabb{a, b};
    }
    KWideBvhNode n{};
    quantize_wide_node(n, boxes, used);
    for (uint32_t s = 0; s < kWideBvhWidth; ++s) {
      const bool live = ((used >> s) & 1u) && !boxes[s].empty();
      for (int a = 0; a < 3; ++a) {
        uint8_t qlo = 255, qhi = 0;
        if (live) {
          reference_planes(component(n.origin, a), wide_node_scale(n, a), component(boxes[s].lo, a),
                           component(boxes[s].hi, a), &qlo, &qhi);
          ++planes;
        }
        ASSERT_EQ(n.qlo[a][s], qlo) << "trial " << trial << " slot " << s << " axis " << a;
        ASSERT_EQ(n.qhi[a][s], qhi) << "trial " << trial << " slot " << s << " axis " << a;
      }
      if (live) {
        EXPECT_TRUE(contains(wide_slot_box(n, s), boxes[s])) << "trial " << trial;
      }
    }
  }
  EXPECT_GT(planes, 100000u);
}

TEST(BvhBuilder, SahCostBeatsMedianSplit) {
  std::vector<std::pair<std::string, Mesh>> meshes;
  meshes.push_back({"uv sphere 64x128", make_uv_sphere(1.0f, 64, 128, 0, false)});
  meshes.push_back({"jittered grid 100x100", grid_mesh(100, 0.5f, 1)});
  const Scene proc = make_procedural_scene(200000, 7);
  for (const Mesh& m : proc.meshes()) {
    if (m.triangles.size() >= 10000) meshes.push_back({"procedural " + m.name, m});
  }
  const std::string duck =
      std::string(TANDEM_SHARED_DIR) + "/scenes/gltf/Duck/glTF-Binary/Duck.glb";
  if (std::filesystem::exists(duck)) meshes.push_back({"Duck", load_scene(duck).meshes()[0]});
  BuildSettings median;
  median.method = SplitMethod::kMedian;
  for (const auto& [name, mesh] : meshes) {
    const std::vector<Aabb> boxes = mesh_boxes(mesh);
    const BuildTree sah_tree = build_bvh(boxes, BuildSettings{});
    const BuildTree median_tree = build_bvh(boxes, median);
    const double sah = sah_cost(sah_tree, 1.0f, 1.0f), med = sah_cost(median_tree, 1.0f, 1.0f);
    const BvhLayouts l = make_layouts(sah_tree, boxes, kWideMaxLeafPrims, 1.0f, 1.0f);
    std::printf(
        "[accstruc] SAH cost (C_trav = C_isect = 1) %-28s %7zu tris: binned SAH %8.2f, median "
        "%8.2f, "
        "8-wide %8.2f, depth %u\n",
        name.c_str(), boxes.size(), sah, med, l.wide_sah_cost, sah_tree.depth);
    EXPECT_LT(sah, med) << name;
    EXPECT_GT(sah, 1.0) << name;  // at least one node and one triangle per ray
    EXPECT_LE(sah_tree.depth, kBvhStackSize - 1) << name;
  }
}

TEST(BvhBuilder, LayoutsHoldEveryPrimitiveOnceAndContainTheirSubtrees) {
  const Scene proc = make_procedural_scene(60000, 3);
  for (const Mesh& m : proc.meshes())
    check_layouts(build_layouts(mesh_boxes(m)), mesh_boxes(m));
  // Leaf-size settings the wide collapse must cope with.
  const std::vector<Aabb> boxes = mesh_boxes(make_uv_sphere(1.0f, 20, 40, 0, false));
  for (uint32_t leaf : {1u, 2u, 3u, 4u, 8u, 16u}) {
    BuildSettings s;
    s.max_leaf_size = leaf;
    check_layouts(build_layouts(boxes, s), boxes);
  }
}

TEST(BvhBuilder, SameResultForAnyThreadCount) {
  const Scene proc = make_procedural_scene(300000, 5);
  const std::vector<Aabb> boxes = mesh_boxes(proc.meshes()[0]);
  BvhLayouts one, many;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = build_layouts(boxes);
  }
  many = build_layouts(boxes);
  ASSERT_EQ(one.nodes.size(), many.nodes.size());
  ASSERT_EQ(one.wide_nodes.size(), many.wide_nodes.size());
  EXPECT_EQ(0,
            std::memcmp(one.nodes.data(), many.nodes.data(), one.nodes.size() * sizeof(KBvhNode)));
  EXPECT_EQ(one.prims, many.prims);
  EXPECT_EQ(0, std::memcmp(one.wide_nodes.data(), many.wide_nodes.data(),
                           one.wide_nodes.size() * sizeof(KWideBvhNode)));
  EXPECT_EQ(one.wide_prims, many.wide_prims);
}

// ---------------------------------------------------------------------------
// Degenerate input

TEST(BvhBuilder, DegenerateInput) {
  // Coincident triangles: no centroid extent at all.
  std::vector<Aabb> same(1000, Aabb{{0, 0, 0}, {1, 1, 0}});
  BvhLayouts l = build_layouts(same);
  check_layouts(l, same);
  EXPECT_LE(l.depth, 16u);
  // Points and segments: zero-area boxes, zero extent on two axes.
  std::vector<Aabb> points;
  for (int i = 0; i < 500; ++i)
    points.push_back({{float(i % 7), 0, 0}, {float(i % 7), 0, 0}});
  for (int i = 0; i < 500; ++i)
    points.push_back({{0, float(i), 0}, {0, float(i) + 1.0f, 0}});
  l = build_layouts(points);
  check_layouts(l, points);
  // Invalid boxes (NaN, inf, inverted, beyond Embree's coordinate limit) are
  // left out; the rest is built.
  std::vector<Aabb> mixed = mesh_boxes(grid_mesh(10, 0.3f, 2));
  const float nan = std::nanf("");
  mixed.push_back({{nan, 0, 0}, {1, 1, 1}});
  mixed.push_back({{0, 0, 0}, {INFINITY, 1, 1}});
  mixed.push_back({{1, 1, 1}, {0, 0, 0}});
  mixed.push_back({{0, 0, 0}, {2e18f, 1, 1}});
  l = build_layouts(mixed);
  check_layouts(l, mixed);
  EXPECT_EQ(l.prims.size(), mixed.size() - 4);
  // Huge but valid coordinates still quantise conservatively.
  std::vector<Aabb> huge = {{{-1e18f, 0, 0}, {-1e18f + 1e12f, 1, 1}},
                            {{1e18f, 5, 5}, {1.5e18f, 6, 6}},
                            {{0, 0, 0}, {1e-30f, 1e-30f, 1e-30f}}};
  l = build_layouts(huge);
  check_layouts(l, huge);
  // A single primitive, and none at all.
  std::vector<Aabb> one = {{{0, 0, 0}, {1, 2, 3}}};
  l = build_layouts(one);
  check_layouts(l, one);
  EXPECT_EQ(l.nodes.size(), 1u);
  EXPECT_TRUE(build_layouts({}).empty());
  // Geometrically shrinking boxes: the SAH would build a list; the depth
  // limit switches to median splits and keeps the kernel stacks safe.
  std::vector<Aabb> nested;
  for (int i = 0; i < 20000; ++i) {
    const float s = std::ldexp(1.0f, -(i % 120));
    nested.push_back({{s, s, s}, {2 * s, 2 * s, 2 * s}});
  }
  l = build_layouts(nested);
  check_layouts(l, nested);
  EXPECT_LT(l.depth, kBvhStackSize);
}

TEST(BvhBuilder, ValidationRejectsBrokenHierarchies) {
  const std::vector<Aabb> boxes = mesh_boxes(grid_mesh(20, 0.2f, 3));
  const BvhLayouts good = build_layouts(boxes);
  ASSERT_TRUE(validate_layouts(good, uint32_t(boxes.size())));
  EXPECT_FALSE(validate_layouts(good, uint32_t(boxes.size()) - 1));  // primitive out of range
  BvhLayouts bad = good;
  bad.nodes[1].child[0] = 0;  // cycle back to the root
  EXPECT_FALSE(validate_layouts(bad, uint32_t(boxes.size())));
  bad = good;
  bad.nodes[0].child[1] = uint32_t(bad.nodes.size());  // out of range
  EXPECT_FALSE(validate_layouts(bad, uint32_t(boxes.size())));
  bad = good;
  bad.wide_nodes[0].child_base = 0;  // child before its parent
  EXPECT_FALSE(validate_layouts(bad, uint32_t(boxes.size())));
  bad = good;
  bad.wide_nodes[0].exponent[1] = 0;
  EXPECT_FALSE(validate_layouts(bad, uint32_t(boxes.size())));
  bad = good;
  bad.wide_prims.pop_back();  // a leaf now reads past the end
  EXPECT_FALSE(validate_layouts(bad, uint32_t(boxes.size())));
}

// ---------------------------------------------------------------------------
// Ray tests

TEST(BvhRayTests, ZeroDirectionComponentsAndOriginOnSlabPlanes) {
  const Vec3 lo = {0, 0, 0}, hi = {1, 1, 1};
  float t;
  // Along +x inside the slab of y and z, including exactly on their planes.
  for (float y : {0.0f, 0.5f, 1.0f}) {
    for (float z : {0.0f, 1.0f}) {
      EXPECT_TRUE(intersect_box(make_box_ray({-1, y, z}, {1, 0, 0}), lo, hi, 0, kFloatMax, &t))
          << y << z;
      EXPECT_TRUE(intersect_box(make_box_ray({-1, y, z}, {1, -0.0f, 0}), lo, hi, 0, kFloatMax, &t));
    }
  }
  // Outside a slab with a zero component: never hit.
  EXPECT_FALSE(
      intersect_box(make_box_ray({-1, 1.0001f, 0.5f}, {1, 0, 0}), lo, hi, 0, kFloatMax, &t));
  EXPECT_FALSE(
      intersect_box(make_box_ray({-1, -0.0001f, 0.5f}, {1, -0.0f, 0}), lo, hi, 0, kFloatMax, &t));
  // Flat box (zero extent), hit exactly in its plane and across it.
  EXPECT_TRUE(intersect_box(make_box_ray({0.5f, -1, 0.5f}, {0, 1, 0}), {0, 0, 0}, {1, 0, 1}, 0,
                            kFloatMax, &t));
  EXPECT_TRUE(intersect_box(make_box_ray({-1, 0, 0.5f}, {1, 0, 0}), {0, 0, 0}, {1, 0, 1}, 0,
                            kFloatMax, &t));
  // The interval is respected.
  EXPECT_FALSE(intersect_box(make_box_ray({-3, 0.5f, 0.5f}, {1, 0, 0}), lo, hi, 0, 2.9f, &t));
  EXPECT_FALSE(
      intersect_box(make_box_ray({-3, 0.5f, 0.5f}, {1, 0, 0}), lo, hi, 4.1f, kFloatMax, &t));
}

// A jittered triangulated grid seen from above: rays through its vertices
// and along its shared edges must never fall through (watertightness), in
// either layout.
TEST(BvhRayTests, NoRayFallsThroughSharedEdgesOrVertices) {
  Scene scene;
  scene.add_material(Material{});
  const uint32_t n = 40;
  const Mesh grid = grid_mesh(n, 0.6f, 9);
  const uint32_t mesh = scene.add_mesh(grid);
  // Rotated and translated so the instance transform is exercised too.
  glm::mat4 xf = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(3.0f, -2.0f, 7.0f)), 0.7f,
                             glm::normalize(glm::vec3(0.3f, 1.0f, 0.2f)));
  scene.add_instance({"grid", mesh, xf});
  TracedScene s(std::move(scene));
  const KernelData kd = s.kd();
  TestRandom rng(4);
  uint32_t rays = 0, misses[2] = {0, 0};
  auto shoot = [&](glm::vec3 p_obj) {
    const glm::vec3 p = glm::vec3(xf * glm::vec4(p_obj, 1.0f));
    const glm::vec3 nrm = glm::normalize(glm::vec3(xf * glm::vec4(0, 0, 1, 0)));
    const float uz = rng.uniform(), uy = rng.uniform(), ux = rng.uniform();
    const glm::vec3 dir = glm::normalize(-nrm + 0.4f * glm::vec3(ux - 0.5f, uy - 0.5f, uz - 0.5f));
    const glm::vec3 o = p - 5.0f * dir;
    const Ray ray = {{o.x, o.y, o.z}, 0.0f, {dir.x, dir.y, dir.z}, kFloatMax};
    ++rays;
    for (uint32_t layout = 0; layout < 2; ++layout)
      misses[layout] += hit_valid(bvh_intersect(kd, ray, 0, layout)) ? 0 : 1;
  };
  for (uint32_t j = 1; j < n; ++j) {
    for (uint32_t i = 1; i < n; ++i) {
      const glm::vec3 v = grid.positions[j * (n + 1) + i];
      shoot(v);  // through an interior vertex
      const glm::vec3 right = grid.positions[j * (n + 1) + i + 1],
                      up = grid.positions[(j + 1) * (n + 1) + i];
      shoot(glm::mix(v, right, rng.uniform()));  // along shared edges
      shoot(glm::mix(v, up, rng.uniform()));
    }
  }
  EXPECT_EQ(misses[0], 0u) << "of " << rays;
  EXPECT_EQ(misses[1], 0u) << "of " << rays;
}

// A fully cut-out MASK quad in front of an opaque one: the traversal must
// run the alpha test and find the quad behind, like Embree's filter.
TEST(BvhRayTests, AlphaMaskedTrianglesAreSkipped) {
  Scene scene;
  Material opaque;
  const uint32_t solid = scene.add_material(opaque);
  Material cut;
  cut.alpha_mode = AlphaMode::kMask;
  cut.base_color.w = 0.2f;
  cut.alpha_cutoff = 0.5f;
  const uint32_t masked = scene.add_material(cut);
  Mesh front, back;
  append_quad(front, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, masked, {0, 0, 1});
  append_quad(back, {-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, solid, {0, 0, 1});
  scene.add_instance({"front", scene.add_mesh(front), glm::mat4(1.0f)});
  scene.add_instance({"back", scene.add_mesh(back), glm::mat4(1.0f)});
  TracedScene s(std::move(scene));
  const KernelData kd = s.kd();
  const Ray ray = {{0.1f, 0.2f, 5.0f}, 0.0f, {0, 0, -1}, kFloatMax};
  for (uint32_t layout = 0; layout < 2; ++layout) {
    const Hit h = bvh_intersect(kd, ray, 0, layout);
    ASSERT_TRUE(hit_valid(h));
    EXPECT_EQ(h.instance, 1u);
    EXPECT_NEAR(h.t, 6.0f, 1e-5f);
    const Hit e = s.embree.intersect(ray, 0);
    EXPECT_EQ(e.instance, h.instance);
    EXPECT_EQ(e.prim, h.prim);
    // Occlusion sees through the cut-out too; a segment ending before the
    // back quad is unoccluded.
    EXPECT_TRUE(bvh_occluded(kd, ray, 0, layout));
    Ray short_ray = ray;
    short_ray.tmax = 5.5f;
    EXPECT_FALSE(bvh_occluded(kd, short_ray, 0, layout));
    EXPECT_EQ(s.embree.occluded(short_ray, 0), false);
  }
}

TEST(BvhRayTests, EmptySceneAndEmptyMeshesMiss) {
  Scene scene;
  scene.add_material(Material{});
  scene.add_instance({"nothing", scene.add_mesh(Mesh{}), glm::mat4(1.0f)});
  TracedScene s(std::move(scene));
  const KernelData kd = s.kd();
  EXPECT_EQ(kd.blas_roots[0].bvh_root, kInvalidIndex);
  EXPECT_EQ(kd.bvh.tlas_root, kInvalidIndex);
  const Ray ray = {{0, 0, 5}, 0.0f, {0, 0, -1}, kFloatMax};
  for (uint32_t layout = 0; layout < 2; ++layout) {
    EXPECT_FALSE(hit_valid(bvh_intersect(kd, ray, 0, layout)));
    EXPECT_FALSE(bvh_occluded(kd, ray, 0, layout));
  }
  // A KernelData without any BVH (e.g. before the first update) misses too.
  KernelData none{};
  EXPECT_FALSE(hit_valid(BvhTracer{&none}.intersect(ray, 0)));
}

}  // namespace
}  // namespace tandem
