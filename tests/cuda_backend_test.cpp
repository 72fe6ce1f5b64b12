// The CUDA backend: its device query, the commit planner, and the tests that
// need a device.
//
//   - CudaBuild.* and CudaCommit.* run everywhere (CI has no GPU): the device
//     query and the factory's fallbacks, the double-buffered commit
//     bookkeeping replayed against host-side mirrors of the two device buffer
//     sets, and the host/device tone map;
//   - CudaGpu.* need a device (ctest label "gpu") and skip themselves with
//     the reason where there is none (fail under TANDEM_REQUIRE_GPU=1): images
//     against the host backend tile by tile, hits against Embree ray by ray,
//     100 overlapped frames of commits against the host arrays byte for byte,
//     the device-resident film, and a host that sleeps while it waits. CI
//     also runs them on the simulated device (TANDEM_DEVICE=sim).
#include <gtest/gtest.h>

#include <time.h>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "accstruc_test_util.h"
#include "backends/backend_factory.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cuda/commit_plan.h"
#include "backends/cuda/cuda_backend.h"
#include "core/image/image.h"
#include "core/kernel/tone_map.h"
#include "core/render/offline_render.h"
#include "core/util/errors.h"
#include "cuda_test_util.h"
#include "scenes/builtin_scenes.h"
#include "scenes/deforming_grid.h"
#include "scenes/procedural_scenes.h"
#include "tracer/core_tracer.h"

