// The CUDA backend's pipeline on the simulated device (no GPU needed): the
// images it renders, the ordering of its copies and kernels (the simulated
// device reports every unordered access), the commits of an overlapped
// frame loop, and recovery from every kind of injected device fault.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <map>
#include <random>

#include "backends/backend_factory.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cuda/commit_plan.h"
#include "backends/cuda/cuda_backend.h"
#include "backends/cuda/device_faults.h"
#include "backends/cuda/device_launch.h"
#include "backends/cuda/sim_device.h"
#include "core/util/errors.h"
#include "core/world/motion_history.h"
#include "cuda_test_util.h"
#include "tracer/core_tracer.h"

namespace tandem {
namespace {

using namespace cuda_test;

// Fast simulated timing: these tests run thousands of operations.
SimDeviceOptions quick() {
  SimDeviceOptions o;
  o.op_seconds = 5e-6;
  o.kernel_seconds = 20e-6;
  o.copy_seconds_per_mib = 1e-4;
  return o;
}

std::string hazards_of(const SimDeviceReport& r) {
  std::string s;
  for (const std::string& h : r.hazards)
    s += "\n  " + h;
  return s;
}

void expect_nothing_left(const SimDevice& sim) {
  const SimDeviceReport r = sim.report();
  EXPECT_EQ(r.live_device_allocations, 0u);
  EXPECT_EQ(r.live_pinned_allocations, 0u);
  EXPECT_EQ(r.live_streams, 0u);
  EXPECT_EQ(r.live_events, 0u);
}

// The checker must be able to fail: a kernel that reads a buffer another
// stream is still writing, with no event between them, is reported, and
// the same pair ordered by an event is not.
TEST(CudaSim, HazardCheckerFindsAnUnorderedReadAndAcceptsAnOrderedOne) {
  for (bool ordered : {false, true}) {
    SimDevice sim(quick());
    FrameScene fs(load_scene("builtin:cornell"), 8, 8);
    fs.next_frame();
    const KernelData host = fs.ks.view();
    DeviceStream copy = sim.create_stream(), render = sim.create_stream();
    DeviceEvent uploaded = sim.create_event(false);
    // A device KernelData whose only array is the positions.
    void* positions = sim.alloc(host.positions_count * sizeof(Vec3));
    KernelData kd{};
    kd.positions = static_cast<const Vec3*>(positions);
    kd.positions_count = host.positions_count;
    kd.constants = host.constants;
    void* d_kd = sim.alloc(sizeof kd);
    void* staging = sim.alloc_pinned(sizeof kd + host.positions_count * sizeof(Vec3));
    std::memcpy(staging, &kd, sizeof kd);
    sim.copy_to_device(d_kd, staging, sizeof kd, render);
    sim.copy_to_device(positions, static_cast<uint8_t*>(staging) + sizeof kd,
                       host.positions_count * sizeof(Vec3), copy);
    sim.record(uploaded, copy);
    if (ordered) sim.wait(render, uploaded);
    void* hits = sim.alloc(sizeof(Hit));
    void* rays = sim.alloc(sizeof(Ray));
    void* counter = sim.alloc(sizeof(uint32_t));
    sim.zero(rays, sizeof(Ray), render);
    sim.zero(counter, sizeof(uint32_t), render);
    launch_trace_rays(sim, static_cast<const KernelData*>(d_kd), static_cast<const Ray*>(rays),
                      nullptr, 1, false, static_cast<Hit*>(hits), static_cast<uint32_t*>(counter),
                      render);
    sim.synchronize(render);
    sim.synchronize(copy);
    const SimDeviceReport r = sim.report();
    if (ordered) {
      EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
    } else {
      ASSERT_FALSE(r.hazards.empty());
      EXPECT_NE(r.hazards[0].find("positions"), std::string::npos) << r.hazards[0];
    }
    for (void* p : {positions, d_kd, hits, rays, counter})
      sim.free(p);
    sim.free_pinned(staging);
    sim.destroy_event(uploaded);
    sim.destroy_stream(copy);
    sim.destroy_stream(render);
    expect_nothing_left(sim);
  }
}

// The simulated device computes what the GPU computes, from what the
// backend uploaded: bit for bit the host backend's image, with several
// batches and several sample chunks per pass, both kernel variants and
// both BVH layouts, and with no hazard and no pageable async copy.
TEST(CudaSim, RendersTheHostBackendsImageBitForBitWithoutHazards) {
  const uint32_t width = 48, height = 32, spp = 5;
  CudaBackend::LaunchLimits limits;
  limits.max_batch_pixels = 600;  // three batches of 16x16 tiles
  limits.max_items = 1200;        // 2 samples per chunk
  for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
    auto sim = std::make_shared<SimDevice>();
    {
      FrameScene fs(load_scene("builtin:cornell-spheres"), width, height);
      fs.sync.set_bvh_layout(KBvhLayout(layout));
      const SceneDelta delta = fs.next_frame();
      CpuBackend host{CpuTraversal::kTandemBvh};
      host.sync(fs.ks, delta);
      CudaBackend cuda(sim, CudaKernelVariant::kMegakernel, limits);
      cuda.sync(fs.ks, delta);
      BackendStats hs, cs;
      const ImageRGB reference = render_image(host, width, height, spp, 16, &hs);
      EXPECT_EQ(identical_pixels(render_image(cuda, width, height, spp, 16, &cs), reference),
                size_t(width) * height);
      EXPECT_EQ(cs.rays, hs.rays);
      EXPECT_EQ(cs.samples, hs.samples);
      cuda.set_variant(CudaKernelVariant::kWavefront);
      EXPECT_EQ(identical_pixels(render_image(cuda, width, height, spp), reference),
                size_t(width) * height);
    }
    const SimDeviceReport r = sim->report();
    EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
    EXPECT_EQ(r.pageable_async_copies, 0u);
    EXPECT_GT(r.kernels, 6u);
    expect_nothing_left(*sim);
  }
}

// The per-tile comparison the GPU tests use must catch one wrong tile.
TEST(CudaSim, TileComparisonCatchesASingleWrongTile) {
  FrameScene fs(load_scene("builtin:cornell"), 64, 48);
  const SceneDelta delta = fs.next_frame();
  CpuBackend host{CpuTraversal::kTandemBvh};
  host.sync(fs.ks, delta);
  const ImageRGB good = render_image(host, 64, 48, 2);
  ImageRGB bad = good;
  for (uint32_t y = 16; y < 32; ++y)
    for (uint32_t x = 32; x < 48; ++x)
      bad.rgb[3 * (size_t(y) * 64 + x)] *= 1.01f;
  EXPECT_TRUE(disagreeing_tiles(good, good, 16, 0.9).empty());
  const std::vector<TileDisagreement> found = disagreeing_tiles(bad, good, 16, 0.9);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].x0, 32u);
  EXPECT_EQ(found[0].y0, 16u);
}

