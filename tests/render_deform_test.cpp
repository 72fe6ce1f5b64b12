// A deforming mesh renders the same image whether its BVH was refit every
// frame (with the rebuild policy) or built fresh for the frame: both trees
// hold the same triangles and the kernels compute each triangle's hit the
// same way, so only the order of box tests differs, which cannot change the
// closest hit except between triangles hit at exactly the same distance
// (shared edges), and those agree on the shading inputs there. Expected bit
// for bit; the test reports how many pixels differ if not.
#include <gtest/gtest.h>

#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "accstruc/accel_structure.h"
#include "backends/cpu/cpu_backend.h"
#include "core/render/offline_render.h"
#include "scenes/deforming_grid.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

constexpr uint32_t kWidth = 64, kHeight = 48;

AccelSettings no_cache() {
  AccelSettings s;
  s.cache.enabled = false;
  return s;
}

ImageRGB render(Backend& backend) {
  OfflineRenderOptions options;
  options.spp = 4;
  options.tile_size = 16;
  return render_offline(backend, kWidth, kHeight, options).image;
}

TEST(RenderDeform, RefitEveryFrameRendersLikeAFreshBuild) {
  Scene scene;
  Material diffuse;
  diffuse.base_color = glm::vec4(0.8f, 0.7f, 0.6f, 1.0f);
  diffuse.metallic = 0.0f;
  scene.add_material(diffuse);
  Material lamp;
  lamp.emissive = glm::vec3(4.0f);
  scene.add_material(lamp);
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.1f, .wavelength = 1.1f};
  scene.add_mesh(make_wave_grid(g));
  // A deforming emissive sheet above: its light tables follow it too.
  WaveGrid lg{.cells = 8, .size = 1.5f, .amplitude = 0.05f, .wavelength = 0.7f};
  scene.add_mesh(make_wave_grid(lg, 1));
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  scene.add_instance({"lamp", 1,
                      glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 2.0f, 0.0f)),
                                  3.14159265f, glm::vec3(1.0f, 0.0f, 0.0f))});
  scene.edit_environment().color = glm::vec3(0.2f, 0.25f, 0.3f);
  Camera cam;
  cam.position = {0.0f, 3.0f, 4.5f};
  cam.forward = glm::normalize(glm::vec3(0.0f, -3.0f, -4.5f));
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  scene.set_camera(cam);

  RenderSettings settings;
  settings.width = kWidth;
  settings.height = kHeight;
  settings.max_depth = 4;
  SceneSync sync(SceneSyncSettings{.bvh = true, .accel = no_cache()});
  const KernelScene& ks = sync.kernel_scene();
  CpuBackend host(CpuTraversal::kTandemBvh);
  uint32_t refits = 0;
  for (uint32_t frame = 0; frame <= 30; ++frame) {
    if (frame > 0) {
      g.amplitude = 0.1f + 0.02f * float(frame);
      deform_wave_grid(scene.edit_mesh_vertices(0), g, 0.04f * float(frame));
      deform_wave_grid(scene.edit_mesh_vertices(1), lg, 0.1f * float(frame));
    }
    const SceneSyncUpdate& up = sync.update(scene, settings);
    refits += up.accel.blas_refit;
    host.sync(ks, up.changes);
  }
  EXPECT_GT(refits, 30u);
  const ImageRGB refit = render(host);

  // The same frame's kernel arrays with every BVH built from scratch (the
  // reference: AccelStructure alone, on a copy of the arrays).
  KernelScene fresh_ks = ks;
  AccelStructure fresh_accel(no_cache());
  fresh_accel.update(fresh_ks, SceneDelta::everything());
  CpuBackend fresh_host(CpuTraversal::kTandemBvh);
  fresh_host.sync(fresh_ks, SceneDelta::everything());
  const ImageRGB fresh = render(fresh_host);

  ASSERT_EQ(refit.rgb.size(), fresh.rgb.size());
  size_t differing = 0;
  double sum = 0.0;
  for (size_t i = 0; i < refit.rgb.size(); i += 3) {
    differing += std::memcmp(&refit.rgb[i], &fresh.rgb[i], 3 * sizeof(float)) != 0;
    sum += refit.rgb[i] + refit.rgb[i + 1] + refit.rgb[i + 2];
  }
  std::printf("[render] deformed grid, refit vs fresh BVH: %zu of %u pixels differ\n", differing,
              kWidth * kHeight);
  EXPECT_GT(sum, 0.0);  // something was lit
  EXPECT_EQ(differing, 0u);
}

}  // namespace
}  // namespace tandem
