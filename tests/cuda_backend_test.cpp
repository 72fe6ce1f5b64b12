// The CUDA backend (issue 4).
//
// Two kinds of tests live here:
//   - CudaBuild.* and CudaCommit.* run everywhere the backend is built, GPU
//     or not (CI has none): the device query and the factory's fallbacks,
//     the double-buffered commit bookkeeping replayed against host-side
//     mirrors of the two device buffer sets, and the host/device tone map;
//   - CudaGpu.* need a device (ctest label "gpu") and skip themselves with
//     the reason where there is none: images against the host backend (the
//     same kernels on the CPU), hits against Embree ray by ray, a dynamic
//     scene committed frame by frame against a fresh upload, and the
//     device-resident film.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "accstruc_test_util.h"
#include "backends/backend_factory.h"
#include "backends/cuda/commit_plan.h"
#include "backends/cuda/cuda_backend.h"
#include "backends/host/host_backend.h"
#include "core/image/image.h"
#include "core/kernel/tone_map.h"
#include "core/render/renderer.h"
#include "core/util/errors.h"
#include "scenes/procedural_scenes.h"

namespace tandem {
namespace {

using accstruc_test::test_settings;

// ---------------------------------------------------------------------------
// Scenes driven frame by frame the way the tracer drives them.

struct FrameScene {
  Scene scene;
  KernelScene ks;
  SceneCompiler compiler;
  RenderSettings settings;
  AccelStructure accel{test_settings()};

  FrameScene(Scene s, uint32_t width, uint32_t height) : scene(std::move(s)) {
    settings.width = width;
    settings.height = height;
    if (!scene.has_camera()) {
      scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, float(width) / float(height)));
    }
  }
  // Compiles the scene's edits and updates the BVH; returns the delta.
  SceneDelta next_frame() {
    SceneDelta delta = compiler.compile(scene, settings, ks);
    accel.update_and_mark(ks, delta);
    return delta;
  }
};

SceneDelta everything_delta() {
  SceneDelta d;
  d.full = d.constants = d.instances_changed = true;
#define TANDEM_MARK_ALL(T, name) d.name.reallocated = true;
  TANDEM_KERNEL_ARRAYS(TANDEM_MARK_ALL)
#undef TANDEM_MARK_ALL
  return d;
}