// The overlapped frame loop on the simulated device: every frame's delta is
// committed while the previous frame renders, from another thread, and the
// device sees no unordered access in 40 frames of changes.
TEST(CudaSim, OverlappedFrameLoopHasNoHazards) {
  auto sim = std::make_shared<SimDevice>(quick());
  {
    Scene scene = make_procedural_scene(6000, 4);
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.7f, 1.5f));
    std::vector<std::unique_ptr<Backend>> backends;
    backends.push_back(std::make_unique<CudaBackend>(sim, CudaKernelVariant::kMegakernel,
                                                     CudaBackend::LaunchLimits{256, 512}));
    TracerSettings settings;
    settings.render.width = 24;
    settings.render.height = 16;
    settings.tile_size = 8;
    CoreTracer tracer(std::move(backends), settings);
    uint32_t overlapped = 0;
    for (uint32_t f = 0; f < 40; ++f) {
      tracer.begin_frame(scene);
      edit_frame(scene, f + 1);
      ASSERT_TRUE(tracer.prepare_next_frame(scene));
      const FrameMetrics& m = tracer.end_frame();
      overlapped += m.overlapped_commit;
      EXPECT_GE(m.backends[0].commit_copy_seconds, m.backends[0].commit_hidden_seconds);
    }
    EXPECT_EQ(overlapped, 39u);
  }
  const SimDeviceReport r = sim->report();
  EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
  EXPECT_EQ(r.pageable_async_copies, 0u);
  expect_nothing_left(*sim);
}

