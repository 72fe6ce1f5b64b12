// Every shared glTF model must not only load but render: finite pixels, not
// all black, under a uniform sky with the automatic or the file's camera.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "backends/cpu/cpu_backend.h"
#include "core/render/offline_render.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> shared_models() {
  std::vector<std::string> files;
  for (const auto& e :
       fs::recursive_directory_iterator(fs::path(TANDEM_SHARED_DIR) / "scenes/gltf")) {
    const std::string ext = e.path().extension().string();
    if (ext == ".gltf" || ext == ".glb") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

class ModelRenderTest : public ::testing::TestWithParam<std::string> {};

TEST_P(ModelRenderTest, RendersFiniteNonBlackImage) {
  Scene scene = load_scene(GetParam());
  scene.edit_environment().color = glm::vec3(1.0f);
  RenderSettings settings;
  settings.width = 24;
  settings.height = 16;
  settings.max_depth = 4;
  if (!scene.has_camera()) scene.set_camera(frame_bounds_camera(scene.bounds(), 0.69f, 1.5f));
  SceneSync scene_sync(SceneSyncSettings::arrays_only());
  const SceneDelta delta = scene_sync.update(scene, settings).changes;
  const KernelScene& ks = scene_sync.kernel_scene();
  CpuBackend backend{CpuTraversal::kEmbree};
  backend.sync(ks, delta);
  OfflineRenderOptions options;
  options.spp = 2;
  const OfflineRenderResult r = render_offline(backend, settings.width, settings.height, options);
  double sum = 0.0;
  for (float v : r.image.rgb) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0.0f);
    sum += v;
  }
  EXPECT_GT(sum, 0.0);
  EXPECT_GT(r.stats.rays, r.stats.samples);  // at least one bounce or shadow ray somewhere
}

INSTANTIATE_TEST_SUITE_P(
    SharedModels, ModelRenderTest, ::testing::ValuesIn(shared_models()), [](const auto& info) {
      std::string name = fs::path(info.param).parent_path().parent_path().filename().string() +
                         "_" + fs::path(info.param).parent_path().filename().string();
      for (char& c : name) {
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      }
      return name;
    });

}  // namespace
}  // namespace tandem
