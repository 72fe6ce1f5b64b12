// SceneCompiler's incremental updates: each kind of edit touches only the
// kernel arrays it has to (what the CUDA backend uploads every frame), and
// the light data stays consistent with the instances. Also where the
// texels lie in memory (huge pages, core/util/huge_pages.h).
#include <gtest/gtest.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/util/huge_pages.h"
#include "core/util/log.h"
#include "core/world/kernel_scene.h"
#include "scenes/builtin_scenes.h"
#include "tests/world_compile_util.h"

namespace tandem {
namespace {

struct TwoQuads {
  Scene scene;
  uint32_t floor_instance = 0, lamp_instance = 0, lamp_material = 0;
};

// A white floor and a small emissive quad above it, one instance each.
TwoQuads make_two_quads() {
  TwoQuads t;
  Material white;
  white.name = "white";
  white.base_color = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  const uint32_t floor_mat = t.scene.add_material(white);
  Material lamp = white;
  lamp.name = "lamp";
  lamp.emissive = glm::vec3(4.0f);
  t.lamp_material = t.scene.add_material(lamp);
  Mesh floor, quad;
  floor.name = "floor";
  quad.name = "lamp";
  append_quad(floor, {-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, floor_mat, {0, 1, 0});
  append_quad(quad, {-0.5f, 0, -0.5f}, {-0.5f, 0, 0.5f}, {0.5f, 0, 0.5f}, {0.5f, 0, -0.5f},
              t.lamp_material, {0, -1, 0});
  const uint32_t floor_mesh = t.scene.add_mesh(std::move(floor));
  const uint32_t lamp_mesh = t.scene.add_mesh(std::move(quad));
  t.floor_instance = t.scene.add_instance({"floor", floor_mesh, glm::mat4(1.0f)});
  t.lamp_instance = t.scene.add_instance(
      {"lamp", lamp_mesh, glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0))});
  Camera cam;
  cam.position = {0, 1, 6};
  cam.forward = {0, 0, -1};
  cam.up = {0, 1, 0};
  t.scene.set_camera(cam);
  return t;
}

TEST(SceneCompiler, FirstCompileIsFullAndAnUnchangedSceneGivesAnEmptyDelta) {
  TwoQuads t = make_two_quads();
  Compiled c;
  EXPECT_TRUE(c.compile(t.scene).full);
  const SceneDelta again = c.compile(t.scene);
  EXPECT_FALSE(again.any());
  EXPECT_EQ(again.bytes(c.ks), 0u);
}

// With the power table; the light tree's boxes and cones follow a move
// (world_light_tree_test.cpp). The instance's triangle lights are its
// mesh's, in object space: only its own light (its world power) and the
// table over the lights are rewritten.
TEST(SceneCompiler, MovingAnEmissiveInstanceRigidlyKeepsTheLightArrays) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.settings.light_sampler = LightSampler::kPower;
  c.compile(t.scene);
  const float power_before = c.ks.constants.total_light_power;
  // Rotate and move the lamp: same areas, same powers.
  const glm::mat4 moved = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(1, 2.5f, -1)), 0.7f,
                                      glm::normalize(glm::vec3(1, 1, 0)));
  t.scene.set_instance_transform(t.lamp_instance, moved);
  const SceneDelta d = c.compile(t.scene);
  EXPECT_TRUE(d.instances_changed());
  EXPECT_EQ(d.instances.begin, t.lamp_instance);
  EXPECT_EQ(d.instances.end, t.lamp_instance + 1);
  EXPECT_LE(d.lights.element_count(), 1u);
  EXPECT_FALSE(d.lights.reallocated || d.light_alias.reallocated);
  EXPECT_FALSE(d.triangle_lights.any() || d.triangle_light_alias.any() || d.mesh_lights.any());
  EXPECT_FALSE(d.full);
  EXPECT_NEAR(c.ks.constants.total_light_power, power_before, 1e-6f * power_before);
  EXPECT_LT(d.bytes(c.ks), 1024u);
}