namespace tandem {
namespace {

using accstruc_test::test_settings;

using namespace cuda_test;

// ---------------------------------------------------------------------------
// Tests that run without a GPU.

TEST(CudaBuild, DeviceQueryGivesAReason) {
  std::string reason;
  const bool available = cuda_device_available(&reason);
  std::string direct;
  EXPECT_EQ(cuda_backend_device_available(&direct), available);
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
  if (cuda_device_available(&reason))
    GTEST_SKIP() << "a CUDA device (or the simulated one) is present";
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
  EXPECT_EQ(parse_cuda_kernel_variant("megakernel"), CudaKernelVariant::kMegakernel);
  EXPECT_EQ(parse_cuda_kernel_variant("wave"), CudaKernelVariant::kWavefront);
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
  EXPECT_EQ(a.array_bytes(), fs.ks.byte_size() - sizeof(KernelConstants) - sizeof(KBvhConstants));
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

// Each buffer set holds a generation of the scene's change log: it gets
// what it missed since then, and a log it has not seen (another scene, a
// copy) makes it take everything.
TEST(CudaCommit, EachSetHoldsAGenerationOfTheLog) {
  FrameScene fs(make_procedural_scene(3000, 9), 32, 32);
  const KernelChangeLog& log = fs.sync.change_log();
  DoubleBufferedCommits commits;
  fs.next_frame();
  const CommitPlan a = commits.plan(fs.ks, 0, log);
  commits.complete(a);
  EXPECT_FALSE(commits.pending(0, log));
  EXPECT_TRUE(commits.pending(1, log));
  fs.scene.edit_material(0).base_color = glm::vec4(0.1f, 0.9f, 0.3f, 1.0f);
  fs.next_frame();
  fs.scene.edit_material(1).base_color = glm::vec4(0.9f, 0.1f, 0.3f, 1.0f);
  fs.next_frame();
  // Set 0 missed two generations: both materials, and far from everything.
  const CommitPlan b = commits.plan(fs.ks, 0, log);
  std::vector<bool> material_sent(fs.ks.materials.size(), false);
  for (const ArrayCopy& c : b.copies) {
    EXPECT_FALSE(c.resize) << kernel_array_name(c.array);
    if (c.array != kArray_materials) continue;
    for (uint32_t i = c.begin; i < c.end; ++i)
      material_sent[i] = true;
  }
  EXPECT_TRUE(material_sent[0]) << "the first generation it missed";
  EXPECT_TRUE(material_sent[1]) << "the second";
  EXPECT_LT(b.array_bytes(), a.array_bytes() / 10);
  EXPECT_EQ(b.generation, log.generation());
  commits.complete(b);
  EXPECT_FALSE(commits.pending(0, log));
  const KernelChangeLog copy = log;
  const CommitPlan c = commits.plan(fs.ks, 0, copy);
  EXPECT_EQ(c.array_bytes(), a.array_bytes()) << "another log's generation: everything";
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
  KernelScene grown = fs.ks;
  grown.instances.push_back(grown.instances.front());
  const CommitPlan p = commits.plan(grown, quiet);
  bool whole = false;
  for (const ArrayCopy& c : p.copies)
    whole = whole ||
            (c.array == kArray_instances && c.resize && c.begin == 0 && c.end == instances + 1);
  EXPECT_TRUE(whole);
  EXPECT_TRUE(p.view_changed);
}

// A deformed vertex range reaches each set as exactly that range (and the
// BVH nodes above it), not the whole vertex arrays: the bytes planned equal
// the delta's own count, one copy per range, and both sets stay exact.
TEST(CudaCommit, VertexRangeDeltaCommitsExactlyItsBytes) {
  WaveGrid g{.cells = 64, .size = 4.0f, .amplitude = 0.05f, .wavelength = 1.0f};
  Scene scene;
  scene.add_material(Material{});
  scene.add_mesh(make_wave_grid(g));
  scene.add_mesh(make_uv_sphere(1.0f, 16, 32, 0, false));  // static, after the grid
  scene.add_instance({"wave", 0, glm::mat4(1.0f)});
  scene.add_instance({"ball", 1, glm::translate(glm::mat4(1.0f), glm::vec3(0, 2, 0))});
  FrameScene fs(std::move(scene), 32, 32);
  DoubleBufferedCommits commits;
  MirrorDevice device;
  for (int i = 0; i < 2; ++i) {
    const CommitPlan p = commits.plan(fs.ks, fs.next_frame());
    device.apply(p, fs.ks);
  }
  for (uint32_t frame = 1; frame <= 4; ++frame) {
    // A short run of one row: a compact patch away from the grid's halves
    // and quarters, where the top splits of its BLAS lie (a range across a
    // split or a row's end touches subtrees far apart in the node array).
    const uint32_t row = 10 + frame, first = row * (g.cells + 1) + 3, count = 12;
    Mesh& m = fs.scene.edit_mesh_vertices(0, first, count);
    for (uint32_t v = first; v < first + count; ++v)
      m.positions[v].y *= 0.5f;
    const SceneDelta delta = fs.next_frame();
    ASSERT_EQ(delta.positions.element_count(), count);
    const CommitPlan plan = commits.plan(fs.ks, delta);
    device.apply(plan, fs.ks);
    ASSERT_EQ(device.mismatch(plan.set, fs.ks), "") << "frame " << frame;
    size_t position_bytes = 0;
    for (const ArrayCopy& c : plan.copies) {
      EXPECT_FALSE(c.resize);
      if (c.array == kArray_positions) position_bytes += c.bytes();
    }
    // This set missed the previous frame's range too (it went to the other
    // set), so it receives both: the union of the two frames' deltas.
    SceneDelta both = delta;
    if (frame > 1) {
      const uint32_t before = first - (g.cells + 1);
      both.positions.mark(fs.ks.meshes[0].vertex_offset + before,
                          fs.ks.meshes[0].vertex_offset + before + count);
    }
    EXPECT_EQ(position_bytes, both.positions.element_count() * sizeof(Vec3)) << "frame " << frame;
    EXPECT_LT(plan.array_bytes(), fs.ks.byte_size() / 10) << "frame " << frame;
    if (frame == 1) {
      // The first set to see a change gets just this frame's delta.
      EXPECT_EQ(plan.total_bytes() - (plan.view_changed ? sizeof(KernelData) : 0),
                delta.bytes(fs.ks) - (delta.constants ? sizeof(KernelConstants) : 0) -
                    (delta.bvh_constants ? sizeof(KBvhConstants) : 0));
    }
  }
}

// ---------------------------------------------------------------------------
// Tests that need a CUDA device. They also run (label cuda) on the simulated
// device under TANDEM_DEVICE=sim, with smaller frames, so that they are known
// to work before a GPU run.

struct ImageCase {
  std::string name;
  std::function<Scene()> scene;
  uint32_t layout;
};

std::vector<ImageCase> image_cases() {
  const std::filesystem::path gltf = shared_dir() / "scenes" / "gltf";
  auto sky_plane = [] {
    Scene s = load_scene("builtin:sky-plane");
    s.set_environment(test_environment());
    return s;
  };
  std::vector<ImageCase> cases = {
      {"builtin:cornell", [] { return load_scene("builtin:cornell"); }, kBvhLayoutWide},
      {"procedural", [] { return make_procedural_scene(30000, 3); }, kBvhLayoutBinary},
      {"sky-plane + environment map", sky_plane, kBvhLayoutWide},
  };
  for (const char* model :
       {"BoxTextured/glTF-Binary/BoxTextured.glb", "Duck/glTF-Binary/Duck.glb"}) {
    const std::filesystem::path path = gltf / model;
    if (!std::filesystem::exists(path)) continue;
    cases.push_back({model,
                     [path] {
                       Scene s = load_scene(path.string());
                       s.edit_environment().color = glm::vec3(1.0f);
                       return s;
                     },
                     kBvhLayoutBinary});
  }
  return cases;
}

// The host backend runs the same kernels with the same RNG on the CPU, so
// the images agree pixel for pixel except where device math functions
// tip a path onto another branch; every tile must agree (one wrong tile is
// a wrong batch or tile offset somewhere), the ray counts too, and both
// kernel variants give the same bits. Chunks are kept small so that the
// samples of a pass run as several launches.
TEST(CudaGpu, ImagesMatchHostTileByTile) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  const bool sim = on_simulated_device();
  const uint32_t width = sim ? 64 : 320, height = sim ? 40 : 180, spp = 6;
  CudaBackend::LaunchLimits limits;
  limits.max_batch_pixels = width * height / 3;              // several batches
  limits.max_items = uint64_t(limits.max_batch_pixels) * 2;  // 2 samples per chunk
  std::string reason;
  for (const ImageCase& c : image_cases()) {
    for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
      SCOPED_TRACE(c.name + ", " + (layout == kBvhLayoutWide ? "wide" : "binary") + " BVH");
      FrameScene fs(c.scene(), width, height);
      fs.sync.set_bvh_layout(KBvhLayout(layout));
      const SceneDelta delta = fs.next_frame();
      CpuBackend host{CpuTraversal::kTandemBvh};
      host.sync(fs.ks, delta);
      CudaBackend cuda(open_device(&reason), CudaKernelVariant::kMegakernel, limits);
      cuda.sync(fs.ks, delta);
      BackendStats host_stats, mega_stats, wave_stats;
      const ImageRGB reference = render_image(host, width, height, spp, 16, &host_stats);
      CpuBackend host_wave(CpuTraversal::kTandemBvh, CudaKernelVariant::kWavefront);
      host_wave.sync(fs.ks, delta);
      EXPECT_EQ(identical_pixels(render_image(host_wave, width, height, spp), reference),
                size_t(width) * height);
      const ImageRGB mega = render_image(cuda, width, height, spp, 16, &mega_stats);
      cuda.set_variant(CudaKernelVariant::kWavefront);
      const ImageRGB wave = render_image(cuda, width, height, spp, 16, &wave_stats);
      const std::vector<TileDisagreement> bad = disagreeing_tiles(mega, reference, 16, 0.9);
      for (const TileDisagreement& t : bad)
        ADD_FAILURE() << "tile at (" << t.x0 << ", " << t.y0 << "): " << 100.0 * t.close_fraction
                      << "% of pixels agree, mean " << t.mean_a << " vs " << t.mean_b;
      std::printf("[cuda] %s on %s: %.2f%% of pixels identical to the host backend\n",
                  c.name.c_str(), cuda.device_name().c_str(),
                  100.0 * double(identical_pixels(mega, reference)) / (width * height));
      EXPECT_EQ(identical_pixels(wave, mega), size_t(width) * height);
      EXPECT_EQ(mega_stats.samples, host_stats.samples);
      EXPECT_NEAR(double(mega_stats.rays), double(host_stats.rays), 0.01 * double(host_stats.rays));
      EXPECT_EQ(wave_stats.rays, mega_stats.rays);
      if (sim) {
        EXPECT_EQ(identical_pixels(mega, reference), size_t(width) * height);
      }
    }
  }
}

// A full HD frame: eight batches of the default launch limits.
TEST(CudaGpu, FullHdFrameMatchesHostTileByTile) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  if (on_simulated_device())
    GTEST_SKIP() << "a full HD frame takes minutes on the simulated device";
  FrameScene fs(load_scene("builtin:cornell"), 1920, 1080);
  const SceneDelta delta = fs.next_frame();
  CpuBackend host{CpuTraversal::kTandemBvh};
  host.sync(fs.ks, delta);
  CudaBackend cuda;
  cuda.sync(fs.ks, delta);
  const ImageRGB reference = render_image(host, 1920, 1080, 2, 32);
  const ImageRGB image = render_image(cuda, 1920, 1080, 2, 32);
  const std::vector<TileDisagreement> bad = disagreeing_tiles(image, reference, 32, 0.9);
  EXPECT_TRUE(bad.empty()) << bad.size() << " tiles disagree, the first at (" << bad[0].x0 << ", "
                           << bad[0].y0 << ")";
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
    cuda.sync(s.ks, SceneDelta::everything());
    const KernelData kd = s.kd();
    for (int kind = 0; kind < 2; ++kind) {
      const size_t n = on_simulated_device() ? 20000 : 200000;
      const std::vector<RaySample> samples =
          kind == 0 ? primary_rays(s, n, 11) : diffuse_rays(s, n, 12);
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
    const std::vector<RaySample> shadows =
        shadow_rays(s, on_simulated_device() ? 10000 : 100000, 13);
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

// 100 frames of edits through the core tracer's overlapped loop: each
// frame's delta is committed while the previous frame renders. Afterwards
// both device buffer sets hold exactly the host arrays, byte for byte, and
// the image equals that of a backend given the final scene in one upload.
TEST(CudaGpu, OverlappedCommitsLeaveBothSetsExact) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  const uint32_t width = on_simulated_device() ? 24 : 64, height = on_simulated_device() ? 16 : 48;
  Scene scene = make_procedural_scene(20000, 10);
  scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, float(width) / float(height)));
  std::vector<std::unique_ptr<Backend>> backends;
  backends.push_back(std::make_unique<CudaBackend>());
  CudaBackend* cuda = static_cast<CudaBackend*>(backends[0].get());
  TracerSettings settings;
  settings.render.width = width;
  settings.render.height = height;
  settings.tile_size = 8;
  CoreTracer tracer(std::move(backends), settings);
  uint64_t committed = 0, overlapped = 0;
  double copy = 0.0, hidden = 0.0;
  const uint32_t frames = 102;  // the last two change nothing: both sets catch up
  for (uint32_t f = 0; f < frames; ++f) {
    tracer.begin_frame(scene);
    if (f + 1 < frames - 2) edit_frame(scene, f + 1);
    EXPECT_TRUE(tracer.prepare_next_frame(scene));
    // A late edit after the prepared commit (the camera, as from input).
    if (f % 3 == 0 && f + 1 < frames - 2) {
      Camera cam = scene.camera();
      cam.position.x += 0.001f;
      scene.set_camera(cam);
    }
    const FrameMetrics& m = tracer.end_frame();
    committed += m.backends[0].commit_bytes;
    copy += m.backends[0].commit_copy_seconds;
    hidden += m.backends[0].commit_hidden_seconds;
    overlapped += m.overlapped_commit;
  }
  std::printf(
      "[cuda] %u overlapped frames: %.2f MB committed, copies %.2f ms, %.2f ms of it hidden\n",
      unsigned(overlapped), double(committed) * 1e-6, copy * 1e3, hidden * 1e3);
  EXPECT_EQ(overlapped, frames - 1);
  EXPECT_GT(copy, 0.0);
  // The tracer's own kernel scene is private; compile the same scene again.
  FrameScene fs(scene, width, height);
  fs.next_frame();
  const std::array<std::vector<std::vector<uint8_t>>, 2> sets = {cuda->read_back_scene(0),
                                                                 cuda->read_back_scene(1)};
  for (uint32_t set = 0; set < 2; ++set) {
    const std::vector<std::vector<uint8_t>>& device = sets[set];
    for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
      const size_t bytes = kernel_array_host_count(fs.ks, a) * kernel_array_element_size(a);
      ASSERT_EQ(device[a].size(), bytes) << "set " << set << ", " << kernel_array_name(a);
      // The tracer refits only the layout its backends trace (binary here):
      // the wide nodes keep the build's boxes, which nothing reads, while
      // the fresh compile's are refit to the final scene.
      if (a == kArray_bvh_wide_nodes && fs.ks.bvh.layout == kBvhLayoutBinary) continue;
      // The meshes that deformed dropped their leaf records
      // (kBlasNoLeafRecords), and those refit with records kept only the
      // binary layout's current (kBlasNoWideRecords), where a fresh compile
      // has both: there the two sets must hold the same bytes (what the host
      // last sent), and the roots must be the fresh compile's, flagged.
      if (a == kArray_bvh_leaf_triangles || a == kArray_bvh_wide_leaf_triangles) {
        EXPECT_EQ(sets[0][a], sets[1][a]) << kernel_array_name(a);
        continue;
      }
      if (a == kArray_blas_roots) {
        const KBlasRoot* roots = reinterpret_cast<const KBlasRoot*>(device[a].data());
        uint32_t flagged = 0;
        for (size_t m = 0; m < fs.ks.blas_roots.size(); ++m) {
          EXPECT_EQ(roots[m].bvh_root, fs.ks.blas_roots[m].bvh_root) << "mesh " << m;
          EXPECT_EQ(roots[m].wide_root, fs.ks.blas_roots[m].wide_root) << "mesh " << m;
          EXPECT_EQ(roots[m].flags & ~uint32_t(kBlasNoLeafRecords | kBlasNoWideRecords), 0u);
          flagged += (roots[m].flags & kBlasNoLeafRecords) != 0u;
        }
        EXPECT_GT(flagged, 0u) << "set " << set << ": no deformed mesh dropped its records";
        continue;
      }
      EXPECT_TRUE(bytes == 0 ||
                  std::memcmp(device[a].data(), kernel_array_host_data(fs.ks, a), bytes) == 0)
          << "set " << set << ", " << kernel_array_name(a);
    }
  }
  CudaBackend fresh;
  fresh.sync(fs.ks, SceneDelta::everything());
  EXPECT_EQ(identical_pixels(render_image(*cuda, width, height, 2),
                             render_image(fresh, width, height, 2)),
            size_t(width) * height);
}

