// The host side of the CUDA backend's kernels, written once for every
// device (the CUDA GPU and the simulated one): launch geometry, the
// wavefront's round loop, and one typed helper per kernel over
// DeviceOps::launch(). Every function here only enqueues on its stream;
// none waits for the device unless it says so.
#pragma once

#include <array>

#include "backends/cuda/device_kernels.h"
#include "backends/cuda/device_ops.h"

namespace tandem {

template <class K>
void launch_kernel(DeviceOps& dev, const LaunchDims& dims, const typename K::Args& args,
                   DeviceStream stream) {
  dev.launch(K::kId, dims, &args, sizeof args, stream);
}

// One thread per item of a one-dimensional range, in blocks of K::kThreads.
template <class K>
LaunchDims launch_dims_for(uint64_t items) {
  LaunchDims d;
  d.block.x = K::kThreads;
  d.grid.x = uint32_t((items + K::kThreads - 1) / K::kThreads);
  return d;
}

// Paths the wavefront keeps in flight: four times the threads the device
// holds at once, so that the queues stay full while paths end and slots
// are regenerated.
uint32_t wavefront_slots(const DeviceProperties& properties);

// Rounds of the wavefront that are sure to finish every item of a batch of
// `items` pixel samples with `slots` slots, when no path has more than
// `max_segments` segments: while items remain, every slot is busy in every
// round, so at most items * max_segments / slots rounds pass before the
// last item is taken, and its path then needs at most max_segments more.
uint64_t wavefront_round_bound(uint64_t items, uint32_t slots, uint32_t max_segments);

// The host's loop over the wavefront's rounds, for one stream. It is
// asynchronous: it enqueues the rounds a batch can need (the bound above;
// the kernels of a round after the batch ended see empty queues and return
// at once), and waits for the device only to stay at most kLookaheadRounds
// rounds ahead of it, reading how many paths go on every kRoundsPerRead
// rounds and stopping when none do. With the default depth that bound is
// within the lookahead for any batch that fills the device, so the host
// never waits. Owns a ring of pinned counters, allocated once.
class WavefrontDriver {
 public:
  static constexpr uint32_t kRoundsPerRead = 8;
  static constexpr uint32_t kReadsInFlight = 4;
  static constexpr uint32_t kLookaheadRounds = kRoundsPerRead * kReadsInFlight;

  explicit WavefrontDriver(DeviceOps& dev);
  WavefrontDriver(const WavefrontDriver&) = delete;
  WavefrontDriver& operator=(const WavefrontDriver&) = delete;

  // Traces every item of `batch` into radiance[item] with the slots of
  // `wave` (at least min(batch.items(), wave.slots) of them) and adds the
  // rays to *ray_count. `max_segments`: the scene's max_depth + 1.
  void launch(const KernelData* kd, const TileBatch& batch, uint32_t max_segments,
              const WavefrontArrays& wave, Vec3* radiance, unsigned long long* ray_count,
              DeviceStream stream);

  // Of the most recent launch: rounds enqueued, and the host waits it made.
  uint32_t last_rounds() const { return last_rounds_; }
  uint32_t last_host_waits() const { return last_host_waits_; }

 private:
  DeviceOps& dev_;
  DeviceBuffer counts_;  // pinned: kReadsInFlight counters
  std::array<DeviceEventOwner, kReadsInFlight> read_done_;
  uint32_t last_rounds_ = 0, last_host_waits_ = 0;
};

// Each of these is one launch on `stream` (device_kernels.h says what the
// kernel computes).
void launch_megakernel(DeviceOps& dev, const KernelData* kd, const TileBatch& batch, Vec3* radiance,
                       unsigned long long* ray_count, DeviceStream stream);
void launch_reduce_samples(DeviceOps& dev, const TileBatch& batch, const Vec3* radiance,
                           double* pixel_sums, DeviceStream stream);
void launch_accumulate_film(DeviceOps& dev, const TileBatch& batch, const double* pixel_sums,
                            uint32_t sample_count, const DeviceFilmView& film, DeviceStream stream);
void launch_resolve_film(DeviceOps& dev, const DeviceFilmView& film, float* rgb,
                         DeviceStream stream);
void launch_tone_map_film(DeviceOps& dev, const DeviceFilmView& film, float exposure_scale,
                          uint32_t curve, uint8_t* rgb8, DeviceStream stream);
// Persistent threads: as many blocks as the device holds at once, or fewer
// for a short array. `work_counter` must be zero on entry.
void launch_trace_rays(DeviceOps& dev, const KernelData* kd, const Ray* rays,
                       const uint32_t* alpha_keys, uint32_t n, bool any_hit, Hit* hits,
                       uint32_t* work_counter, DeviceStream stream);
// The feature pass of a width x height film whose camera `kd` holds.
void launch_features(DeviceOps& dev, const KernelData* kd, const FeaturePass& pass, uint32_t width,
                     uint32_t height, PixelFeatures* out, DeviceStream stream);
// 16 x 16 blocks over a width x height image.
LaunchDims svgf_launch_dims(uint32_t width, uint32_t height);

}  // namespace tandem
