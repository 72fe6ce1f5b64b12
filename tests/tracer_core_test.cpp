// The core tracer's frame loop: the image never depends on which backend
// rendered which tile, progressive accumulation stays exact when tiles change
// owner between frames, and scene changes restart it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "backends/cpu/cpu_backend.h"
#include "backends/cpu_loops/cpu_tile_loop.h"
#include "core/kernel/bvh_traverse.h"
#include "core/render/offline_render.h"
#include "core/util/activity.h"
#include "scenes/builtin_scenes.h"
#include "tracer/core_tracer.h"

namespace tandem {
namespace {

// Stands in for a GPU backend on machines without one: sync() copies the
// whole KernelScene (as the CUDA backend uploads it) and render() traces
// only that copy, with the kernels the GPU runs.
class SnapshotBackend final : public Backend {
 public:
  explicit SnapshotBackend(KBvhLayout layout = kBvhLayoutBinary) : layout_(layout) {}
  std::string name() const override { return "snapshot"; }
  BackendTraits traits() const override {
    return {.needs_bvh = true, .bvh_layout = layout_, .reads_host_scene_while_rendering = false};
  }
  // The layout its copy of the scene's BVH says to trace.
  uint32_t traced_layout() const { return copy_.bvh.layout; }
  // Applies exactly the delta, as a device upload would: a change the
  // tracer forgets to report leaves the copy stale.
  void sync(const KernelScene& scene, const SceneDelta& delta) override {
#define TANDEM_APPLY_CHANGE(T, name)                                                      \
  if (delta.name.reallocated || copy_.name.size() != scene.name.size()) {                 \
    copy_.name = scene.name;                                                              \
  } else if (delta.name.end > delta.name.begin) {                                         \
    std::copy(scene.name.begin() + delta.name.begin, scene.name.begin() + delta.name.end, \
              copy_.name.begin() + delta.name.begin);                                     \
  }
    TANDEM_KERNEL_ARRAYS(TANDEM_APPLY_CHANGE)
#undef TANDEM_APPLY_CHANGE
    if (delta.constants || delta.full) copy_.constants = scene.constants;
    if (delta.bvh_constants || delta.full) copy_.bvh = scene.bvh;
    kd_ = copy_.view();
  }
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override {
    return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
  }

 private:
  KBvhLayout layout_;
  KernelScene copy_;
  KernelData kd_{};
};

// A SnapshotBackend whose need of Tandem's BVH can be switched off and on
// (a GPU falling back, a backend tracing the BVH coming back): it notes
// whether it was sent BVH changes while it did not need them.
class SwitchingBackend final : public Backend {
 public:
  explicit SwitchingBackend(const bool* needs) : needs_(needs) {}
  std::string name() const override { return "switching"; }
  BackendTraits traits() const override {
    return {.needs_bvh = *needs_, .reads_host_scene_while_rendering = false};
  }
  void sync(const KernelScene& scene, const SceneDelta& delta) override {
    if (!*needs_ && (delta.bvh_nodes.any() || delta.bvh_wide_nodes.any() || delta.bvh_constants))
      bvh_changes_while_not_needed = true;
    inner_.sync(scene, delta);
  }
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override {
    return inner_.render(pass, tiles, film);
  }
  bool bvh_changes_while_not_needed = false;

