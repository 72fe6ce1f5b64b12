// builtin:many-lights, the scene light sampling is measured on: thousands
// of emitters, most of them instances, of varied power and orientation, in
// a closed room; the same scene on every standard library.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/many_lights_scene.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

TEST(ManyLights, ThousandsOfEmittersMostOfThemInstancesFacingEveryWay) {
  const auto names = builtin_scene_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "many-lights"), names.end());
  Scene s = make_builtin_scene("many-lights");
  Compiled c;
  c.settings.light_sampler = LightSampler::kPower;  // its table's probabilities below
  c.compile(s);
  uint32_t punctual = 0;
  std::set<uint32_t> emitting_instances;
  std::set<int> facing;  // the axis and sign each bulb instance emits along
  for (const KLight& l : c.ks.lights) {
    if (l.type == kLightMeshInstance) {
      emitting_instances.insert(l.instance);
    } else if (l.type != kLightEnvironment) {
      ++punctual;
    }
  }
  const ManyLightsCounts counts;
  // The triangles of the four bulb meshes once, however often instanced.
  EXPECT_EQ(c.ks.triangle_lights.size(), 2 * 4 + 2 * counts.panel_cells);
  EXPECT_EQ(punctual, counts.punctual);
  EXPECT_EQ(emitting_instances.size(), counts.bulbs + 1);  // every bulb and the panel
  for (const Instance& inst : s.instances()) {
    if (inst.name.rfind("bulb", 0) != 0) continue;
    const glm::vec3 n = glm::normalize(glm::vec3(inst.transform * glm::vec4(0, -1, 0, 0)));
    for (int axis = 0; axis < 3; ++axis) {
      if (std::fabs(n[axis]) > 0.9f) facing.insert(n[axis] > 0 ? axis + 1 : -(axis + 1));
    }
  }
  EXPECT_EQ(facing.size(), 5u) << "bulbs face down and each of the four horizontal ways";
  // Powers (the power table's choice probabilities) spread over two
  // orders of magnitude.
  float lo = INFINITY, hi = 0.0f;
  for (size_t i = 0; i < c.ks.lights.size(); ++i) {
    if (c.ks.lights[i].type != kLightMeshInstance) continue;
    lo = std::min(lo, c.ks.light_alias[i].pdf);
    hi = std::max(hi, c.ks.light_alias[i].pdf);
  }
  EXPECT_GT(hi / lo, 100.0f);
  // The same room whatever the compiler: every random draw in a fixed order
  // (an -O1 build once evaluated a position's arguments in the other
  // order). The first ceiling bulb's place, as every build must make it:
  const glm::vec4 first_bulb = s.instances()[1].transform[3];
  EXPECT_NEAR(first_bulb.x, 7.32685661f, 1e-5f);
  EXPECT_NEAR(first_bulb.y, 4.98999977f, 1e-5f);
  EXPECT_NEAR(first_bulb.z, -4.45767975f, 1e-5f);
  // Built twice: the same scene.
  Scene again = make_many_lights_scene();
  ASSERT_EQ(again.instances().size(), s.instances().size());
  for (size_t i = 0; i < s.instances().size(); ++i)
    EXPECT_EQ(again.instances()[i].transform, s.instances()[i].transform);
}

}  // namespace
}  // namespace tandem
