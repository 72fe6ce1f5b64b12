// The host side of the CUDA backend's kernels (device_launch.h, the buffer
// sets of device_scene.h), on the simulated device, which runs the kernels'
// own bodies: the wavefront's round loop gives the megakernel's radiance
// without waiting for the device, and the bookkeeping that an earlier
// version got wrong (a second commit of a frame while the other set
// renders, the hidden-copy figure, staging grown during a render, buffers
// allocated per call, a sync racing the feature pass, hazards on every
// wavefront array) is tested where it went wrong.
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <memory>
#include <stdexcept>
#include <vector>

#include "backends/cpu/cpu_backend.h"
#include "backends/cuda/cuda_backend.h"
#include "backends/cuda/device_launch.h"
#include "backends/cuda/device_scene.h"
#include "backends/cuda/kernel_arrays.h"
#include "backends/cuda/sim_device.h"
#include "core/kernel/integrator.h"
#include "core/world/motion_history.h"
#include "cuda_test_util.h"

namespace tandem {
namespace {

using namespace cuda_test;

std::string hazards_of(const SimDeviceReport& r) {
  std::string s;
  for (const std::string& h : r.hazards)
    s += "\n  " + h;
  return s;
}

// A batch of the whole film in one tile, with its radiance and ray count,
// on the simulated device.
struct DeviceBatch {
  SimDevice& sim;
  DeviceBuffer tiles, radiance, rays, wave, host;
  TileBatch batch;
  WavefrontArrays arrays{};

  DeviceBatch(SimDevice& s, uint32_t width, uint32_t height, uint32_t spp, DeviceStream stream)
      : sim(s),
        tiles(s, DeviceBuffer::kDevice),
        radiance(s, DeviceBuffer::kDevice),
        rays(s, DeviceBuffer::kDevice),
        wave(s, DeviceBuffer::kDevice),
        host(s, DeviceBuffer::kPinned) {
    const DeviceTile tile{0, 0, width, height, 0};
    batch.tile_count = 1;
    batch.pixel_count = width * height;
    batch.sample_begin = 0;
    batch.sample_count = spp;
    tiles.allocate(sizeof tile);
    radiance.allocate(batch.items() * sizeof(Vec3));
    rays.allocate(sizeof(unsigned long long));
    host.allocate(std::max<size_t>(sizeof tile, batch.items() * sizeof(Vec3)));
    std::memcpy(host.get(), &tile, sizeof tile);
    sim.copy_to_device(tiles.get(), host.get(), sizeof tile, stream);
    sim.zero(rays.get(), sizeof(unsigned long long), stream);
    batch.tiles = tiles.as<const DeviceTile>();
    const uint32_t slots =
        std::min<uint32_t>(uint32_t(batch.items()), wavefront_slots(sim.properties()));
    uint64_t bytes = 0;
    wavefront_arrays_in(nullptr, slots, &bytes);
    wave.allocate(bytes);
    arrays = wavefront_arrays_in(wave.get(), slots, &bytes);
  }