// The planner with amended commits (a second commit for a frame whose set
// no render has claimed): after each commit the target set equals the host
// arrays, and no copy re-sends a range that holds nothing new for the set:
// every change reaches each set exactly once.
TEST(CudaCommit, EveryChangeReachesEachSetExactlyOnce) {
  FrameScene fs(make_procedural_scene(3000, 12), 32, 32);
  DoubleBufferedCommits commits;
  // version[a][i]: frame in which element i of array a last changed.
  std::array<std::vector<uint32_t>, kKernelArrayCount> version;
  std::array<std::array<std::vector<uint32_t>, kKernelArrayCount>, 2> device;
  std::mt19937 rng(5);
  uint32_t target = 0;
  bool claimed = true;
  for (uint32_t f = 0; f < 120; ++f) {
    if (f > 0) edit_frame(fs.scene, f);
    const SceneDelta delta = fs.next_frame();
    for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
      const ArrayChange& c = kernel_array_change(delta, a);
      const size_t n = kernel_array_host_count(fs.ks, a);
      version[a].resize(n, f);
      if (delta.full || c.reallocated) std::fill(version[a].begin(), version[a].end(), f);
      c.for_each_range([&](uint32_t b, uint32_t e) {
        for (uint32_t i = b; i < std::min<size_t>(e, n); ++i)
          version[a][i] = f;
      });
    }
    // Amend (same set) a third of the time, as the tracer does for edits
    // that arrive after the prepared commit.
    const bool amend = commits.has_committed() && !claimed;
    target = amend ? commits.current_set() : (commits.current_set() + 1) % 2;
    const CommitPlan plan = commits.plan(fs.ks, target, fs.sync.change_log());
    for (const ArrayCopy& c : plan.copies) {
      std::vector<uint32_t>& d = device[target][c.array];
      if (c.resize) d.assign(c.count, ~0u);
      bool anything_new = c.end == c.begin;
      for (uint32_t i = c.begin; i < c.end; ++i) {
        anything_new = anything_new || d[i] != version[c.array][i];
        d[i] = version[c.array][i];
      }
      EXPECT_TRUE(anything_new || c.resize) << "frame " << f << ": " << kernel_array_name(c.array)
                                            << " [" << c.begin << ", " << c.end << ") re-sent";
    }
    commits.complete(plan);
    for (uint32_t a = 0; a < kKernelArrayCount; ++a)
      ASSERT_EQ(device[target][a], version[a])
          << "frame " << f << ", set " << target << ", " << kernel_array_name(a);
    claimed = rng() % 3 != 0;
  }
}

// Runs three frames of the tracer (overlapped when `overlap`) on a CUDA
// backend whose device fails as `spec` says, wrapped in the CPU fallback,
// each frame starting the accumulation over (so each frame's image is the
// same two samples per pixel); returns the frames' images and whether the
// fallback happened.
struct FaultRun {
  std::vector<ImageRGB> images;
  bool fell_back = false;
  bool constructed = true;
};
FaultRun run_with_fault(const FaultSpec& spec, std::shared_ptr<SimDevice> sim, bool overlap) {
  FaultRun out;
  Scene scene = load_scene("builtin:cornell");
  std::vector<std::unique_ptr<Backend>> backends;
  try {
    backends.push_back(make_cpu_fallback(
        std::make_unique<CudaBackend>(inject_faults(sim, spec), CudaKernelVariant::kMegakernel,
                                      CudaBackend::LaunchLimits{300, 600})));
  } catch (const DeviceError&) {
    out.constructed = false;  // the factory then uses the CPU; nothing to render here
    return out;
  }
  TracerSettings settings;
  settings.render.width = 32;
  settings.render.height = 24;
  settings.render.seed = 7;
  settings.tile_size = 8;
  settings.samples_per_frame = 2;
  CoreTracer tracer(std::move(backends), settings);
  for (uint32_t f = 0; f < 3; ++f) {
    tracer.reset_accumulation();
    tracer.begin_frame(scene);
    if (overlap) tracer.prepare_next_frame(scene);
    const FrameMetrics& m = tracer.end_frame();
    out.fell_back =
        out.fell_back || m.backends[0].name == "cpu" || m.backends[0].completed_after_failure;
    EXPECT_EQ(m.accumulated_spp, 2u);
    out.images.push_back(tracer.image());
  }
  return out;
}

