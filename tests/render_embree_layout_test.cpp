// The CPU backend's two Embree layouts (backends/cpu/embree_tracer.h): a
// static scene without instancing is traced flat (identity instances without
// an instance level), and must answer every query exactly as the two-level
// scene does, bit for bit (frames of an animation are compared bit for bit
// with still renders, which may be traced in the other layout), alpha tests
// included; a scene whose instance moves turns two-level for good.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "backends/cpu/embree_tracer.h"
#include "core/kernel/camera.h"
#include "core/kernel/sampling.h"
#include "core/world/kernel_scene.h"
#include "scenes/deforming_grid.h"
#include "scenes/procedural_scenes.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

constexpr uint32_t kWidth = 48, kHeight = 36;

struct Compiled {
  Scene scene;
  RenderSettings settings;
  SceneSync sync{SceneSyncSettings::arrays_only()};
  const KernelScene& ks = sync.kernel_scene();
  SceneDelta delta;

  explicit Compiled(Scene s) : scene(std::move(s)) {
    settings.width = kWidth;
    settings.height = kHeight;
    if (!scene.has_camera()) {
      scene.set_camera(frame_bounds_camera(scene.bounds(), 0.69f, float(kWidth) / float(kHeight)));
    }
    delta = sync.update(scene, settings).changes;
  }
};

// Camera rays over the image and, from each first hit, a ray in a
// hashed direction (rays that start on surfaces and hit other instances).
std::vector<Ray> query_rays(const KernelData& kd, const EmbreeTracer& tracer) {
  std::vector<Ray> rays;
  for (uint32_t y = 0; y < kHeight; y += 2) {
    for (uint32_t x = 0; x < kWidth; x += 2) {
      const Ray cam =
          generate_camera_ray(kd.constants.camera, float(x) + 0.5f, float(y) + 0.5f, 0.5f, 0.5f);
      rays.push_back(cam);
      const Hit h = tracer.intersect(cam, 0);
      if (!hit_valid(h)) continue;
      const float u1 = float((x * 7919u + y * 104729u) % 1000u) / 1000.0f;
      const float u2 = float((x * 15485863u + y * 32452843u) % 1000u) / 1000.0f;
      const Vec3 dir = sample_uniform_sphere(u1, u2);
      const Vec3 p = cam.origin + cam.dir * (h.t * 0.999f);
      rays.push_back({p, 0.0f, dir, kFloatMax});
    }
  }
  return rays;
}

// Queries of `flat` and `two_level` give the same hits, bit for bit, and
// the same occlusion short of and past each hit.
void expect_same_answers(const KernelData& kd, const EmbreeScene& flat,
                         const EmbreeScene& two_level) {
  const EmbreeTracer a{flat.top_level(), &kd}, b{two_level.top_level(), &kd};
  const std::vector<Ray> rays = query_rays(kd, b);
  size_t hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    SCOPED_TRACE(i);
    const uint32_t key = uint32_t(i) * 0x9e3779b9u;
    const Hit ha = a.intersect(rays[i], key), hb = b.intersect(rays[i], key);
    ASSERT_EQ(std::memcmp(&ha, &hb, sizeof ha), 0) << ha.instance << " " << hb.instance;
    if (!hit_valid(ha)) continue;
    ++hits;
    Ray shorter = rays[i], longer = rays[i];
    shorter.tmax = hb.t * 0.99f;
    longer.tmax = hb.t * 1.01f;
    EXPECT_EQ(a.occluded(shorter, key), b.occluded(shorter, key));
    EXPECT_TRUE(a.occluded(longer, key));
    EXPECT_TRUE(b.occluded(longer, key));
  }
  EXPECT_GT(hits, rays.size() / 3);
}

uint32_t material_named(const Scene& scene, const std::string& name) {
  for (uint32_t i = 0; i < scene.materials().size(); ++i) {
    if (scene.materials()[i].name == name) return i;
  }
  ADD_FAILURE() << "no material " << name;
  return 0;
}

TEST(EmbreeLayout, StaticScenesWithoutInstancingAreFlatAndAnswerAsTwoLevel) {
  // The box alone: one identity instance; with the spheres: two translated
  // instances beside it, which stay instances.
  for (const char* spec : {"builtin:cornell", "builtin:cornell-spheres"}) {
    SCOPED_TRACE(spec);
    Compiled c(load_scene(spec));
    EmbreeScene flat, two_level;
    two_level.disallow_flat();
    flat.sync(c.ks, c.delta);
    two_level.sync(c.ks, c.delta);
    EXPECT_TRUE(flat.flat());
    EXPECT_FALSE(two_level.flat());
    expect_same_answers(c.ks.view(), flat, two_level);
  }
}

