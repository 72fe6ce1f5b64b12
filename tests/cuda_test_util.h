// Helpers shared by the CUDA backend's tests: scenes driven frame by frame
// the way the tracer drives them, the GPU-test guard, and image comparisons
// that look at every tile.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <string>
#include <vector>

#include "accstruc_test_util.h"
#include "backends/backend_factory.h"
#include "backends/cuda/cuda_backend.h"
#include "core/image/image.h"
#include "core/render/offline_render.h"
#include "scenes/procedural_scenes.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem::cuda_test {

// The shared test data (test_shared_dir.h: $TANDEM_SHARED_DIR or the build's).
inline std::filesystem::path shared_dir() {
  return TANDEM_SHARED_DIR;
}

// GPU tests skip with the reason where no device works, and fail instead
// under TANDEM_REQUIRE_GPU=1 (the GPU runbook), so a lent GPU that the tests
// cannot use is never mistaken for a pass.
inline bool gpu_required() {
  const char* v = std::getenv("TANDEM_REQUIRE_GPU");
  return v && std::string(v) == "1";
}
#define TANDEM_REQUIRE_CUDA_DEVICE()                                                      \
  do {                                                                                    \
    std::string reason_;                                                                  \
    if (!cuda_device_available(&reason_)) {                                               \
      if (::tandem::cuda_test::gpu_required())                                            \
        FAIL() << "TANDEM_REQUIRE_GPU=1 but the CUDA backend has no device: " << reason_; \
      GTEST_SKIP() << "no CUDA device: " << reason_;                                      \
    }                                                                                     \
  } while (0)

// Tests of the GPU's own arithmetic: the simulated device computes with the
// CPU's, so they need a real GPU.
#define TANDEM_REQUIRE_REAL_GPU()                                                    \
  do {                                                                               \
    TANDEM_REQUIRE_CUDA_DEVICE();                                                    \
    if (::tandem::cuda_test::on_simulated_device())                                  \
      GTEST_SKIP() << "tests the GPU's own arithmetic: not on the simulated device"; \
  } while (0)

// Whether the CUDA backend runs on the simulated device (TANDEM_DEVICE=sim):
// GPU tests then use smaller frames, since it computes on two CPU cores.
inline bool on_simulated_device() {
  const char* v = std::getenv("TANDEM_DEVICE");
  return v && std::string(v) == "sim";
}

struct FrameScene {
  Scene scene;
  RenderSettings settings;
  SceneSync sync{SceneSyncSettings{.bvh = true, .accel = accstruc_test::test_settings()}};
  const KernelScene& ks = sync.kernel_scene();

  FrameScene(Scene s, uint32_t width, uint32_t height) : scene(std::move(s)) {
    settings.width = width;
    settings.height = height;
    if (!scene.has_camera()) {
      scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, float(width) / float(height)));
    }
  }
  // Compiles the scene's edits and updates the BVH; returns the delta.
  SceneDelta next_frame() { return sync.update(scene, settings).changes; }
};

// Frame f of the dynamic-scene sequence: moves an instance, recolours a
// material, every 10th frame bends a mesh (BLAS refit) and at frame 50 adds
// an instance (arrays reallocated, full rebuild).
inline void edit_frame(Scene& scene, uint32_t f) {
  const uint32_t inst = f % uint32_t(scene.instances().size());
  const glm::mat4 t = scene.instances()[inst].transform;
  const float s = 0.01f * float(f % 7) - 0.03f;
  scene.set_instance_transform(inst,
                               glm::translate(glm::mat4(1.0f), glm::vec3(s, 0.5f * s, -s)) * t);
  Material& m = scene.edit_material(f % uint32_t(scene.materials().size()));
  m.base_color =
      glm::vec4(0.2f + 0.07f * float(f % 10), 0.5f, 0.8f - 0.05f * float(f % 9), m.base_color.w);
  if (f % 10 == 9) {
    Mesh& mesh = scene.edit_mesh_vertices(f % uint32_t(scene.meshes().size()));
    for (glm::vec3& p : mesh.positions)
      p *= 1.001f;
  }
  if (f == 50) {
    Instance extra = scene.instances()[0];
    extra.transform =
        glm::translate(glm::mat4(1.0f), glm::vec3(0.1f, 0.0f, 0.1f)) * extra.transform;
    scene.add_instance(extra);
  }
}

// A small equirectangular sky with a bright spot, so that importance
// sampling of the environment matters.
inline Environment test_environment() {
  Environment e;
  e.color = glm::vec3(1.0f);
  e.width = 32;
  e.height = 16;
  for (uint32_t y = 0; y < e.height; ++y)
    for (uint32_t x = 0; x < e.width; ++x)
      e.texels.push_back(x == 5 && y == 4 ? glm::vec3(40.0f, 30.0f, 20.0f)
                                          : glm::vec3(0.2f + 0.02f * float(y), 0.3f, 0.5f));
  e.source = "test sky";
  return e;
}

inline ImageRGB render_image(Backend& backend, uint32_t width, uint32_t height, uint32_t spp,
                             uint32_t tile_size = 16, BackendStats* stats = nullptr) {
  OfflineRenderOptions options;
  options.spp = spp;
  options.tile_size = tile_size;
  OfflineRenderResult r = render_offline(backend, width, height, options);
  if (stats) *stats = r.stats;
  return std::move(r.image);
}

inline bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Per tile of `tile` pixels: the fraction of pixels within a relative 1e-4 of
// each other, and whether the tile's mean agrees within its noise. A tile
// that disagrees is named, so one wrong tile cannot hide among many right
// ones (an image-wide average would).
struct TileDisagreement {
  uint32_t x0, y0;
  double close_fraction;
  double mean_a, mean_b;
};
inline std::vector<TileDisagreement> disagreeing_tiles(const ImageRGB& a, const ImageRGB& b,
                                                       uint32_t tile, double min_close) {
  std::vector<TileDisagreement> out;
  for (uint32_t y0 = 0; y0 < a.height; y0 += tile) {
    for (uint32_t x0 = 0; x0 < a.width; x0 += tile) {
      size_t close = 0, n = 0;
      double sa = 0.0, sb = 0.0;
      for (uint32_t y = y0; y < std::min(y0 + tile, a.height); ++y) {
        for (uint32_t x = x0; x < std::min(x0 + tile, a.width); ++x, ++n) {
          bool c = true;
          for (int k = 0; k < 3; ++k) {
            const float u = a.rgb[3 * (size_t(y) * a.width + x) + k];
            const float v = b.rgb[3 * (size_t(y) * b.width + x) + k];
            c = c && (same_bits(u, v) ||
                      std::fabs(u - v) <= 1e-4f * std::max(std::fabs(u), std::fabs(v)));
            sa += u;
            sb += v;
          }
          close += c;
        }
      }
      const double frac = double(close) / double(n);
      if (frac < min_close) out.push_back({x0, y0, frac, sa / (3.0 * n), sb / (3.0 * n)});
    }
  }
  return out;
}

inline size_t identical_pixels(const ImageRGB& a, const ImageRGB& b) {
  size_t same = 0;
  for (size_t i = 0; i < size_t(a.width) * a.height; ++i)
    same += std::memcmp(&a.rgb[3 * i], &b.rgb[3 * i], 3 * sizeof(float)) == 0;
  return same;
}

}  // namespace tandem::cuda_test