  std::vector<Vec3> read_radiance(DeviceStream stream) {
    sim.copy_to_host(host.get(), radiance.get(), batch.items() * sizeof(Vec3), stream);
    sim.synchronize(stream);
    const auto* p = host.as<const Vec3>();
    return std::vector<Vec3>(p, p + batch.items());
  }
};

bool same_bits(const Vec3& a, const Vec3& b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// The wavefront's host loop enqueues a batch without one wait for the
// device (the rounds it can need fit the lookahead), a larger batch waits
// only to stay within the lookahead, and both give every item the radiance
// the host computes for it, bit for bit.
TEST(CudaDriver, WavefrontEnqueuesABatchWithoutWaitingForTheDevice) {
  SimDevice sim;
  {
    FrameScene fs(load_scene("builtin:cornell-spheres"), 24, 16);
    const SceneDelta delta = fs.next_frame();
    DeviceScene scene(sim);
    scene.commit(fs.ks, delta);
    DeviceStreamOwner stream(sim);
    WavefrontDriver driver(sim);
    const KernelData kd = fs.ks.view();
    for (const uint32_t spp : {1u, 12u}) {
      SCOPED_TRACE(std::to_string(spp) + " spp");
      DeviceBatch b(sim, 24, 16, spp, stream.get());
      const DeviceScene::RenderTicket ticket = scene.begin_render(stream.get());
      const uint64_t bound =
          wavefront_round_bound(b.batch.items(), b.arrays.slots, ticket.max_segments);
      const uint64_t waits_before = sim.report().host_waits;
      driver.launch(ticket.view, b.batch, ticket.max_segments, b.arrays, b.radiance.as<Vec3>(),
                    b.rays.as<unsigned long long>(), stream.get());
      scene.end_render(ticket, stream.get());
      if (bound <= WavefrontDriver::kLookaheadRounds) {
        EXPECT_EQ(driver.last_host_waits(), 0u);
        EXPECT_EQ(sim.report().host_waits, waits_before) << "the host waited for the device";
        EXPECT_EQ(driver.last_rounds(), bound);
      } else {
        EXPECT_GT(driver.last_host_waits(), 0u);
        EXPECT_LE(driver.last_rounds(), bound);
      }
      const std::vector<Vec3> radiance = b.read_radiance(stream.get());
      size_t same = 0;
      for (uint64_t item = 0; item < b.batch.items(); ++item) {
        const uint32_t pixel = uint32_t(item % b.batch.pixel_count);
        uint32_t rays = 0;
        same += same_bits(radiance[item],
                          render_pixel_sample(kd, BvhTracer{&kd}, pixel % 24, pixel / 24,
                                              uint32_t(item / b.batch.pixel_count), &rays));
      }
      EXPECT_EQ(same, b.batch.items());
    }
  }
  const SimDeviceReport r = sim.report();
  EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
}

// Every array of the wavefront is in its kernels' access lists: a write
// from another stream with nothing ordering it against the batch is a
// hazard, whichever array it hits.
TEST(CudaDriver, UnorderedWriteToAnyWavefrontArrayIsAHazard) {
  FrameScene fs(load_scene("builtin:cornell"), 16, 16);
  const SceneDelta delta = fs.next_frame();
  for (const char* array : {"hits", "shadow rays", "the retire queue", "the shadow queue"}) {
    SCOPED_TRACE(array);
    SimDevice sim;
    {
      DeviceScene scene(sim);
      scene.commit(fs.ks, delta);
      DeviceStreamOwner stream(sim), other(sim);
      WavefrontDriver driver(sim);
      DeviceBatch b(sim, 16, 16, 2, stream.get());
      const DeviceScene::RenderTicket ticket = scene.begin_render(stream.get());
      driver.launch(ticket.view, b.batch, ticket.max_segments, b.arrays, b.radiance.as<Vec3>(),
                    b.rays.as<unsigned long long>(), stream.get());
      scene.end_render(ticket, stream.get());
      const WavefrontArrays& w = b.arrays;
      const std::string name = array;
      void* target = name == "hits"               ? static_cast<void*>(w.hits)
                     : name == "shadow rays"      ? static_cast<void*>(w.shadows)
                     : name == "the retire queue" ? static_cast<void*>(w.retire_queue)
                                                  : static_cast<void*>(w.shadow_queue);
      sim.zero(target, sizeof(uint32_t), other.get());
      sim.synchronize(stream.get());
      sim.synchronize(other.get());
    }
    const SimDeviceReport r = sim.report();
    bool named = false;
    for (const std::string& h : r.hazards)
      named = named || h.find(array) != std::string::npos;
    EXPECT_TRUE(named) << hazards_of(r);
  }
}

// Frame 3 is committed while frame 2 renders, then amended (a second commit
// for the same frame): the amendment goes to frame 3's set, not to the set
// frame 2 renders from, and the hidden-copy figure of frame 3 is measured
// against the moment frame 3's render could start.
TEST(CudaDeviceScene, SecondCommitOfAFrameWhileTheOtherSetRendersAmendsIt) {
  SimDevice sim;
  {
    FrameScene fs(make_procedural_scene(2000, 5), 16, 16);
    DeviceScene scene(sim);
    DeviceStreamOwner render(sim);
    auto render_frame = [&] {
      const DeviceScene::RenderTicket t = scene.begin_render(render.get());
      scene.end_render(t, render.get());
      sim.synchronize(render.get());
      return t;
    };
    scene.commit(fs.ks, fs.next_frame());  // frame 1
    render_frame();
    edit_frame(fs.scene, 2);
    scene.commit(fs.ks, fs.next_frame());  // frame 2
    const DeviceScene::RenderTicket frame2 = scene.begin_render(render.get());
    edit_frame(fs.scene, 3);
    scene.commit(fs.ks, fs.next_frame());  // frame 3, while frame 2 renders
    edit_frame(fs.scene, 4);
    EXPECT_NO_THROW(scene.commit(fs.ks, fs.next_frame()));  // frame 3 amended
    EXPECT_NE(scene.newest_set(), frame2.set);
    scene.end_render(frame2, render.get());
    sim.synchronize(render.get());
    (void)scene.take_timing(frame2);
    scene.synchronize();  // every copy of frame 3 has landed
    const DeviceScene::RenderTicket frame3 = render_frame();
    const DeviceScene::CommitTiming t = scene.take_timing(frame3);
    EXPECT_GT(t.copy_seconds, 0.0);
    EXPECT_DOUBLE_EQ(t.hidden_seconds, t.copy_seconds) << "the copies ended before the render";
    // The amended set holds frame 4's edits.
    const std::vector<std::vector<uint8_t>> device = scene.read_back(frame3.set);
    const auto& instances = fs.ks.instances;
    ASSERT_EQ(device[kArray_instances].size(), instances.size() * sizeof(KInstance));
    EXPECT_EQ(std::memcmp(device[kArray_instances].data(), instances.data(),
                          instances.size() * sizeof(KInstance)),
              0);
  }
  const SimDeviceReport r = sim.report();
  EXPECT_TRUE(r.hazards.empty()) << hazards_of(r);
}

// A commit that needs more staging memory than the set has, while the other
// set renders, does not wait for that render: staging grows without freeing
// pinned memory, which waits for the whole device.
TEST(CudaDeviceScene, GrowingStagingDuringARenderDoesNotWaitForIt) {
  SimDevice sim;
  {
    FrameScene small(load_scene("builtin:cornell"), 16, 16);
    FrameScene large(make_procedural_scene(20000, 7), 16, 16);
    DeviceScene scene(sim);
    scene.commit(small.ks, small.next_frame());  // set A
    DeviceStreamOwner render(sim);
    const DeviceScene::RenderTicket a = scene.begin_render(render.get());
    scene.end_render(a, render.get());
    sim.synchronize(render.get());
    scene.commit(small.ks, SceneDelta::everything());  // set B: both sets have small staging
    const DeviceScene::RenderTicket b = scene.begin_render(render.get());
    sim.stall(render.get(), 0.3);  // frame B renders for a while
    const uint64_t stalls = sim.report().device_wide_waits;
    scene.commit(large.ks, large.next_frame());  // into set A, much larger
    EXPECT_EQ(sim.report().device_wide_waits, stalls) << "the commit waited for the render";
    scene.end_render(b, render.get());
    sim.synchronize(render.get());
    scene.synchronize();
    EXPECT_EQ(scene.read_back(scene.newest_set())[kArray_positions].size(),
              large.ks.positions.size() * sizeof(Vec3));
  }
  EXPECT_TRUE(sim.report().hazards.empty()) << hazards_of(sim.report());
}

// trace_rays keeps its buffers: a second call of the same size allocates
// nothing (every allocation of a device can wait for it).
TEST(CudaBackendQueries, TraceRaysAllocatesOnlyToGrow) {
  auto sim = std::make_shared<SimDevice>();
  FrameScene fs(load_scene("builtin:cornell"), 16, 16);
  const SceneDelta delta = fs.next_frame();
  CudaBackend cuda(sim, CudaKernelVariant::kMegakernel, {});
  cuda.sync(fs.ks, delta);
  const KernelData kd = fs.ks.view();
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < 300; ++i) {
    PathState p;
    path_generate(kd, i % 16, (i / 16) % 16, i, &p);
    rays.push_back(p.ray);
  }
  const std::vector<uint32_t> keys(rays.size(), 0u);
  (void)cuda.trace_rays(rays, keys, false);
  const uint64_t allocations = sim->report().allocations;
  for (bool any_hit : {false, true}) {
    const std::vector<Hit> hits = cuda.trace_rays(rays, keys, any_hit);
    for (size_t i = 0; i < rays.size(); ++i) {
      const Hit h =
          bvh_trace_counted<false, true>(kd, rays[i], 0u, kd.bvh.layout, any_hit, nullptr);
      EXPECT_EQ(std::memcmp(&hits[i], &h, sizeof h), 0) << i;
    }
  }
  EXPECT_EQ(sim->report().allocations, allocations);
}

// A DeviceOps that calls `hook` once, at the first allocation or copy to
// the device, before doing it.
class HookedDevice final : public DeviceOps {
 public:
  HookedDevice(std::shared_ptr<DeviceOps> inner) : inner_(std::move(inner)) {}
  std::function<void()> hook;
  std::string name() const override { return inner_->name(); }
  void* alloc(size_t bytes) override {
    fire();
    return inner_->alloc(bytes);
  }
  void free(void* p) override { inner_->free(p); }
  void* alloc_async(size_t bytes, DeviceStream s) override {
    fire();
    return inner_->alloc_async(bytes, s);
  }
  void free_async(void* p, DeviceStream s) override { inner_->free_async(p, s); }
  void* alloc_pinned(size_t bytes) override {
    fire();
    return inner_->alloc_pinned(bytes);
  }
  void free_pinned(void* p) override { inner_->free_pinned(p); }
  DeviceStream create_stream() override { return inner_->create_stream(); }
  void destroy_stream(DeviceStream s) override { inner_->destroy_stream(s); }
  DeviceEvent create_event(bool timing) override { return inner_->create_event(timing); }
  void destroy_event(DeviceEvent e) override { inner_->destroy_event(e); }
  void record(DeviceEvent e, DeviceStream s) override { inner_->record(e, s); }
  void wait(DeviceStream s, DeviceEvent e) override { inner_->wait(s, e); }
  void synchronize(DeviceEvent e) override { inner_->synchronize(e); }
  void synchronize(DeviceStream s) override { inner_->synchronize(s); }
  double elapsed_seconds(DeviceEvent a, DeviceEvent b) override {
    return inner_->elapsed_seconds(a, b);
  }
  void copy_to_device(void* d, const void* s, size_t n, DeviceStream st) override {
    fire();
    inner_->copy_to_device(d, s, n, st);
  }
  void copy_to_host(void* d, const void* s, size_t n, DeviceStream st) override {
    inner_->copy_to_host(d, s, n, st);
  }
  void zero(void* d, size_t n, DeviceStream s) override { inner_->zero(d, n, s); }
  DeviceProperties properties() const override { return inner_->properties(); }
  uint32_t resident_blocks(DeviceKernel k, uint32_t threads) override {
    return inner_->resident_blocks(k, threads);
  }
  void launch(DeviceKernel k, const LaunchDims& d, const void* a, size_t n,
              DeviceStream s) override {
    inner_->launch(k, d, a, n, s);
  }

