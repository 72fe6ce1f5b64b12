// The light BVH (core/kernel/light_tree.h, built by core/world/
// light_tree_build.h): the light it chooses at a point follows the
// probability light_tree_pmf gives for it (chi-square), those
// probabilities sum to at most one (the rest: no light), the pmf returned with a choice is the same
// bits as the one recomputed from its trail (what MIS needs), and no light
// that can light a point has probability zero there (no bias). As the
// scene compiler builds it (--light-sampler tree): every edit gives the
// tables a fresh compile would, and select_light's choices among all of a
// scene's lights (the tree's and the infinite ones) follow the pmf MIS
// recomputes for them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/kernel/lights.h"
#include "core/world/light_tree_build.h"
#include "scenes/builtin_scenes.h"
#include "scenes/deforming_grid.h"
#include "tests/test_stats.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

using namespace test_stats;

// Random lights in a 10 m box: small oriented emitters (cones of 0-90
// degrees, theta_e pi/2 as for surfaces), some two-sided, and points
// emitting everywhere; powers over three orders of magnitude.
std::vector<LightTreeInput> random_lights(uint32_t n, uint32_t seed) {
  TestRng rng(seed);
  std::vector<LightTreeInput> out;
  for (uint32_t i = 0; i < n; ++i) {
    LightTreeInput l;
    const glm::vec3 c(10.0f * rng.next() - 5.0f, 10.0f * rng.next() - 5.0f,
                      10.0f * rng.next() - 5.0f);
    const float size = i % 5 == 0 ? 0.0f : 0.2f * rng.next();
    l.lo = c - glm::vec3(size), l.hi = c + glm::vec3(size);
    const Vec3 d = spherical_direction(std::acos(1.0 - 2.0 * rng.next_double()),
                                       2.0 * M_PI * rng.next_double());
    l.axis = glm::vec3(d.x, d.y, d.z);
    l.cos_theta_o = i % 5 == 0 ? -1.0f : std::cos(0.5f * float(M_PI) * rng.next() * rng.next());
    l.cos_theta_e = i % 5 == 0 ? -1.0f : 0.0f;
    l.two_sided = i % 7 == 3;
    l.power = std::pow(10.0f, 3.0f * rng.next());
    l.light = i;
    out.push_back(l);
  }
  return out;
}

// Whether light `l` can send light to p (normal n, or zero): some point of
// its box sees p within its cone plus theta_e, and p's front sees it.
// Checked at the box's corners and centre: enough for the small boxes here.
bool can_light(const LightTreeInput& l, glm::vec3 p, glm::vec3 n) {
  const float reach = std::acos(std::clamp(l.cos_theta_o, -1.0f, 1.0f)) +
                      std::acos(std::clamp(l.cos_theta_e, -1.0f, 1.0f));
  for (int c = 0; c < 9; ++c) {
    const glm::vec3 q = c == 8 ? 0.5f * (l.lo + l.hi)
                               : glm::vec3(c & 1 ? l.hi.x : l.lo.x, c & 2 ? l.hi.y : l.lo.y,
                                           c & 4 ? l.hi.z : l.lo.z);
    const glm::vec3 w = glm::normalize(p - q);
    float cos_w = glm::dot(w, l.axis);
    if (l.two_sided) cos_w = std::fabs(cos_w);
    const bool emits = std::acos(std::clamp(cos_w, -1.0f, 1.0f)) < reach - 1e-3f;
    const bool receives = glm::dot(n, n) == 0.0f || glm::dot(n, -w) > 1e-3f;
    if (emits && receives) return true;
  }
  return false;
}