// Frame f of the dynamic-scene sequence: moves an instance, recolours a
// material, every 10th frame bends a mesh (BLAS refit) and at frame 50 adds
// an instance (arrays reallocated, full rebuild).
void edit_frame(Scene& scene, uint32_t f) {
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

// ---------------------------------------------------------------------------
// Tests that run without a GPU.

TEST(CudaBuild, DeviceQueryGivesAReason) {
  std::string reason;
  const bool available = cuda_device_available(&reason);
  std::string direct;
  EXPECT_EQ(cuda_query_device(&direct), available);
  if (available) {
    EXPECT_TRUE(reason.empty()) << reason;
  } else {
    EXPECT_FALSE(reason.empty());
    EXPECT_EQ(reason, direct);
    std::printf("[cuda] no device: %s\n", reason.c_str());
  }
}

TEST(CudaBuild, FactoryFallsBackOrRefusesWithoutDevice) {
  std::string reason;
  if (cuda_device_available(&reason)) GTEST_SKIP() << "a CUDA device is present";
  try {
    create_backends(BackendKind::kCuda);
    ADD_FAILURE() << "--backend cuda without a device must throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
  }
  EXPECT_THROW(CudaBackend backend, InputError);
  for (BackendKind kind : {BackendKind::kAuto, BackendKind::kHetero}) {
    const auto backends = create_backends(kind);
    ASSERT_EQ(backends.size(), 1u);
    EXPECT_EQ(backends[0]->name(), "cpu");
  }
}

TEST(CudaBuild, VariantNames) {
  EXPECT_EQ(parse_cuda_kernel_variant("mega"), CudaKernelVariant::kMegakernel);
  EXPECT_EQ(parse_cuda_kernel_variant("wavefront"), CudaKernelVariant::kWavefront);
  EXPECT_THROW(parse_cuda_kernel_variant("quantum"), UsageError);
}

// The GPU tone map (core/kernel/tone_map.h) must give the bytes the host
// writes to PNG files (core/image/image.cpp), non-finite values included.
TEST(CudaBuild, KernelToneMapMatchesHost) {
  std::vector<float> values = {0.0f,
                               -1.0f,
                               1e-8f,
                               0.0031308f,
                               0.5f,
                               1.0f,
                               1.5f,
                               100.0f,
                               1e30f,
                               std::numeric_limits<float>::infinity(),
                               -std::numeric_limits<float>::infinity(),
                               std::numeric_limits<float>::quiet_NaN()};
  for (int i = 0; i < 4000; ++i)
    values.push_back(std::ldexp(float(i % 1000) / 1000.0f, i / 1000 - 2));
  ImageRGB image(uint32_t(values.size()), 1);
  for (size_t i = 0; i < values.size(); ++i)
    image.rgb[3 * i] = image.rgb[3 * i + 1] = image.rgb[3 * i + 2] = values[i];
  for (ToneMap curve : {ToneMap::kStandard, ToneMap::kAces, ToneMap::kReinhard}) {
    for (float stops : {-2.0f, 0.0f, 1.5f}) {
      const std::vector<uint8_t> host = tone_map_to_srgb8(image, stops, curve);
      for (size_t i = 0; i < values.size(); ++i) {
        ASSERT_EQ(tone_map_channel_srgb8(values[i], std::exp2(stops), uint32_t(curve)), host[3 * i])
            << "value " << values[i] << " curve " << int(curve) << " stops " << stops;
      }
    }
  }
}

// Replays commit plans onto host-side copies of the two buffer sets, with
// the copy semantics of DeviceScene, and checks after every frame that the
// set the frame renders from equals the KernelScene byte for byte.
class MirrorDevice {
 public:
  void apply(const CommitPlan& plan, const KernelScene& ks) {
    auto& set = sets_[plan.set];
    for (const ArrayCopy& c : plan.copies) {
      const size_t elem = kernel_array_element_size(c.array);
      std::vector<uint8_t>& buf = set[c.array];
      if (c.resize) buf.resize(size_t(c.count) * elem);
      ASSERT_LE(size_t(c.end) * elem, buf.size()) << kernel_array_name(c.array);
      const auto* src = static_cast<const uint8_t*>(kernel_array_host_data(ks, c.array));
      if (c.bytes())
        std::memcpy(buf.data() + size_t(c.begin) * elem, src + size_t(c.begin) * elem, c.bytes());
    }
  }
  // Names the first array that differs, or "".
  std::string mismatch(uint32_t set, const KernelScene& ks) const {
    for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
      const size_t bytes = kernel_array_host_count(ks, a) * kernel_array_element_size(a);
      const std::vector<uint8_t>& buf = sets_[set][a];
      if (buf.size() != bytes ||
          (bytes && std::memcmp(buf.data(), kernel_array_host_data(ks, a), bytes) != 0))
        return kernel_array_name(a);
    }
    return "";
  }

 private:
  std::array<std::array<std::vector<uint8_t>, kKernelArrayCount>, 2> sets_;
};

TEST(CudaCommit, FirstCommitsFillBothSetsThenNothingMoves) {
  FrameScene fs(make_procedural_scene(3000, 5), 32, 32);
  DoubleBufferedCommits commits;
  const SceneDelta first = fs.next_frame();
  const CommitPlan a = commits.plan(fs.ks, first);
  EXPECT_EQ(a.set, 0u);
  EXPECT_EQ(a.array_bytes(), fs.ks.byte_size() - sizeof(KernelConstants));
  EXPECT_TRUE(a.view_changed);
  // Set 1 has received nothing yet: the next commit sends everything again,
  // although this frame changed nothing.
  const SceneDelta none = fs.next_frame();
  EXPECT_FALSE(none.any());
  const CommitPlan b = commits.plan(fs.ks, none);
  EXPECT_EQ(b.set, 1u);
  EXPECT_EQ(b.array_bytes(), a.array_bytes());
  const CommitPlan c = commits.plan(fs.ks, fs.next_frame());
  EXPECT_EQ(c.set, 0u);
  EXPECT_EQ(c.total_bytes(), 0u);
  EXPECT_FALSE(commits.pending(0) || commits.pending(1));
}