TEST(SceneCompiler, ScalingAnEmissiveInstanceRecomputesLightPower) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  const float power_before = c.ks.constants.total_light_power;
  t.scene.set_instance_transform(
      t.lamp_instance,
      glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0)), glm::vec3(2.0f)));
  const SceneDelta d = c.compile(t.scene);
  EXPECT_TRUE(d.lights.any() || d.light_alias.any());
  // Twice the size, four times the area and the emitted power.
  EXPECT_NEAR(c.ks.constants.total_light_power, 4.0f * power_before, 1e-3f * power_before);
}

TEST(SceneCompiler, MaterialEditTouchesOnlyThatMaterial) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  t.scene.edit_material(0).base_color = glm::vec4(0.2f, 0.3f, 0.4f, 1.0f);
  const SceneDelta d = c.compile(t.scene);
  EXPECT_EQ(d.materials.begin, 0u);
  EXPECT_EQ(d.materials.end, 1u);
  EXPECT_FALSE(d.instances_changed());
  EXPECT_FALSE(d.lights.any());
  EXPECT_NEAR(c.ks.materials[0].base_color.y, 0.3f, 1e-6f);
}

// The mean luminance of an emissive texture scales its material's emission
// for light sampling; the compiler takes it at the texture's first use as
// an emissive texture (not for every texture of a model). Checked against
// the sRGB curve written out here, after the first compile and after an
// edit that makes a second texture emissive.
TEST(SceneCompiler, EmissiveTexturesCarryTheirMeanLuminance) {
  TwoQuads t = make_two_quads();
  const auto texture = [](uint32_t seed) {
    Texture tex;
    tex.width = 4;
    tex.height = 3;
    for (uint32_t i = 0; i < tex.width * tex.height; ++i) {
      const uint32_t v = (seed + 53u * i) * 2654435761u;
      tex.rgba8.push_back(v | 0xff000000u);
    }
    return tex;
  };
  const auto mean_luminance = [](const Texture& tex) {
    const auto decode = [](uint32_t byte) {
      const double c = double(byte & 0xffu) / 255.0;
      return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    };
    double sum = 0.0;
    for (uint32_t px : tex.rgba8)
      sum += 0.2126 * decode(px) + 0.7152 * decode(px >> 8) + 0.0722 * decode(px >> 16);
    return sum / double(tex.rgba8.size());
  };
  const Texture base = texture(1), glow = texture(2);
  const uint32_t base_tex = t.scene.add_texture(base), glow_tex = t.scene.add_texture(glow);
  t.scene.edit_material(0).base_color_texture.texture = int32_t(base_tex);
  t.scene.edit_material(t.lamp_material).emissive_texture.texture = int32_t(glow_tex);
  Compiled c;
  c.compile(t.scene);
  const double glow_mean = mean_luminance(glow), base_mean = mean_luminance(base);
  ASSERT_GT(std::fabs(glow_mean - base_mean), 0.01);
  EXPECT_NEAR(c.ks.materials[t.lamp_material].emission_luminance_scale, glow_mean,
              1e-5 * glow_mean);
  EXPECT_EQ(c.ks.materials[0].emission_luminance_scale, 1.0f);  // not emissive-textured
  // An edit makes the floor's base colour texture its emissive one too.
  Material& floor = t.scene.edit_material(0);
  floor.emissive = glm::vec3(1.0f);
  floor.emissive_texture.texture = int32_t(base_tex);
  c.compile(t.scene);
  EXPECT_NEAR(c.ks.materials[0].emission_luminance_scale, base_mean, 1e-5 * base_mean);
  EXPECT_NEAR(c.ks.materials[t.lamp_material].emission_luminance_scale, glow_mean,
              1e-5 * glow_mean);
}