// Every kind of device failure, at every point of a short run, overlapped
// or not: the run completes, each pixel of every frame is exactly what the
// host backend (tiles the device finished) or the CPU backend (after the
// fallback) computes for it, so no sums were lost, doubled or stale, and the
// device is left with nothing allocated.
TEST(CudaFaults, EveryFaultFallsBackToTheCpuWithTheRightImage) {
  const uint32_t width = 32, height = 24;
  auto reference = [&](Backend& b) {
    Scene scene = load_scene("builtin:cornell");
    TracerSettings settings;
    settings.render.width = width;
    settings.render.height = height;
    settings.render.seed = 7;
    settings.tile_size = 8;
    settings.samples_per_frame = 2;
    std::vector<std::unique_ptr<Backend>> one;
    struct Borrowed final : Backend {
      Backend& b;
      explicit Borrowed(Backend& x) : b(x) {}
      std::string name() const override { return b.name(); }
      BackendTraits traits() const override { return b.traits(); }
      void sync(const KernelScene& s, const SceneDelta& d) override { b.sync(s, d); }
      BackendStats render(const RenderPass& p, TileSource& t, Film& f) override {
        return b.render(p, t, f);
      }
    };
    one.push_back(std::make_unique<Borrowed>(b));
    CoreTracer tracer(std::move(one), settings);
    tracer.render_frame(scene);
    return tracer.image();
  };
  CpuBackend host{CpuTraversal::kTandemBvh};
  CpuBackend cpu{CpuTraversal::kEmbree};
  const ImageRGB on_host = reference(host), on_cpu = reference(cpu);
  const size_t pixels = size_t(width) * height;
  uint32_t runs = 0, fallbacks = 0;
  for (const char* kind : {"lost", "oom", "launch", "illegal-address"}) {
    for (bool overlap : {false, true}) {
      // `lost` counts every operation, the others only theirs.
      const uint32_t last = std::string(kind) == "lost" ? 160 : 40;
      for (uint32_t n = 1; n <= last; n += std::string(kind) == "lost" ? 3 : 1) {
        const std::string text = std::string(kind) + "@" + std::to_string(n);
        SCOPED_TRACE(text + (overlap ? ", overlapped" : ""));
        auto sim = std::make_shared<SimDevice>(quick());
        const FaultRun r = run_with_fault(parse_fault_spec(text), sim, overlap);
        ++runs;
        if (r.constructed) {
          fallbacks += r.fell_back;
          for (const ImageRGB& image : r.images) {
            size_t matched = 0;
            for (size_t i = 0; i < pixels; ++i) {
              matched += std::memcmp(&image.rgb[3 * i], &on_host.rgb[3 * i], 12) == 0 ||
                         std::memcmp(&image.rgb[3 * i], &on_cpu.rgb[3 * i], 12) == 0;
            }
            EXPECT_EQ(matched, pixels);
          }
        }
        const SimDeviceReport rep = sim->report();
        EXPECT_TRUE(rep.hazards.empty()) << hazards_of(rep);
        expect_nothing_left(*sim);
      }
    }
  }
  std::printf("[cuda] %u faulty runs, %u fell back to the CPU\n", runs, fallbacks);
  EXPECT_GT(fallbacks, runs / 3);
}

