// The light BVH (core/kernel/light_tree.h, built by core/world/
// light_tree_build.h): the light it chooses at a point follows the
// probability light_tree_pmf gives for it (chi-square), those
// probabilities sum to at most one (the rest: no light), the pmf returned with a choice is the same
// bits as the one recomputed from its trail (what MIS needs), and no light
// that can light a point has probability zero there (no bias).
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "core/world/light_tree_build.h"
#include "tests/test_stats.h"

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
  ASSERT_EQ(tree.nodes.size(), 2u * 500 - 1);
  std::set<uint32_t> leaves;
  double power = 0.0;
  for (const KLightTreeNode& n : tree.nodes) {
    if (n.flags & kLightTreeLeaf) leaves.insert(n.index);
  }
  for (const LightTreeInput& l : lights)
    power += l.power;
  EXPECT_EQ(leaves.size(), 500u);
  EXPECT_NEAR(tree.nodes[0].power, power, 1e-4 * power);
  EXPECT_EQ(std::set<uint64_t>(tree.trails.begin(), tree.trails.end()).size(), 500u);
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
      const float pmf = light_tree_pmf(nodes, count, tree.trails[i], kp, kn);
      sum += pmf;
      expected[i] = pmf;
      if (can_light(lights[i], p, normal)) {
        EXPECT_GT(pmf, 0.0f) << "light " << i << " lights point " << k << " but is never chosen";
      }
    }
    // A branch whose children both turn out unable to light p (the parent's
    // bound was looser) chooses nothing: at most 1 in all, the rest the
    // chance of no light (which costs a sample, never biases: no light
    // under it can light p).
    EXPECT_LE(sum, 1.0 + 1e-5) << "point " << k;
    EXPECT_GT(sum, 0.9) << "point " << k;
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
      ASSERT_EQ(pmf, light_tree_pmf(nodes, count, tree.trails[light], kp, kn))
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
        light_tree_pmf(tree.nodes.data(), uint32_t(tree.nodes.size()), tree.trails[i], p, n);
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
  spot.lo = spot.hi = make_vec3(0.0f, 2.0f, 0.0f);
  spot.power = 1.0f;
  spot.axis = make_vec3(0.0f, -1.0f, 0.0f);
  spot.cos_theta_o = std::cos(0.3f);
  spot.cos_theta_e = 1.0f;
  spot.flags = kLightTreeLeaf;
  const Vec3 up = make_vec3(0.0f, 1.0f, 0.0f);
  EXPECT_GT(light_tree_importance(spot, make_vec3(0.0f, 0.0f, 0.0f), up), 0.0f);
  EXPECT_GT(light_tree_importance(spot, make_vec3(0.5f, 0.0f, 0.0f), up), 0.0f);  // 14 degrees
  EXPECT_EQ(light_tree_importance(spot, make_vec3(1.5f, 0.0f, 0.0f), up), 0.0f);  // 37 degrees
}

}  // namespace
}  // namespace tandem