TEST(CudaCommit, ChangeReachesTheOtherSetOneFrameLater) {
  FrameScene fs(make_procedural_scene(3000, 6), 32, 32);
  DoubleBufferedCommits commits;
  commits.plan(fs.ks, fs.next_frame());
  commits.plan(fs.ks, fs.next_frame());
  fs.scene.edit_material(0).base_color = glm::vec4(0.1f, 0.9f, 0.3f, 1.0f);
  const SceneDelta changed = fs.next_frame();
  ASSERT_TRUE(changed.materials.any());
  const CommitPlan a = commits.plan(fs.ks, changed);
  const size_t material_bytes =
      size_t(changed.materials.end - changed.materials.begin) * sizeof(KMaterial);
  EXPECT_EQ(a.array_bytes(), material_bytes);
  EXPECT_TRUE(commits.pending(1 - a.set));
  // An unchanged frame still brings the other set up to date...
  const CommitPlan b = commits.plan(fs.ks, fs.next_frame());
  EXPECT_NE(b.set, a.set);
  EXPECT_EQ(b.array_bytes(), material_bytes);
  // ...after which nothing is left to send.
  EXPECT_EQ(commits.plan(fs.ks, fs.next_frame()).total_bytes(), 0u);
}

TEST(CudaCommit, HundredDynamicFramesKeepBothSetsExact) {
  FrameScene fs(make_procedural_scene(4000, 7), 32, 32);
  DoubleBufferedCommits commits;
  MirrorDevice device;
  size_t moved = 0, full = 0;
  for (uint32_t f = 0; f < 100; ++f) {
    if (f > 0) edit_frame(fs.scene, f);
    const SceneDelta delta = fs.next_frame();
    const CommitPlan plan = commits.plan(fs.ks, delta);
    device.apply(plan, fs.ks);
    ASSERT_EQ(device.mismatch(plan.set, fs.ks), "") << "frame " << f << ", set " << plan.set;
    moved += plan.total_bytes();
    full += fs.ks.byte_size();
    // Frames that only move an instance and recolour a material send the
    // two frames' ranges and the TLAS region (this scene's ~1600 instances
    // make the TLAS about 18% of it), nothing else.
    const bool steady = f >= 2 && f % 10 != 9 && f % 10 != 0 && (f < 50 || f > 52);
    if (steady) {
      EXPECT_LT(plan.total_bytes(), fs.ks.byte_size() / 4) << "frame " << f;
    }
  }
  std::printf("[cuda] 100 frames committed %.2f MB (%.1f%% of re-sending the scene every frame)\n",
              double(moved) * 1e-6, 100.0 * double(moved) / double(full));
  EXPECT_LT(moved, full * 3 / 10);
}

TEST(CudaCommit, GrowthKeepsHeadroomAndSizeChangesResendWholeArrays) {
  FrameScene fs(make_procedural_scene(2000, 8), 32, 32);
  DoubleBufferedCommits commits;
  commits.plan(fs.ks, fs.next_frame());
  const size_t instances = fs.ks.instances.size();
  EXPECT_EQ(commits.capacity(0, kArray_instances), instances + instances / 4);
  // A size change the delta does not flag is still sent whole.
  SceneDelta quiet;
  fs.ks.instances.push_back(fs.ks.instances.front());
  const CommitPlan p = commits.plan(fs.ks, quiet);
  bool whole = false;
  for (const ArrayCopy& c : p.copies)
    whole = whole ||
            (c.array == kArray_instances && c.resize && c.begin == 0 && c.end == instances + 1);
  EXPECT_TRUE(whole);
  EXPECT_TRUE(p.view_changed);
}

// ---------------------------------------------------------------------------
// Tests that need a GPU.

#define TANDEM_REQUIRE_CUDA_DEVICE()                                                     \
  do {                                                                                   \
    std::string reason_;                                                                 \
    if (!cuda_device_available(&reason_)) GTEST_SKIP() << "no CUDA device: " << reason_; \
  } while (0)

ImageRGB render_image(Backend& backend, const FrameScene& fs, uint32_t spp) {
  OfflineRenderOptions options;
  options.spp = spp;
  options.tile_size = 16;
  return render_offline(backend, fs.settings.width, fs.settings.height, options).image;
}

struct ImageAgreement {
  double identical = 0.0, close = 0.0, mean_abs_diff = 0.0, mean_diff = 0.0, mean_diff_stderr = 0.0;
};