// Without the fallback (`--backend cuda`), a failure reaches the caller as a
// DeviceError; an out-of-memory failure does not poison the backend: the
// next sync and render succeed and give the right image (no stale sums, no
// slot left busy, no bookkeeping describing buffers a failed commit lost).
TEST(CudaFaults, OutOfMemoryLeavesTheBackendUsable) {
  const uint32_t width = 32, height = 24;
  FrameScene fs(load_scene("builtin:cornell"), width, height);
  const SceneDelta delta = fs.next_frame();
  CpuBackend host{CpuTraversal::kTandemBvh};
  host.sync(fs.ks, delta);
  const ImageRGB reference = render_image(host, width, height, 3);
  uint32_t failed_syncs = 0, failed_renders = 0;
  for (uint32_t n = 1; n <= 30; ++n) {
    SCOPED_TRACE("oom@" + std::to_string(n));
    auto sim = std::make_shared<SimDevice>(quick());
    {
      std::unique_ptr<CudaBackend> cuda;
      try {
        cuda = std::make_unique<CudaBackend>(
            inject_faults(sim, parse_fault_spec("oom@" + std::to_string(n))),
            CudaKernelVariant::kWavefront, CudaBackend::LaunchLimits{200, 400});
      } catch (const DeviceError& e) {
        EXPECT_EQ(e.fault(), DeviceFault::kOutOfMemory);
      }
      if (cuda) {
        try {
          cuda->sync(fs.ks, delta);
        } catch (const DeviceError&) {
          ++failed_syncs;
          cuda->sync(fs.ks, SceneDelta{});  // the set was marked for a full upload
        }
        ImageRGB image;
        try {
          image = render_image(*cuda, width, height, 3);
        } catch (const DeviceRenderError&) {
          ++failed_renders;
          image = render_image(*cuda, width, height, 3);
        }
        EXPECT_EQ(identical_pixels(image, reference), size_t(width) * height);
        for (uint32_t set = 0; set < 2; ++set) {
          if (set != cuda->newest_scene_set()) continue;
          std::vector<std::vector<uint8_t>> arrays;
          try {
            arrays = cuda->read_back_scene(set);
          } catch (const DeviceError&) {  // the injected failure hit the read-back itself
            arrays = cuda->read_back_scene(set);
          }
          for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
            const size_t bytes = kernel_array_host_count(fs.ks, a) * kernel_array_element_size(a);
            ASSERT_EQ(arrays[a].size(), bytes) << kernel_array_name(a);
            EXPECT_TRUE(bytes == 0 ||
                        std::memcmp(arrays[a].data(), kernel_array_host_data(fs.ks, a), bytes) == 0)
                << kernel_array_name(a);
          }
        }
      }
    }
    const SimDeviceReport r = sim->report();
    EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
    expect_nothing_left(*sim);
  }
  EXPECT_GT(failed_syncs, 0u);
  EXPECT_GT(failed_renders, 0u);
}

TEST(CudaFaults, FaultSpecsAreParsedStrictly) {
  EXPECT_EQ(parse_fault_spec("").kind, FaultSpec::kNone);
  EXPECT_EQ(parse_fault_spec("oom").nth, 1u);
  EXPECT_EQ(parse_fault_spec("lost@17").nth, 17u);
  EXPECT_EQ(parse_fault_spec("illegal-address@2").kind, FaultSpec::kIllegalAddress);
  for (const char* bad : {"boom", "oom@", "oom@0", "oom@-1", "oom@x", "launch@3x"})
    EXPECT_THROW(parse_fault_spec(bad), InputError) << bad;
}

// The fallback wrapper forwards all of the device backend's traits, so the
// tracer overlaps under `--backend auto`, and reports the CPU's once it
// fell back.
TEST(CudaFaults, FallbackForwardsTraitsAndChangesThemWhenItFallsBack) {
  auto sim = std::make_shared<SimDevice>(quick());
  CudaBackend plain(sim, CudaKernelVariant::kMegakernel, {});
  const BackendTraits device_traits = plain.traits();
  EXPECT_TRUE(device_traits.syncs_while_rendering);
  EXPECT_FALSE(device_traits.reads_host_scene_while_rendering);
  std::unique_ptr<Backend> wrapped = make_cpu_fallback(
      std::make_unique<CudaBackend>(inject_faults(sim, parse_fault_spec("launch@1")),
                                    CudaKernelVariant::kMegakernel, CudaBackend::LaunchLimits{}));
  EXPECT_EQ(wrapped->traits(), device_traits);
  FrameScene fs(load_scene("builtin:cornell"), 16, 16);
  wrapped->sync(fs.ks, fs.next_frame());
  render_image(*wrapped, 16, 16, 1);  // the first launch fails: now the CPU renders
  EXPECT_EQ(wrapped->traits(), CpuBackend(CpuTraversal::kEmbree).traits());
  EXPECT_EQ(wrapped->name(), "cpu");
}