// A node scaled to 0 (how an animation hides an object) is compiled hidden:
// out of the TLAS and the bounds, its triangle lights without power; scaled
// back it is drawn again. One notice for all such instances.
TEST(SceneCompiler, AnInstanceScaledToZeroIsHiddenUntilItIsScaledBack) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  const float power_before = c.ks.constants.total_light_power;
  ASSERT_GT(power_before, 0.0f);
  const glm::mat4 placed = glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0));
  testing::internal::CaptureStderr();
  const LogLevel level = log_level();
  set_log_level(LogLevel::kInfo);
  for (int round = 0; round < 2; ++round) {
    t.scene.set_instance_transform(t.lamp_instance, glm::scale(placed, glm::vec3(0.0f)));
    t.scene.set_instance_transform(t.floor_instance,
                                   glm::scale(glm::mat4(1.0f), glm::vec3(1e-12f)));
    const SceneDelta hidden = c.compile(t.scene);
    EXPECT_TRUE(hidden.instances_changed());
    for (uint32_t i : {t.lamp_instance, t.floor_instance}) {
      EXPECT_TRUE(c.ks.instances[i].flags & kInstanceHidden) << i;
      for (const Vec4& row : c.ks.instances[i].world_to_object.rows)
        EXPECT_TRUE(row.x == 0.0f && row.y == 0.0f && row.z == 0.0f && row.w == 0.0f);
    }
    EXPECT_TRUE(t.scene.bounds().empty);
    EXPECT_LT(c.ks.constants.total_light_power, 1e-6f * power_before);
    t.scene.set_instance_transform(t.lamp_instance, placed);
    t.scene.set_instance_transform(t.floor_instance, glm::mat4(1.0f));
    c.compile(t.scene);
    EXPECT_FALSE(c.ks.instances[t.lamp_instance].flags & kInstanceHidden);
    EXPECT_NEAR(c.ks.constants.total_light_power, power_before, 1e-5f * power_before);
    EXPECT_EQ(t.scene.bounds().hi.y, 2.0f);
  }
  set_log_level(level);
  const std::string log = testing::internal::GetCapturedStderr();
  size_t notices = 0;
  for (size_t p = log.find("not drawn"); p != std::string::npos; p = log.find("not drawn", p + 1))
    ++notices;
  EXPECT_EQ(notices, 1u) << log;
  EXPECT_NE(log.find("has a singular transform"), std::string::npos) << log;
}

// Vertices edited out of float hide every instance of their mesh, with a
// warning naming it, until they are finite again: the tracers never see them.
TEST(SceneCompiler, AMeshDeformedOutOfFloatIsHiddenUntilItIsFiniteAgain) {
  TwoQuads t = make_two_quads();
  Compiled c;
  c.compile(t.scene);
  const uint32_t lamp_mesh = t.scene.instances()[t.lamp_instance].mesh;
  const glm::vec3 before = t.scene.meshes()[lamp_mesh].positions[0];
  testing::internal::CaptureStderr();
  t.scene.edit_mesh_vertices(lamp_mesh).positions[0].x = std::numeric_limits<float>::infinity();
  SceneDelta d = c.compile(t.scene);
  EXPECT_TRUE(d.instances_changed());
  EXPECT_TRUE(c.ks.instances[t.lamp_instance].flags & kInstanceHidden);
  EXPECT_FALSE(c.ks.instances[t.floor_instance].flags & kInstanceHidden);
  EXPECT_TRUE(t.scene.bounds().finite);
  EXPECT_EQ(t.scene.bounds().hi.y, 0.0f);                        // the floor alone
  t.scene.edit_mesh_vertices(lamp_mesh).positions[0].x = 1e20f;  // finite, out of range
  c.compile(t.scene);
  EXPECT_TRUE(c.ks.instances[t.lamp_instance].flags & kInstanceHidden);
  t.scene.edit_mesh_vertices(lamp_mesh).positions[0] = before;
  d = c.compile(t.scene);
  EXPECT_TRUE(d.instances_changed());
  EXPECT_FALSE(c.ks.instances[t.lamp_instance].flags & kInstanceHidden);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("instance 1 ('lamp') of mesh 1 ('lamp') has positions that are not finite"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("instance 1 ('lamp') of mesh 1 ('lamp') lies beyond 1e+09"), std::string::npos)
      << log;
}