ImageAgreement compare_images(const ImageRGB& a, const ImageRGB& b) {
  ImageAgreement r;
  const size_t pixels = size_t(a.width) * a.height;
  double sum = 0.0, sum_sq = 0.0;
  for (size_t i = 0; i < pixels; ++i) {
    bool same = true, close = true;
    double d = 0.0;
    for (int c = 0; c < 3; ++c) {
      const float x = a.rgb[3 * i + c], y = b.rgb[3 * i + c];
      same = same && std::memcmp(&x, &y, sizeof x) == 0;
      close = close && std::fabs(x - y) <= 1e-4f * std::max(std::fabs(x), std::fabs(y));
      d += double(x) - double(y);
      r.mean_abs_diff += std::fabs(double(x) - double(y));
    }
    r.identical += same;
    r.close += close;
    sum += d;
    sum_sq += d * d;
  }
  const double n = double(pixels);
  r.identical /= n;
  r.close /= n;
  r.mean_abs_diff /= 3.0 * n;
  r.mean_diff = sum / n;
  r.mean_diff_stderr = std::sqrt(std::max(0.0, sum_sq / n - r.mean_diff * r.mean_diff) / n);
  return r;
}

// The host backend runs the same kernels with the same RNG on the CPU, so
// the images should agree pixel for pixel except where device math functions
// (sinf, powf: a few ulps apart from glibc) tip a path onto another branch.
TEST(CudaGpu, ImageMatchesHostBackend) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  for (const char* spec : {"builtin:cornell", "procedural"}) {
    FrameScene fs(
        std::string(spec) == "procedural" ? make_procedural_scene(30000, 3) : load_scene(spec), 64,
        48);
    const SceneDelta delta = fs.next_frame();
    HostBackend host;
    host.sync(fs.ks, delta);
    CudaBackend cuda;
    cuda.sync(fs.ks, delta);
    const ImageRGB reference = render_image(host, fs, 4);
    const ImageRGB mega = render_image(cuda, fs, 4);
    cuda.set_variant(CudaKernelVariant::kWavefront);
    const ImageRGB wave = render_image(cuda, fs, 4);
    const ImageAgreement r = compare_images(mega, reference);
    std::printf(
        "[cuda] %s on %s vs host: %.2f%% identical, %.2f%% within 1e-4, mean |diff| %.3g, mean "
        "diff %.3g +- %.3g\n",
        spec, cuda.device_name().c_str(), 100.0 * r.identical, 100.0 * r.close, r.mean_abs_diff,
        r.mean_diff, r.mean_diff_stderr);
    RecordProperty(std::string(spec) + "_identical_pixels", std::to_string(r.identical));
    EXPECT_GE(r.close, 0.9) << spec;
    EXPECT_LE(std::fabs(r.mean_diff), 5.0 * r.mean_diff_stderr + 1e-6) << spec << ": biased";
    // Both variants answer the first hit with the same traversal: same bits.
    EXPECT_EQ(compare_images(wave, mega).identical, 1.0) << spec;
  }
}

TEST(CudaGpu, HitsMatchEmbree) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  using namespace accstruc_test;
  TracedScene s(make_procedural_scene(60000, 9));
  for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
    s.accel.set_layout(KBvhLayout(layout));
    SceneDelta delta;
    s.recompile(&delta);
    CudaBackend cuda;
    cuda.sync(s.ks, everything_delta());
    const KernelData kd = s.kd();
    for (int kind = 0; kind < 2; ++kind) {
      const std::vector<RaySample> samples =
          kind == 0 ? primary_rays(s, 200000, 11) : diffuse_rays(s, 200000, 12);
      std::vector<Ray> rays;
      std::vector<uint32_t> keys;
      for (const RaySample& r : samples) {
        rays.push_back(r.ray);
        keys.push_back(r.alpha_key);
      }
      const std::vector<Hit> gpu = cuda.trace_rays(rays, keys, false);
      std::vector<size_t> index(samples.size());
      for (size_t i = 0; i < index.size(); ++i)
        index[i] = i;
      const Agreement a = compare_closest(
          kd, distance_tolerance(s.bounds), samples,
          [&](const RaySample& r) { return gpu[size_t(&r - samples.data())]; },
          [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); });
      std::printf("[cuda] %s closest hits (%s) vs Embree: %s\n", kind == 0 ? "primary" : "diffuse",
                  layout_name(layout), a.summary().c_str());
      EXPECT_GE(a.fraction(), 0.999);
    }
    const std::vector<RaySample> shadows = shadow_rays(s, 100000, 13);
    std::vector<Ray> rays;
    std::vector<uint32_t> keys;
    for (const RaySample& r : shadows) {
      rays.push_back(r.ray);
      keys.push_back(r.alpha_key);
    }
    const std::vector<Hit> occluded = cuda.trace_rays(rays, keys, true);
    const Agreement a = compare_occlusion(
        shadows,
        [&](const RaySample& r) { return hit_valid(occluded[size_t(&r - shadows.data())]); },
        [&](const RaySample& r) { return s.embree.occluded(r.ray, r.alpha_key); });
    std::printf("[cuda] shadow rays (%s) vs Embree: %s\n", layout_name(layout),
                a.summary().c_str());
    EXPECT_GE(a.fraction(), 0.999);
  }
}