TEST(LightTree, EveryLightIsOneLeafWithAUniqueTrail) {
  const std::vector<LightTreeInput> lights = random_lights(500, 1);
  const LightTree tree = build_light_tree(lights, 500);
  // Each light in one leaf (alone, or an entry of a leaf of a few); lights
  // share a trail only in one leaf.
  std::multiset<uint32_t> in_leaves;
  std::set<uint64_t> leaf_trails;
  uint32_t leaves = 0;
  double power = 0.0;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    const KLightTreeNode& n = tree.nodes[i];
    if (!(n.flags & kLightTreeLeaf)) continue;
    ++leaves;
    ASSERT_GE(n.count, 1u);
    ASSERT_LE(n.count, kLightTreeMaxLeafLights);
    leaf_trails.insert(tree.trails[n.index]);
    if (n.count == 1) {
      in_leaves.insert(n.index);
      continue;
    }
    float sum = 0.0f;
    for (uint32_t k = 1; k <= n.count; ++k) {
      in_leaves.insert(tree.nodes[i + k].index);
      EXPECT_EQ(tree.trails[tree.nodes[i + k].index], tree.trails[n.index]);
      sum += tree.nodes[i + k].power;
    }
    EXPECT_NEAR(sum, 1.0f, 1e-5f);
  }
  for (const LightTreeInput& l : lights)
    power += l.power;
  EXPECT_EQ(in_leaves.size(), 500u);
  EXPECT_EQ(std::set<uint32_t>(in_leaves.begin(), in_leaves.end()).size(), 500u);
  EXPECT_EQ(leaf_trails.size(), leaves);
  EXPECT_NEAR(tree.nodes[0].power, power, 1e-4 * power);
  // No light, or none of power: an empty tree, and nothing is chosen.
  std::vector<LightTreeInput> dark = lights;
  for (LightTreeInput& l : dark)
    l.power = 0.0f;
  const LightTree none = build_light_tree(dark, 500);
  EXPECT_TRUE(none.nodes.empty());
  float pmf = 1.0f;
  EXPECT_EQ(light_tree_sample(none.nodes.data(), 0, make_vec3(0.0f), make_vec3(0.0f), 0.5f, &pmf),
            0xffffffffu);
  EXPECT_EQ(pmf, 0.0f);
}

TEST(LightTree, ChoicesFollowThePmfWhichSumsToAtMostOneAndMissesNoLight) {
  const uint32_t n = 300;
  const std::vector<LightTreeInput> lights = random_lights(n, 2);
  const LightTree tree = build_light_tree(lights, n);
  const KLightTreeNode* nodes = tree.nodes.data();
  const uint32_t count = uint32_t(tree.nodes.size());
  TestRng rng(3);
  const int points = 6;
  const double alpha = sidak_alpha(0.01, points);
  for (int k = 0; k < points; ++k) {
    const glm::vec3 p(8.0f * rng.next() - 4.0f, 8.0f * rng.next() - 4.0f, 8.0f * rng.next() - 4.0f);
    const Vec3 d = spherical_direction(std::acos(1.0 - 2.0 * rng.next_double()),
                                       2.0 * M_PI * rng.next_double());
    // Every other point receives from every side (glass): no normal.
    const glm::vec3 normal = k % 2 ? glm::vec3(d.x, d.y, d.z) : glm::vec3(0.0f);
    const Vec3 kp = make_vec3(p.x, p.y, p.z), kn = make_vec3(normal.x, normal.y, normal.z);
    std::vector<double> expected(n, 0.0), observed(n, 0.0);
    double sum = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
      const float pmf = light_tree_pmf(nodes, count, tree.trails[i], i, kp, kn);
      sum += pmf;
      expected[i] = pmf;
      if (can_light(lights[i], p, normal)) {
        EXPECT_GT(pmf, 0.0f) << "light " << i << " lights point " << k << " but is never chosen";
      }
    }
    // A branch whose children both turn out unable to light p (the parent's
    // bound was looser) chooses nothing: at most 1 in all, the rest the
    // chance of no light (which costs a sample, never biases: no light
    // under it can light p). With a random normal most of the lights may
    // be behind p: that chance can be most of it.
    EXPECT_LE(sum, 1.0 + 1e-5) << "point " << k;
    expected.push_back(std::max(0.0, 1.0 - sum));
    observed.push_back(0.0);
    const int samples = 200000;
    for (int s = 0; s < samples; ++s) {
      float pmf = 0.0f;
      const uint32_t light = light_tree_sample(nodes, count, kp, kn, rng.next(), &pmf);
      if (light == 0xffffffffu) {
        EXPECT_EQ(pmf, 0.0f);
        observed[n] += 1.0;
        continue;
      }
      ASSERT_LT(light, n);
      observed[light] += 1.0;
      ASSERT_EQ(pmf, light_tree_pmf(nodes, count, tree.trails[light], light, kp, kn))
          << "the pmf of a choice differs from its trail's";
    }
    for (double& e : expected)
      e *= samples;
    const ChiSquareResult r = chi_square_test(observed, expected);
    EXPECT_TRUE(r.passed(alpha)) << "point " << k << ": " << r.summary();
    if (::testing::Test::HasFailure()) return;
  }
}