// A punctual light an edit takes beyond what can be traced is off (no
// radiance, no power) with a warning naming it, and on again when it is back.
TEST(SceneCompiler, LightsBeyondTheRangeAreOffUntilTheyAreBack) {
  TwoQuads t = make_two_quads();
  Light bulb;
  bulb.name = "bulb";
  bulb.type = LightType::kPoint;
  bulb.position = {0, 1, 0};
  bulb.intensity = 5.0f;
  const uint32_t light = t.scene.add_light(bulb);
  Compiled c;
  c.compile(t.scene);
  const Vec3 on = c.ks.lights[light].intensity;
  ASSERT_GT(on.x, 0.0f);
  testing::internal::CaptureStderr();
  using Edit = void (*)(Light&);
  const Edit edits[] = {
      [](Light& l) { l.intensity = std::numeric_limits<float>::infinity(); },
      [](Light& l) { l.intensity = 1e35f; },
      [](Light& l) { l.position.x = 1e20f; },
      [](Light& l) { l.position.y = std::numeric_limits<float>::quiet_NaN(); },
  };
  for (const Edit edit : edits) {
    edit(t.scene.edit_light(light));
    c.compile(t.scene);
    EXPECT_EQ(c.ks.lights[light].intensity.x, 0.0f);
    EXPECT_TRUE(std::isfinite(c.ks.constants.total_light_power));
    t.scene.edit_light(light) = bulb;
    c.compile(t.scene);
    EXPECT_EQ(c.ks.lights[light].intensity.x, on.x);
  }
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("light 0 ('bulb') is not finite, out of range or brighter than can be "
                     "rendered: it is off"),
            std::string::npos)
      << log;
}

// The VmFlags line of the mapping in /proc/self/smaps that holds `address`
// ("" where there is none or no smaps to read).
std::string mapping_flags(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  const uintptr_t a = reinterpret_cast<uintptr_t>(address);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    uintptr_t begin = 0, end = 0;
    if (std::sscanf(line.c_str(), "%" SCNxPTR "-%" SCNxPTR " ", &begin, &end) == 2 &&
        line.find(':') > line.find(' ')) {
      inside = a >= begin && a < end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      return line;
    }
  }
  return "";
}

TEST(HugePages, AdviceCoversTheWholeHugePagesInsideTheRange) {
  const size_t huge = kHugePageBytes;
  std::vector<char> buffer(5 * huge);
  const uintptr_t base = reinterpret_cast<uintptr_t>(buffer.data());
  const uintptr_t first = (base + huge - 1) & ~uintptr_t(huge - 1);
  // From an aligned start: two whole pages of 2.5; a range inside one page: none.
  const void* start = reinterpret_cast<const void*>(first);
  if (advise_huge_pages(start, huge * 2 + huge / 2) == 0) {
    GTEST_SKIP() << "this system does not take transparent huge page advice";
  }
  EXPECT_EQ(advise_huge_pages(start, huge * 2 + huge / 2), 2 * huge);
  EXPECT_EQ(advise_huge_pages(reinterpret_cast<const void*>(first + 4096), huge), 0u);
  // From 4 KiB past a boundary: the range's first whole page starts at the next.
  EXPECT_EQ(advise_huge_pages(reinterpret_cast<const void*>(first + 4096), 2 * huge), huge);
  EXPECT_EQ(advise_huge_pages(nullptr, 4 * huge), 0u);
}

// Texture lookups land at random all over the texel array: the compiler
// reserves it whole and advises huge pages before writing it, so a lookup
// does not miss the TLB on every row (measured in
// docs/performance/log/cpu_path_tracing.md). Read back from the mapping's
// flags ("hg": huge page advice).
TEST(SceneCompiler, TexelsLieInMemoryAdvisedForHugePages) {
  std::vector<char> probe(3 * kHugePageBytes);
  if (advise_huge_pages(probe.data(), probe.size()) == 0 || mapping_flags(probe.data()).empty()) {
    GTEST_SKIP() << "no transparent huge page advice or no /proc/self/smaps here";
  }
  TwoQuads t = make_two_quads();
  Texture tex;
  tex.width = 1024;
  tex.height = 1536;  // 6 MiB of texels: at least two whole huge pages
  tex.rgba8.assign(size_t(tex.width) * tex.height, 0xff808080u);
  t.scene.edit_material(0).base_color_texture.texture = int32_t(t.scene.add_texture(tex));
  Compiled c;
  c.compile(t.scene);
  ASSERT_EQ(c.ks.texels.size(), tex.rgba8.size());
  const uintptr_t base = reinterpret_cast<uintptr_t>(c.ks.texels.data());
  const uintptr_t inside = (base + kHugePageBytes - 1) & ~uintptr_t(kHugePageBytes - 1);
  const std::string flags = mapping_flags(reinterpret_cast<const void*>(inside));
  EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
}

}  // namespace
}  // namespace tandem