 private:
  void fire() {
    if (!hook) return;
    std::function<void()> once = std::move(hook);
    hook = nullptr;
    once();
  }
  std::shared_ptr<DeviceOps> inner_;
};

// A sync() with another film size that lands while render_features() runs
// (here: at its first device allocation) is refused with a logic_error
// instead of a kernel that strides by one size and writes another; the next
// call renders the new size, the CPU's features exactly.
TEST(CudaBackendQueries, SyncWithANewSizeDuringTheFeaturePassIsRefused) {
  auto sim = std::make_shared<SimDevice>();
  {
    auto hooked = std::make_shared<HookedDevice>(sim);
    FrameScene first(load_scene("builtin:cornell-spheres"), 24, 16);
    FrameScene second(load_scene("builtin:cornell-spheres"), 32, 24);
    const SceneDelta d1 = first.next_frame(), d2 = second.next_frame();
    CudaBackend cuda(hooked, CudaKernelVariant::kMegakernel, {});
    cuda.sync(first.ks, d1);
    hooked->hook = [&] { cuda.sync(second.ks, d2); };
    MotionHistory motion;
    std::vector<PixelFeatures> out(24 * 16);
    EXPECT_THROW(cuda.render_features(motion.advance(first.ks.view()), out.data(), {}),
                 std::logic_error);
    std::vector<PixelFeatures> now(32 * 24), cpu(32 * 24);
    motion.reset();
    const FeaturePass pass = motion.advance(second.ks.view());
    ASSERT_TRUE(cuda.render_features(pass, now.data(), {}));
    CpuBackend host{CpuTraversal::kTandemBvh};
    host.sync(second.ks, d2);
    ASSERT_TRUE(host.render_features(pass, cpu.data(), {}));
    EXPECT_EQ(std::memcmp(now.data(), cpu.data(), now.size() * sizeof(PixelFeatures)), 0);
  }
  EXPECT_TRUE(sim->report().hazards.empty()) << hazards_of(sim->report());
}

}  // namespace
}  // namespace tandem