// What the tree is for: at a point beside a few bright lights facing it,
// among many facing away or far off, those few get most of the
// probability, where the power table would give them their power's share.
TEST(LightTree, NearLightsFacingThePointTakeMostOfTheProbability) {
  std::vector<LightTreeInput> lights;
  for (uint32_t i = 0; i < 1000; ++i) {
    LightTreeInput l;
    const float x = float(i % 40) - 20.0f, z = float(i / 40) - 12.0f;
    l.lo = l.hi = glm::vec3(x, 3.0f, z);
    l.axis = glm::vec3(0.0f, i % 2 ? -1.0f : 1.0f, 0.0f);  // half face up, at the ceiling
    l.cos_theta_o = 1.0f;
    l.cos_theta_e = 0.0f;
    l.power = 1.0f;
    l.light = i;
    lights.push_back(l);
  }
  const LightTree tree = build_light_tree(lights, 1000);
  const Vec3 p = make_vec3(0.0f, 0.0f, 0.0f), n = make_vec3(0.0f, 1.0f, 0.0f);
  double near_down = 0.0, up = 0.0;
  for (uint32_t i = 0; i < 1000; ++i) {
    const float pmf =
        light_tree_pmf(tree.nodes.data(), uint32_t(tree.nodes.size()), tree.trails[i], i, p, n);
    const glm::vec3 c = lights[i].lo;
    if (lights[i].axis.y > 0.0f) up += pmf;
    if (lights[i].axis.y < 0.0f && std::fabs(c.x) <= 3.0f && std::fabs(c.z) <= 3.0f)
      near_down += pmf;
  }
  EXPECT_EQ(up, 0.0) << "lights facing the ceiling cannot light the floor";
  // 24 of the 500 facing down lie within 3 m: 4.8% by power.
  EXPECT_GT(near_down, 0.3);
}

// A spot: a cone with no falloff beyond it (theta_e 0) lights what is
// inside and nothing outside.
TEST(LightTree, ASpotLightsInsideItsConeOnly) {
  KLightTreeNode spot{};
  spot.center = make_vec3(0.0f, 2.0f, 0.0f);
  spot.power = 1.0f;
  spot.axis = make_vec3(0.0f, -1.0f, 0.0f);
  spot.cos_theta_o = std::cos(0.3f);
  spot.sin_theta_o = std::sin(0.3f);
  spot.cos_theta_e = 1.0f;
  spot.flags = kLightTreeLeaf;
  const Vec3 up = make_vec3(0.0f, 1.0f, 0.0f);
  EXPECT_GT(light_tree_importance(spot, make_vec3(0.0f, 0.0f, 0.0f), up), 0.0f);
  EXPECT_GT(light_tree_importance(spot, make_vec3(0.5f, 0.0f, 0.0f), up), 0.0f);  // 14 degrees
  EXPECT_EQ(light_tree_importance(spot, make_vec3(1.5f, 0.0f, 0.0f), up), 0.0f);  // 37 degrees
}

const WaveGrid kGrid{.cells = 12, .size = 3.0f, .amplitude = 0.2f, .wavelength = 1.3f};