TEST(EmbreeLayout, AlphaTestsSeeTheirInstanceInTheFlatScene) {
  // The glass sphere (an instance) and the red wall (of the box, an identity
  // instance in the top-level scene) cut out entirely (alpha 0.25 below a
  // 0.5 cutoff): a filter that read the wrong instance would keep them.
  Scene scene = load_scene("builtin:cornell-spheres");
  for (const char* name : {"glass", "red"}) {
    Material& m = scene.edit_material(material_named(scene, name));
    m.alpha_mode = AlphaMode::kMask;
    m.base_color.w = 0.25f;
  }
  Compiled c(std::move(scene));
  EmbreeScene flat, two_level;
  two_level.disallow_flat();
  flat.sync(c.ks, c.delta);
  two_level.sync(c.ks, c.delta);
  ASSERT_TRUE(flat.flat());
  expect_same_answers(c.ks.view(), flat, two_level);
  // A ray at the glass sphere's centre passes through it.
  const KernelData kd = c.ks.view();
  const EmbreeTracer tracer{flat.top_level(), &kd};
  const glm::vec3 centre = glm::vec3(370.0f, 100.0f, 169.0f) * 0.001f;
  const Vec3 origin = {centre.x, centre.y, centre.z - 0.5f};
  const Hit h = tracer.intersect({origin, 0.0f, {0.0f, 0.0f, 1.0f}, kFloatMax}, 0);
  ASSERT_TRUE(hit_valid(h));
  EXPECT_GT(h.t, 0.6f);  // past the sphere (radius 0.1), on the back wall
  // A ray towards the red wall (x = 0.55) leaves the box through it.
  EXPECT_FALSE(
      hit_valid(tracer.intersect({{0.3f, 0.27f, 0.3f}, 0.0f, {1.0f, 0.0f, 0.0f}, kFloatMax}, 0)));
  EXPECT_TRUE(
      hit_valid(tracer.intersect({{0.3f, 0.27f, 0.3f}, 0.0f, {-1.0f, 0.0f, 0.0f}, kFloatMax}, 0)));
}

TEST(EmbreeLayout, InstancedScenesStayTwoLevel) {
  Compiled c(make_procedural_scene(20000, 3));
  EmbreeScene embree;
  embree.sync(c.ks, c.delta);
  EXPECT_FALSE(embree.flat());
}

TEST(EmbreeLayout, AMovedInstanceTurnsTheSceneTwoLevel) {
  Compiled c(load_scene("builtin:cornell-spheres"));
  EmbreeScene embree;
  embree.sync(c.ks, c.delta);
  ASSERT_TRUE(embree.flat());
  const uint32_t sphere = 1;  // the mirror sphere (instance 0 is the box)
  c.scene.set_instance_transform(sphere,
                                 glm::translate(glm::mat4(1.0f), glm::vec3(0.2f, 0.1f, 0.3f)));
  const SceneDelta moved = c.sync.update(c.scene, c.settings).changes;
  embree.sync(c.ks, moved);
  EXPECT_FALSE(embree.flat());
  // It traces the moved scene: the same answers as a scene built for it.
  EmbreeScene fresh;
  fresh.disallow_flat();
  fresh.sync(c.ks, moved);
  expect_same_answers(c.ks.view(), embree, fresh);
  // And it stays two-level through the next frames.
  const SceneDelta again = c.sync.update(c.scene, c.settings).changes;
  embree.sync(c.ks, again);
  EXPECT_FALSE(embree.flat());
}

// A frame that deforms one mesh or moves one instance commits again only the
// instances it touched (those of the refit mesh, or the moved one), and
// traces like an Embree scene built for that frame.
TEST(EmbreeLayout, AFrameCommitsOnlyTheInstancesItTouched) {
  Scene scene;
  scene.add_material(Material{});
  WaveGrid g{.cells = 12, .size = 1.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  scene.add_mesh(make_wave_grid(g));  // 3 instances
  scene.add_mesh(make_wave_grid(g));  // 5 instances
  // Side by side in a row, each turned to face the camera (+z).
  const glm::mat4 facing = glm::rotate(glm::mat4(1.0f), glm::radians(90.0f), glm::vec3(1, 0, 0));
  for (uint32_t i = 0; i < 8; ++i) {
    scene.add_instance(
        {"grid", i < 3 ? 0u : 1u,
         glm::translate(glm::mat4(1.0f), glm::vec3(1.1f * float(i % 4), 1.1f * float(i / 4), 0)) *
             facing});
  }
  Camera close;  // the grids fill the frame
  close.position = {1.65f, 0.55f, 2.5f};
  scene.set_camera(close);
  Compiled c(std::move(scene));
  EmbreeScene embree;
  embree.disallow_flat();
  embree.sync(c.ks, c.delta);

  g.amplitude = 0.2f;
  deform_wave_grid(c.scene.edit_mesh_vertices(0), g, 0.3f);
  const SceneDelta deformed = c.sync.update(c.scene, c.settings).changes;
  ASSERT_EQ(deformed.meshes_refit, std::vector<uint32_t>{0});
  embree.sync(c.ks, deformed);
  EXPECT_EQ(embree.last_instance_commits(), 3u) << "the refit mesh's instances, once each";
  EmbreeScene fresh;
  fresh.disallow_flat();
  fresh.sync(c.ks, SceneDelta::everything());
  expect_same_answers(c.ks.view(), fresh, embree);

  c.scene.set_instance_transform(
      6, glm::translate(glm::mat4(1.0f), glm::vec3(2.3f, 1.2f, 0.3f)) * facing);
  const SceneDelta moved = c.sync.update(c.scene, c.settings).changes;
  embree.sync(c.ks, moved);
  EXPECT_EQ(embree.last_instance_commits(), 1u);
  EmbreeScene fresh_moved;
  fresh_moved.disallow_flat();
  fresh_moved.sync(c.ks, SceneDelta::everything());
  expect_same_answers(c.ks.view(), fresh_moved, embree);
}

}  // namespace
}  // namespace tandem