// 100 frames of edits committed as deltas into the double-buffered device
// scene (rendering now and then, so uploads overlap renders) must leave the
// device with exactly the scene a fresh upload gives.
TEST(CudaGpu, DynamicSceneCommitsMatchFreshUpload) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  FrameScene fs(make_procedural_scene(20000, 10), 48, 32);
  CudaBackend cuda;
  uint64_t committed = 0;
  for (uint32_t f = 0; f < 100; ++f) {
    if (f > 0) edit_frame(fs.scene, f);
    cuda.sync(fs.ks, fs.next_frame());
    committed += cuda.last_commit_bytes();
    if (f % 10 == 5) render_image(cuda, fs, 1);
  }
  std::printf("[cuda] 100 frames: %.2f MB committed, scene %.2f MB\n", double(committed) * 1e-6,
              double(fs.ks.byte_size()) * 1e-6);
  CudaBackend fresh;
  fresh.sync(fs.ks, everything_delta());
  const ImageRGB incremental = render_image(cuda, fs, 2);
  const ImageRGB reference = render_image(fresh, fs, 2);
  EXPECT_EQ(compare_images(incremental, reference).identical, 1.0);
}

TEST(CudaGpu, DeviceFilmMatchesHostFilmAndToneMap) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  FrameScene fs(load_scene("builtin:cornell"), 40, 40);
  CudaBackend cuda;
  cuda.sync(fs.ks, fs.next_frame());
  const ImageRGB host_film = render_image(cuda, fs, 8);
  cuda.reset_device_film(40, 40);
  // One sample per pass, as render_offline does for 8 spp, so both films
  // add the same doubles in the same order.
  for (uint32_t pass = 0; pass < 8; ++pass) {
    TileQueue tiles(make_tile_grid(40, 40, 16));
    const BackendStats st = cuda.render_to_device_film({pass, 1, nullptr}, tiles);
    EXPECT_EQ(st.samples, 40u * 40u);
  }
  const ImageRGB device_film = cuda.resolve_device_film();
  EXPECT_EQ(compare_images(device_film, host_film).identical, 1.0);
  const std::vector<uint8_t> gpu8 = cuda.tone_map_device_film(0.5f, ToneMap::kAces);
  const std::vector<uint8_t> host8 = tone_map_to_srgb8(host_film, 0.5f, ToneMap::kAces);
  ASSERT_EQ(gpu8.size(), host8.size());
  size_t off_by_more_than_one = 0;
  for (size_t i = 0; i < gpu8.size(); ++i)
    off_by_more_than_one += std::abs(int(gpu8[i]) - int(host8[i])) > 1;
  EXPECT_EQ(off_by_more_than_one, 0u);  // device powf may round the last level differently
}

TEST(CudaGpu, SyncWithoutBvhIsACallerBug) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  FrameScene fs(load_scene("builtin:cornell"), 16, 16);
  const SceneDelta delta = fs.compiler.compile(fs.scene, fs.settings, fs.ks);  // no AccelStructure
  CudaBackend cuda;
  EXPECT_THROW(cuda.sync(fs.ks, delta), std::logic_error);
}

}  // namespace
}  // namespace tandem