// Every kind of light: an emissive grid (two instances, one turned), a
// plain box-ish grid, a point, a spot, a directional light and a sky.
Scene all_lights_scene() {
  Scene s;
  Material glow;
  glow.base_color = glm::vec4(0.7f, 0.6f, 0.5f, 1.0f);
  glow.emissive = glm::vec3(2.0f, 1.5f, 1.0f);
  s.add_material(glow);
  s.add_material(Material{});
  s.add_mesh(make_wave_grid(kGrid));
  s.add_mesh(make_wave_grid(WaveGrid{.cells = 4, .size = 1.0f}, 1));
  s.add_instance({"a", 0, glm::mat4(1.0f)});
  s.add_instance({"b", 0,
                  glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 2.0f, 0.0f)), 2.5f,
                              glm::vec3(1.0f, 0.0f, 0.0f))});
  s.add_instance({"c", 1, glm::translate(glm::mat4(1.0f), glm::vec3(3.0f, 0.0f, 0.0f))});
  // Stretched: its normals' cone widens by a bound, not by the angle.
  s.add_instance({"d", 0,
                  glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(-3.0f, 1.0f, 2.0f)),
                             glm::vec3(1.5f, 0.5f, 1.0f))});
  // Mirrored and sheared: the front (the winding's side) flips with the
  // handedness, which the tree's object-space tests must follow.
  glm::mat4 shear(1.0f);
  shear[1][0] = 0.4f;
  s.add_instance({"e", 0,
                  glm::translate(glm::mat4(1.0f), glm::vec3(2.0f, 3.0f, -2.0f)) * shear *
                      glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.0f, 1.0f))});
  // A flat lamp off to the side: its two triangles a leaf of two.
  Mesh lamp;
  append_quad(lamp, {4.0f, 3.0f, 4.0f}, {5.0f, 3.0f, 4.0f}, {5.0f, 3.0f, 5.0f}, {4.0f, 3.0f, 5.0f},
              0, {0.0f, -1.0f, 0.0f});
  s.add_instance({"lamp", s.add_mesh(std::move(lamp)), glm::mat4(1.0f)});
  Light point;
  point.position = glm::vec3(0.0f, 5.0f, 0.0f);
  point.intensity = 20.0f;
  s.add_light(point);
  Light spot = point;
  spot.type = LightType::kSpot;
  spot.position = glm::vec3(-2.0f, 3.0f, 1.0f);
  spot.direction = glm::vec3(0.3f, -1.0f, 0.0f);
  spot.outer_cone_angle = 0.5f;
  spot.inner_cone_angle = 0.3f;
  s.add_light(spot);
  Light sun;
  sun.type = LightType::kDirectional;
  sun.direction = glm::vec3(0.2f, -1.0f, 0.1f);
  sun.intensity = 0.5f;
  s.add_light(sun);
  Environment sky;
  sky.color = glm::vec3(0.05f, 0.07f, 0.1f);
  s.set_environment(sky);
  return s;
}

RenderSettings tree_settings() {
  RenderSettings settings;
  settings.light_sampler = LightSampler::kTree;
  return settings;
}

void expect_fresh(Scene& scene, const KernelScene& ks, const RenderSettings& settings, int step) {
  Scene copy = scene;
  Compiled fresh;
  fresh.settings = settings;
  fresh.compile(copy);
  expect_same_scene_arrays(ks, fresh.ks, step);
}