// Waiting for the GPU must not cost the host a core: the CPU backend
// renders on the same cores in a hetero frame.
TEST(CudaGpu, HostSleepsWhileTheDeviceWorks) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  const uint32_t size = on_simulated_device() ? 48 : 512;
  FrameScene fs(load_scene("builtin:cornell"), size, size);
  CudaBackend cuda;
  cuda.sync(fs.ks, fs.next_frame());
  timespec cpu0, cpu1;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu0);
  const auto wall0 = std::chrono::steady_clock::now();
  render_image(cuda, size, size, on_simulated_device() ? 4 : 256, 64);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu1);
  const double cpu = double(cpu1.tv_sec - cpu0.tv_sec) + 1e-9 * double(cpu1.tv_nsec - cpu0.tv_nsec);
  std::printf("[cuda] render: %.3f s wall, %.3f s of the calling thread's CPU time\n", wall, cpu);
  EXPECT_LT(cpu, 0.25 * wall + 0.01);
}

RenderPass one_sample(uint32_t sample) {
  RenderPass pass;
  pass.sample_begin = sample;
  pass.sample_count = 1;
  return pass;
}

TEST(CudaGpu, DeviceFilmMatchesHostFilmAndToneMap) {
  TANDEM_REQUIRE_CUDA_DEVICE();
  FrameScene fs(load_scene("builtin:cornell"), 40, 40);
  CudaBackend cuda;
  cuda.sync(fs.ks, fs.next_frame());
  const ImageRGB host_film = render_image(cuda, 40, 40, 8);
  cuda.reset_device_film(40, 40);
  // One sample per pass, as render_offline does for 8 spp, so both films
  // add the same doubles in the same order.
  for (uint32_t pass = 0; pass < 8; ++pass) {
    TileQueue tiles(make_tile_grid(40, 40, 16));
    const BackendStats st = cuda.render_to_device_film(one_sample(pass), tiles);
    EXPECT_EQ(st.samples, 40u * 40u);
  }
  const ImageRGB device_film = cuda.resolve_device_film();
  EXPECT_EQ(identical_pixels(device_film, host_film), size_t(40) * 40);
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
  Scene scene = load_scene("builtin:cornell");
  SceneSync arrays_only(SceneSyncSettings::arrays_only());  // no BVH
  const SceneSyncUpdate& up = arrays_only.update(scene, RenderSettings{});
  CudaBackend cuda;
  EXPECT_THROW(cuda.sync(arrays_only.kernel_scene(), up.changes), std::logic_error);
}

}  // namespace
}  // namespace tandem