 private:
  const bool* needs_;
  SnapshotBackend inner_;
};

TracerSettings small_settings(float split, bool stealing) {
  TracerSettings s;
  s.render.width = 64;
  s.render.height = 48;
  s.render.seed = 3;
  s.samples_per_frame = 2;
  s.tile_size = 8;
  s.scheduler.forced_split = split;
  s.scheduler.stealing = stealing;
  // Most tests want both backends rendering every frame, not the tracer's
  // choice of the faster CPU backend (tested on its own below).
  s.exclusive_host_cores = false;
  return s;
}

std::vector<std::unique_ptr<Backend>> make(const std::vector<std::string>& names) {
  std::vector<std::unique_ptr<Backend>> out;
  for (const std::string& n : names) {
    if (n == "cpu")
      out.push_back(std::make_unique<CpuBackend>(CpuTraversal::kEmbree));
    else if (n == "snapshot")
      out.push_back(std::make_unique<SnapshotBackend>());
    else
      out.push_back(std::make_unique<CpuBackend>(CpuTraversal::kTandemBvh));
  }
  return out;
}

ImageRGB render_frames(const std::vector<std::string>& backends, const TracerSettings& settings,
                       int frames, CoreTracer** keep = nullptr) {
  Scene scene = make_cornell_box();
  CoreTracer tracer(make(backends), settings);
  for (int f = 0; f < frames; ++f)
    tracer.render_frame(scene);
  EXPECT_EQ(tracer.accumulated_spp(), uint32_t(frames) * settings.samples_per_frame);
  return tracer.image();
}

bool bitwise_equal(const ImageRGB& a, const ImageRGB& b) {
  return a.width == b.width && a.height == b.height &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

TEST(CoreTracer, SplitInvarianceWithIdenticalBackends) {
  // Two Embree backends trace bit-identical paths, so any split, with or
  // without stealing, must give exactly the single-backend image.
  const ImageRGB alone = render_frames({"cpu"}, small_settings(-1.0f, true), 3);
  for (bool stealing : {true, false}) {
    for (float split : {0.0f, 0.2f, 0.5f, 0.8f, 1.0f, -1.0f}) {
      const ImageRGB split_image =
          render_frames({"cpu", "cpu"}, small_settings(split, stealing), 3);
      EXPECT_TRUE(bitwise_equal(alone, split_image))
          << "split " << split << " stealing " << stealing;
    }
  }
}

TEST(CoreTracer, SplitInvarianceAcrossCpuAndHostBackends) {
  // Embree and Tandem's BVH may disagree in the last ulp of a hit point,
  // which can send a path elsewhere; seams between tiles of different owners
  // may differ only that much.
  const ImageRGB cpu = render_frames({"cpu"}, small_settings(-1.0f, true), 2);
  for (float split : {0.0f, 0.3f, 0.7f, 1.0f}) {
    const ImageRGB mixed = render_frames({"cpu", "host"}, small_settings(split, true), 2);
    size_t identical = 0;
    for (size_t i = 0; i < cpu.rgb.size(); ++i) {
      identical +=
          std::fabs(cpu.rgb[i] - mixed.rgb[i]) <= 1e-4f * std::max(1.0f, std::fabs(cpu.rgb[i]));
    }
    EXPECT_GE(double(identical), 0.97 * double(cpu.rgb.size())) << "split " << split;
  }
}

TEST(CoreTracer, AccumulationIsExactWhenTilesChangeOwner) {
  // The split moves every frame, so pixels change owner between frames; the
  // accumulated image must equal a single backend's, bit for bit.
  const TracerSettings base = small_settings(-1.0f, true);
  const ImageRGB alone = render_frames({"cpu"}, base, 6);
  Scene scene = make_cornell_box();
  CoreTracer tracer(make({"cpu", "cpu"}), base);
  std::vector<int32_t> first_owners;
  bool owner_changed = false;
  for (int f = 0; f < 6; ++f) {
    TracerSettings s = base;
    s.scheduler.forced_split = float(f % 3) * 0.4f + 0.1f;
    tracer.set_settings(s);  // scheduler settings only: accumulation continues
    const FrameMetrics& m = tracer.render_frame(scene);
    EXPECT_EQ(m.accumulation_reset, f == 0);
    if (f == 0)
      first_owners = tracer.tile_owners();
    else
      owner_changed |= tracer.tile_owners() != first_owners;
  }
  EXPECT_TRUE(owner_changed);
  EXPECT_TRUE(bitwise_equal(alone, tracer.image()));
}

TEST(CoreTracer, HeteroAccumulationMatchesSingleBackendStatistically) {
  // cpu + host over many frames against cpu alone with another seed: the
  // per-channel means must agree within their standard errors.
  TracerSettings a = small_settings(-1.0f, true);
  a.samples_per_frame = 4;
  TracerSettings b = a;
  b.render.seed = 11;
  const ImageRGB hetero = render_frames({"cpu", "host"}, a, 8);
  const ImageRGB single = render_frames({"cpu"}, b, 8);
  for (int c = 0; c < 3; ++c) {
    double sum_d = 0, sum_d2 = 0;
    const size_t n = size_t(hetero.width) * hetero.height;
    for (size_t i = 0; i < n; ++i) {
      const double d = double(hetero.rgb[3 * i + c]) - double(single.rgb[3 * i + c]);
      sum_d += d;
      sum_d2 += d * d;
    }
    const double mean = sum_d / double(n);
    const double se = std::sqrt((sum_d2 / double(n) - mean * mean) / double(n));
    EXPECT_LT(std::fabs(mean), 5.0 * se + 1e-6) << "channel " << c;
  }
}

// The BVH's layout is the wide one only when every backend that traces it
// prefers it (the host backend does, a GPU backend does not), and the image
// does not depend on it beyond the last bits of a tie.
TEST(CoreTracer, BvhLayoutIsTheOneEveryBackendTracingItPrefers) {
  EXPECT_EQ(CpuBackend(CpuTraversal::kTandemBvh).traits().bvh_layout, kBvhLayoutWide);
  const TracerSettings settings = small_settings(0.5f, false);
  Scene scene = make_cornell_box();
  for (const KBvhLayout second : {kBvhLayoutWide, kBvhLayoutBinary}) {
    std::vector<std::unique_ptr<Backend>> backends;
    backends.push_back(std::make_unique<SnapshotBackend>(kBvhLayoutWide));
    backends.push_back(std::make_unique<SnapshotBackend>(second));
    const SnapshotBackend* a = static_cast<const SnapshotBackend*>(backends[0].get());
    const SnapshotBackend* b = static_cast<const SnapshotBackend*>(backends[1].get());
    CoreTracer tracer(std::move(backends), settings);
    tracer.render_frame(scene);
    EXPECT_EQ(a->traced_layout(), uint32_t(second));
    EXPECT_EQ(b->traced_layout(), uint32_t(second));
  }
  const ImageRGB host = render_frames({"host"}, settings, 2);
  const ImageRGB binary = render_frames({"snapshot"}, settings, 2);
  size_t identical = 0;
  for (size_t i = 0; i < host.rgb.size(); ++i)
    identical += host.rgb[i] == binary.rgb[i];
  EXPECT_GE(double(identical), 0.99 * double(host.rgb.size()));
}

TEST(CoreTracer, SceneChangeRestartsAccumulationAndReportsDelta) {
  Scene scene = make_cornell_box();
  CoreTracer tracer(make({"cpu", "host"}), small_settings(-1.0f, true));
  const FrameMetrics& first = tracer.render_frame(scene);
  EXPECT_TRUE(first.accumulation_reset);
  EXPECT_GT(first.delta_bytes, 0u);
  const FrameMetrics& second = tracer.render_frame(scene);
  EXPECT_FALSE(second.accumulation_reset);
  EXPECT_EQ(second.delta_bytes, 0u);
  EXPECT_EQ(second.accumulated_spp, 4u);
  // Move the first instance: a TLAS-only change.
  Instance moved = scene.instances()[0];
  moved.transform[3][1] += 0.01f;
  scene.set_instance_transform(0, moved.transform);
  const FrameMetrics& third = tracer.render_frame(scene);
  EXPECT_TRUE(third.accumulation_reset);
  EXPECT_GT(third.delta_bytes, 0u);
  EXPECT_EQ(third.accumulated_spp, 2u);
  ASSERT_EQ(third.backends.size(), 2u);
  uint32_t tiles = 0;
  for (const BackendFrameMetrics& b : third.backends)
    tiles += b.tiles;
  EXPECT_EQ(tiles, uint32_t(tracer.tiles().size()));
}

// sync_scene() does the first frame's set-up ahead (tandem render runs it
// before signals become a polled flag): the frames after it are the frames
// without it, and the snapshot backend (which applies only the deltas it is
// sent) has the whole scene.
TEST(CoreTracer, SyncingTheSceneAheadGivesTheSameFrames) {
  const TracerSettings settings = small_settings(-1.0f, true);
  const ImageRGB plain = render_frames({"snapshot"}, settings, 2);
  Scene scene = make_cornell_box();
  CoreTracer tracer(make({"snapshot"}), settings);
  tracer.sync_scene(scene);
  const FrameMetrics& first = tracer.render_frame(scene);
  EXPECT_EQ(first.delta_bytes, 0u);  // all of it went ahead
  EXPECT_TRUE(first.accumulation_reset);
  tracer.render_frame(scene);
  EXPECT_TRUE(bitwise_equal(tracer.image(), plain));
  tracer.begin_frame(scene);
  EXPECT_THROW(tracer.sync_scene(scene), std::logic_error);
  tracer.end_frame();
}

// A cancelled frame (the viewer's answer to input) hands out no more tiles,
// drops its samples and restarts accumulation, so the frames after it are
// those of a tracer that never started it; waiting for a frame in slices
// ends when it is rendered.
TEST(CoreTracer, ACancelledFrameLeavesNoSamplesBehind) {
  for (const char* backend : {"cpu", "host"}) {
    SCOPED_TRACE(backend);
    TracerSettings settings = small_settings(-1.0f, true);
    // 3,072 tiles, a tenth of a second: cancelled long before the last.
    settings.render.width = 256;
    settings.render.height = 192;
    settings.tile_size = 4;
    const ImageRGB plain = render_frames({backend}, settings, 2);
    Scene scene = make_cornell_box();
    CoreTracer tracer(make({backend}), settings);
    tracer.begin_frame(scene);
    tracer.cancel_frame();
    const FrameMetrics& cancelled = tracer.end_frame();
    EXPECT_TRUE(cancelled.cancelled);
    EXPECT_EQ(cancelled.accumulated_spp, 0u);
    EXPECT_LT(cancelled.backends[0].tiles, 3072u) << "tiles were taken after the cancel";
    EXPECT_EQ(tracer.accumulated_spp(), 0u);
    for (int f = 0; f < 2; ++f) {
      tracer.begin_frame(scene);
      while (!tracer.wait_rendered(0.001)) {
      }
      EXPECT_TRUE(tracer.wait_rendered(0.0));
      const FrameMetrics& m = tracer.end_frame();
      EXPECT_FALSE(m.cancelled);
      EXPECT_EQ(m.accumulation_reset, f == 0);
    }
    EXPECT_EQ(tracer.accumulated_spp(), 2 * settings.samples_per_frame);
    EXPECT_TRUE(bitwise_equal(tracer.image(), plain));
  }
}

// Two backends on one frame (what --backend hetero is with a GPU): a frame
// waited on in slices is split between them as one rendered in one wait,
// and a cancel stops both.
TEST(CoreTracer, ACancelledHeterogeneousFrameStopsEveryBackend) {
  TracerSettings settings = small_settings(0.5f, true);
  settings.render.width = 256;
  settings.render.height = 192;
  settings.tile_size = 4;
  const ImageRGB plain = render_frames({"cpu", "host"}, settings, 2);
  Scene scene = make_cornell_box();
  CoreTracer tracer(make({"cpu", "host"}), settings);
  tracer.begin_frame(scene);
  tracer.cancel_frame();
  const FrameMetrics& cancelled = tracer.end_frame();
  EXPECT_TRUE(cancelled.cancelled);
  ASSERT_EQ(cancelled.backends.size(), 2u);
  EXPECT_LT(cancelled.backends[0].tiles + cancelled.backends[1].tiles, 3072u);
  EXPECT_EQ(tracer.accumulated_spp(), 0u);
  for (int f = 0; f < 2; ++f) {
    tracer.begin_frame(scene);
    while (!tracer.wait_rendered(0.001)) {
    }
    const FrameMetrics& m = tracer.end_frame();
    EXPECT_FALSE(m.cancelled);
    EXPECT_GT(m.backends[0].tiles, 0u);
    EXPECT_GT(m.backends[1].tiles, 0u);
    EXPECT_EQ(m.backends[0].tiles + m.backends[1].tiles, 3072u);
  }
  // Embree and Tandem's BVH may part in the last ulp of a hit, and tiles
  // change owner with the timing (SplitInvarianceAcrossCpuAndHostBackends).
  const ImageRGB sliced = tracer.image();
  ASSERT_EQ(sliced.rgb.size(), plain.rgb.size());
  size_t identical = 0;
  for (size_t i = 0; i < plain.rgb.size(); ++i) {
    identical +=
        std::fabs(plain.rgb[i] - sliced.rgb[i]) <= 1e-4f * std::max(1.0f, std::fabs(plain.rgb[i]));
  }
  EXPECT_GE(double(identical), 0.97 * double(plain.rgb.size()));
}

// What is being built, for an out-of-memory message: the innermost scope,
// and the outer one again when it ends.
TEST(ScopedActivity, NamesTheInnermostStage) {
  EXPECT_EQ(current_activity(), "");
  {
    const ScopedActivity outer("loading a.gltf");
    {
      const ScopedActivity inner("building the acceleration structure of a.gltf");
      EXPECT_EQ(current_activity(), "building the acceleration structure of a.gltf");
    }
    EXPECT_EQ(current_activity(), "loading a.gltf");
  }
  EXPECT_EQ(current_activity(), "");
}

TEST(CoreTracer, ResolutionChangeRebuildsTheTileGrid) {
  Scene scene = make_cornell_box();
  TracerSettings s = small_settings(-1.0f, true);
  CoreTracer tracer(make({"cpu"}), s);
  tracer.render_frame(scene);
  s.render.width = 40;
  s.render.height = 24;
  tracer.set_settings(s);
  const FrameMetrics& m = tracer.render_frame(scene);
  EXPECT_TRUE(m.accumulation_reset);
  EXPECT_EQ(tracer.image().width, 40u);
  EXPECT_EQ(tracer.tiles().size(), 5u * 3u);
}

// The scene of frame f: the first instance moves a little every frame (a
// TLAS-only change); from frame 3 on the first material is darker as well.
void move_first_instance(Scene& scene, int frame) {
  glm::mat4 t = scene.instances()[0].transform;
  t[3][0] = 0.02f * float(frame);
  scene.set_instance_transform(0, t);
}
void darken_first_material(Scene& scene) {
  scene.edit_material(0).base_color *= glm::vec4(0.5f, 0.5f, 0.5f, 1.0f);
}

TEST(CoreTracer, PreparingTheNextFrameDuringRenderGivesTheSameFrames) {
  // Brigade's overlap: with a backend that renders from its own copy of the
  // scene, the next frame is compiled (and its BVH updated) while the
  // current one renders. Every frame must equal the one rendered without
  // overlap.
  const TracerSettings s = small_settings(-1.0f, true);
  Scene plain_scene = make_cornell_box(), piped_scene = make_cornell_box();
  CoreTracer plain(make({"snapshot"}), s), piped(make({"snapshot"}), s);
  for (int f = 0; f < 4; ++f) {
    move_first_instance(plain_scene, f);
    if (f == 3) darken_first_material(plain_scene);
    plain.render_frame(plain_scene);
  }
  move_first_instance(piped_scene, 0);
  bool overlapped_every_frame = true;
  for (int f = 0; f < 4; ++f) {
    piped.begin_frame(piped_scene);
    move_first_instance(piped_scene, f + 1);  // the game advances meanwhile
    if (f + 1 < 4) {
      EXPECT_TRUE(piped.prepare_next_frame(piped_scene));
    }
    // An edit after the next frame was prepared must still reach it.
    if (f == 2) darken_first_material(piped_scene);
    const FrameMetrics& m = piped.end_frame();
    if (f > 0) overlapped_every_frame &= m.overlapped_prepare;
  }
  EXPECT_TRUE(overlapped_every_frame);
  EXPECT_TRUE(bitwise_equal(plain.image(), piped.image()));
}

TEST(CoreTracer, ABvhNoBackendNeedsIsLeftAloneAndCatchesUpWhenOneDoes) {
  // Frames 2 and 3 no backend needs the BVH while the instance moves; the
  // frame it is needed again must render as if it had been kept all along.
  const TracerSettings s = small_settings(-1.0f, true);
  Scene kept_scene = make_cornell_box(), switched_scene = make_cornell_box();
  bool needs = true;
  std::vector<std::unique_ptr<Backend>> backends;
  backends.push_back(std::make_unique<SwitchingBackend>(&needs));
  const SwitchingBackend* switching = static_cast<const SwitchingBackend*>(backends[0].get());
  CoreTracer kept(make({"snapshot"}), s), switched(std::move(backends), s);
  for (int f = 0; f < 5; ++f) {
    move_first_instance(kept_scene, f);
    move_first_instance(switched_scene, f);
    if (f == 3) {
      darken_first_material(kept_scene);
      darken_first_material(switched_scene);
    }
    needs = f < 2 || f == 4;
    kept.render_frame(kept_scene);
    switched.render_frame(switched_scene);
  }
  EXPECT_FALSE(switching->bvh_changes_while_not_needed);
  EXPECT_TRUE(bitwise_equal(kept.image(), switched.image()));
}

TEST(CoreTracer, NoOverlapWhenABackendReadsTheHostScene) {
  Scene scene = make_cornell_box();
  CoreTracer tracer(make({"cpu"}), small_settings(-1.0f, true));
  tracer.begin_frame(scene);
  EXPECT_FALSE(tracer.prepare_next_frame(scene));
  tracer.end_frame();
  EXPECT_FALSE(tracer.render_frame(scene).overlapped_prepare);
}

TEST(CoreTracer, BackendsSharingTheCpuCoresAreTimedAloneThenTheFastestRenders) {
  // cpu and host both run on the host's cores: after a warm-up frame each is
  // timed alone, then only the faster one renders (splitting between them
  // could only be slower). The image stays the same throughout.
  Scene scene = make_cornell_box();
  TracerSettings s = small_settings(-1.0f, true);
  s.exclusive_host_cores = true;
  CoreTracer tracer(make({"cpu", "host"}), s);
  std::vector<std::vector<uint32_t>> tiles;
  for (int f = 0; f < 8; ++f) {
    const FrameMetrics& m = tracer.render_frame(scene);
    tiles.push_back({m.backends[0].tiles, m.backends[1].tiles});
  }
  const uint32_t all = uint32_t(tracer.tiles().size());
  // Frames 1-4 alternate: cpu alone, host alone, twice.
  for (int f = 1; f <= 4; ++f) {
    const bool cpu_turn = f % 2 == 1;
    EXPECT_EQ(tiles[f][0], cpu_turn ? all : 0u) << "frame " << f;
    EXPECT_EQ(tiles[f][1], cpu_turn ? 0u : all) << "frame " << f;
  }
  // From then on one of them has every tile.
  for (int f = 5; f < 8; ++f) {
    EXPECT_TRUE((tiles[f][0] == all && tiles[f][1] == 0) ||
                (tiles[f][0] == 0 && tiles[f][1] == all));
    EXPECT_EQ(tiles[f], tiles[5]);
  }
  // Without the policy both keep rendering.
  s.exclusive_host_cores = false;
  CoreTracer shared(make({"cpu", "host"}), s);
  for (int f = 0; f < 3; ++f) {
    const FrameMetrics& m = shared.render_frame(scene);
    EXPECT_GT(m.backends[0].tiles, 0u);
    EXPECT_GT(m.backends[1].tiles, 0u);
  }
}

}  // namespace
}  // namespace tandem