TEST(LightTreeCompile, EveryEditGivesTheTablesOfAFreshCompile) {
  Scene scene = all_lights_scene();
  Compiled c;
  c.settings = tree_settings();
  c.compile(scene);
  const KernelScene& ks = c.ks;
  ASSERT_FALSE(ks.light_tree_nodes.empty());
  EXPECT_EQ(ks.light_tree_trails.size(), ks.lights.size());
  // Points, spots and triangles in the tree; the sun and the sky beside it.
  EXPECT_GT(ks.constants.light_tree_fraction, 0.0f);
  EXPECT_LT(ks.constants.light_tree_fraction, 1.0f);
  EXPECT_GE(ks.light_tree_nodes.size(), ks.triangle_lights.size() + ks.lights.size() - 2);
  EXPECT_EQ(ks.instance_lights.size(), ks.instances.size());
  // The emissive grid's triangles once for its two instances.
  EXPECT_EQ(ks.triangle_lights.size(), 2u * kGrid.cells * kGrid.cells + 2u);
  expect_fresh(scene, ks, c.settings, 0);

  // A rigid move of an emissive instance: the tree's boxes and cones follow,
  // refit along its path only (the meshes' trees and the light list stay).
  const std::vector<KLightTreeNode> before = ks.light_tree_nodes;
  scene.set_instance_transform(
      1, glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(1.0f, 2.0f, 0.0f)), 2.0f,
                     glm::vec3(0.0f, 0.0f, 1.0f)));
  SceneDelta d = c.compile(scene);
  EXPECT_TRUE(d.light_tree_nodes.any());
  EXPECT_FALSE(d.light_tree_nodes.reallocated);
  EXPECT_FALSE(d.lights.reallocated || d.triangle_lights.any());
  EXPECT_LT(d.light_tree_nodes.element_count(), 16u);
  EXPECT_FALSE(same_bytes(before, ks.light_tree_nodes));
  expect_fresh(scene, ks, c.settings, 1);
  // Deformed emissive vertices: the tree over their new places. (The sun's
  // and the sky's powers follow the scene's size only once it changed by
  // 10%: the alias table and the fraction may differ from a fresh compile's
  // in the last bits, as they do with the power table.)
  deform_wave_grid(scene.edit_mesh_vertices(0, 0, kGrid.vertex_count()), kGrid, 0.4f);
  d = c.compile(scene);
  EXPECT_TRUE(d.light_tree_nodes.any());
  EXPECT_FALSE(d.light_tree_nodes.reallocated);
  {
    Scene copy = scene;
    Compiled fresh;
    fresh.settings = c.settings;
    fresh.compile(copy);
    EXPECT_TRUE(same_bytes(ks.triangle_lights, fresh.ks.triangle_lights));
    expect_light_trees_bound_their_lights(ks, 2);
  }
  // A punctual light moved, one switched off.
  scene.edit_light(0).position = glm::vec3(1.0f, 4.0f, -1.0f);
  scene.edit_light(1).intensity = 0.0f;
  c.compile(scene);
  expect_fresh(scene, ks, c.settings, 3);
  // The power table and back: each sampler's tables, the tree's gone.
  c.settings.light_sampler = LightSampler::kPower;
  c.compile(scene);
  EXPECT_TRUE(ks.light_tree_nodes.empty());
  EXPECT_EQ(ks.constants.light_tree_fraction, 0.0f);
  expect_fresh(scene, ks, c.settings, 4);
  c.settings.light_sampler = LightSampler::kTree;
  c.compile(scene);
  expect_fresh(scene, ks, c.settings, 5);
}