// A device that fails in the denoiser's feature pass falls back to the CPU
// there too: the caller gets the CPU backend's features, not an exception.
TEST(CudaFaults, FeaturePassFailureFallsBackToTheCpu) {
  auto sim = std::make_shared<SimDevice>(quick());
  std::unique_ptr<Backend> wrapped = make_cpu_fallback(
      std::make_unique<CudaBackend>(inject_faults(sim, parse_fault_spec("launch@1")),
                                    CudaKernelVariant::kMegakernel, CudaBackend::LaunchLimits{}));
  FrameScene fs(load_scene("builtin:cornell"), 16, 16);
  const SceneDelta delta = fs.next_frame();
  wrapped->sync(fs.ks, delta);
  CpuBackend cpu(CpuTraversal::kEmbree);
  cpu.sync(fs.ks, delta);
  MotionHistory motion;
  const FeaturePass pass = motion.advance(fs.ks.view());
  std::vector<PixelFeatures> got(16 * 16), want(16 * 16);
  ASSERT_TRUE(wrapped->render_features(pass, got.data(), {}));  // the first launch fails
  EXPECT_EQ(wrapped->name(), "cpu");
  ASSERT_TRUE(cpu.render_features(pass, want.data(), {}));
  EXPECT_EQ(std::memcmp(got.data(), want.data(), got.size() * sizeof(PixelFeatures)), 0);
}

// Device-film writes are checked against the film: a tile outside it is a
// caller's bug, reported before anything is launched.
TEST(CudaSim, DeviceFilmRejectsTilesOutsideIt) {
  auto sim = std::make_shared<SimDevice>(quick());
  {
    FrameScene fs(load_scene("builtin:cornell"), 16, 16);
    CudaBackend cuda(sim, CudaKernelVariant::kMegakernel, {});
    cuda.sync(fs.ks, fs.next_frame());
    cuda.reset_device_film(16, 16);
    TileQueue inside(make_tile_grid(16, 16, 8));
    EXPECT_EQ(cuda.render_to_device_film(RenderPass{}, inside).samples, 256u);
    TileQueue outside(make_tile_grid(24, 16, 8));
    EXPECT_THROW(cuda.render_to_device_film(RenderPass{}, outside), std::logic_error);
    // The backend is still usable afterwards.
    cuda.reset_device_film(16, 16);
    TileQueue again(make_tile_grid(16, 16, 8));
    EXPECT_EQ(cuda.render_to_device_film(RenderPass{}, again).samples, 256u);
  }
  EXPECT_TRUE(sim->report().hazards.empty()) << hazards_of(sim->report());
}

// Freed blocks stay known to the simulator, so that a late use of one is a
// hazard. The C library hands their addresses out again inside larger
// blocks; the bytes of such a block past a freed block's old start must not
// be taken for freed memory (the hazard would skip the copy, leaving the
// device bytes as they were: found as wrong alpha keys in a CI run).
TEST(CudaSim, ABlockOverAFreedOnesAddressIsUsableToItsEnd) {
  SimDevice sim(quick());
  DeviceStream s = sim.create_stream();
  // Blocks this large are mapped and unmapped one by one by glibc, and a new
  // mapping goes into the highest hole that fits: two neighbours freed, one
  // block as large as both lands over their addresses.
  constexpr size_t kHalf = size_t(40) << 20, kBytes = 2 * kHalf;
  auto* source = static_cast<uint8_t*>(sim.alloc_pinned(kBytes));
  auto* back = static_cast<uint8_t*>(sim.alloc_pinned(kBytes));
  void* first = sim.alloc(kHalf);
  void* second = sim.alloc(kHalf);
  sim.free(first);
  sim.free(second);
  auto* device = static_cast<uint8_t*>(sim.alloc(kBytes));
  bool overlapped = false;
  for (const void* freed : {first, second}) {
    const auto* f = static_cast<const uint8_t*>(freed);
    overlapped |= f > device && f < device + kBytes;
  }
  if (overlapped) {
    for (size_t i = 0; i < kBytes; i += 4096)
      source[i] = uint8_t(i / 4096 * 7 + 1);
    // In pieces, as the scene's commit sends ranges: a piece that starts
    // past a freed block's old address is where the lookup went wrong.
    constexpr size_t kPiece = kBytes / 8;
    for (size_t at = 0; at < kBytes; at += kPiece) {
      sim.copy_to_device(device + at, source + at, kPiece, s);
      sim.copy_to_host(back + at, device + at, kPiece, s);
    }
    sim.synchronize(s);
    EXPECT_TRUE(sim.report().hazards.empty()) << hazards_of(sim.report());
    EXPECT_EQ(std::memcmp(back, source, kBytes), 0);
  }
  sim.free(device);
  sim.free_pinned(back);
  sim.free_pinned(source);
  sim.destroy_stream(s);
  expect_nothing_left(sim);
  if (!overlapped) GTEST_SKIP() << "the C library put the block elsewhere";
}

}  // namespace
}  // namespace tandem