// What the renderer does with the tables: select_light's choice at a point,
// among all the scene's lights (an instance's triangles one by one), has
// the probability that the MIS of a BSDF sample finding that light
// recomputes (for a triangle from (instance, prim) alone, as a hit knows
// it), bit for bit, and the choices follow those probabilities
// (chi-square), on a tree refit after a move.
TEST(LightTreeCompile, ChoicesAmongAllLightsFollowThePmfMisRecomputes) {
  Scene scene = all_lights_scene();
  Compiled c;
  c.settings = tree_settings();
  c.compile(scene);
  // Moved: the tree refit along the instance's path, not built anew.
  scene.set_instance_transform(
      1, glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.5f, 1.5f, 0.0f)), 1.0f,
                     glm::vec3(0.0f, 0.0f, 1.0f)));
  ASSERT_FALSE(c.compile(scene).light_tree_nodes.reallocated);
  const KernelData kd = c.ks.view();
  // The grid's quads are leaves of two triangles: the scan within a leaf is
  // tested too.
  EXPECT_TRUE(std::any_of(
      c.ks.light_tree_nodes.begin(), c.ks.light_tree_nodes.end(),
      [](const KLightTreeNode& node) { return (node.flags & kLightTreeLeaf) && node.count > 1; }));
  Scene copy = scene;
  Compiled power_table;
  power_table.compile(copy);
  // Every choice: a punctual or infinite light, or a triangle of an
  // instance (by its light and its triangle light).
  std::vector<LightChoice> outcomes;
  for (uint32_t i = 0; i < kd.lights_count; ++i) {
    const KLight& l = kd.lights[i];
    if (l.type != kLightMeshInstance) {
      outcomes.push_back({i, kInvalidIndex, 0.0f});
      continue;
    }
    const KMeshLights& ml = kd.mesh_lights[kd.instances[l.instance].mesh];
    for (uint32_t t = ml.first; t < ml.first + ml.count; ++t)
      outcomes.push_back({i, t, 0.0f});
  }
  const uint32_t n = uint32_t(outcomes.size());
  const auto pmf_of = [&](const LightChoice& o, Vec3 p, Vec3 normal) -> float {
    const KLight& l = kd.lights[o.light];
    if (l.type == kLightMeshInstance) {
      return triangle_light_pmf(kd, l.instance, kd.triangle_lights[o.triangle].prim, p, normal);
    }
    if (l.type == kLightDirectional || l.type == kLightEnvironment)
      return kd.light_alias[o.light].pdf;
    return kd.constants.light_tree_fraction *
           light_tree_pmf_at(kd.light_tree_nodes, kd.constants.light_tree_root,
                             kd.light_tree_trails[o.light], o.light, p, normal);
  };
  const auto outcome_of = [&](const LightChoice& c) {
    for (uint32_t k = 0; k < n; ++k) {
      if (outcomes[k].light == c.light &&
          (outcomes[k].triangle == kInvalidIndex || outcomes[k].triangle == c.triangle)) {
        return k;
      }
    }
    return n;
  };
  TestRng rng(11);
  const int points = 4;
  const double alpha = sidak_alpha(0.01, points);
  for (int k = 0; k < points; ++k) {
    const Vec3 p = make_vec3(4.0f * rng.next() - 2.0f, 3.0f * rng.next(), 4.0f * rng.next() - 2.0f);
    const Vec3 normal = spherical_direction(std::acos(1.0 - 2.0 * rng.next_double()),
                                            2.0 * M_PI * rng.next_double());
    std::vector<double> expected(n + 1, 0.0), observed(n + 1, 0.0);
    double sum = 0.0;
    for (uint32_t i = 0; i < n; ++i)
      sum += expected[i] = pmf_of(outcomes[i], p, normal);
    EXPECT_LE(sum, 1.0 + 1e-5) << "point " << k;
    EXPECT_GT(sum, 0.0) << "point " << k;
    expected[n] = std::max(0.0, 1.0 - sum);  // no light
    // The sky's share is its power's, as with the power table.
    const uint32_t env = kd.constants.environment_light_index;
    ASSERT_NE(env, kInvalidIndex);
    EXPECT_NEAR(expected[outcome_of({env, kInvalidIndex, 0.0f})],
                power_table.ks.light_alias[env].pdf, 1e-6);
    const int samples = 200000;
    for (int s = 0; s < samples; ++s) {
      const LightChoice choice = select_light(kd, p, normal, rng.next());
      if (!(choice.pmf > 0.0f)) {
        observed[n] += 1.0;
        continue;
      }
      const uint32_t o = outcome_of(choice);
      ASSERT_LT(o, n);
      observed[o] += 1.0;
      ASSERT_EQ(choice.pmf, pmf_of(choice, p, normal)) << "outcome " << o << " at point " << k;
    }
    for (double& e : expected)
      e *= samples;
    const ChiSquareResult r = chi_square_test(observed, expected);
    EXPECT_TRUE(r.passed(alpha)) << "point " << k << ": " << r.summary();
  }
}

}  // namespace
}  // namespace tandem
