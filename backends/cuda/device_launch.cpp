#include "backends/cuda/device_launch.h"

#include <algorithm>

namespace tandem {

namespace {

// Enough blocks of K to fill the device once (persistent threads), but no
// more than `needed`.
template <class K>
uint32_t persistent_blocks(DeviceOps& dev, uint64_t needed) {
  const uint64_t resident =
      uint64_t(dev.properties().multiprocessors) * dev.resident_blocks(K::kId, K::kThreads);
  return uint32_t(std::max<uint64_t>(1, std::min(resident, needed)));
}

}  // namespace

uint32_t wavefront_slots(const DeviceProperties& p) {
  return uint32_t(
      std::max<uint64_t>(1, 4ull * p.multiprocessors * p.max_threads_per_multiprocessor));
}

uint64_t wavefront_round_bound(uint64_t items, uint32_t slots, uint32_t max_segments) {
  if (items == 0 || slots == 0) return 0;
  return items * max_segments / slots + max_segments;
}

WavefrontDriver::WavefrontDriver(DeviceOps& dev) : dev_(dev), counts_(dev, DeviceBuffer::kPinned) {
  counts_.allocate(kReadsInFlight * sizeof(uint32_t));
  for (DeviceEventOwner& e : read_done_)
    e = DeviceEventOwner(dev, false);
}

void WavefrontDriver::launch(const KernelData* kd, const TileBatch& batch, uint32_t max_segments,
                             const WavefrontArrays& wave, Vec3* radiance,
                             unsigned long long* ray_count, DeviceStream s) {
  last_rounds_ = last_host_waits_ = 0;
  const uint64_t items = batch.items();
  if (items == 0) return;
  WaveArgs a{};
  a.kd = kd;
  a.batch = batch;
  a.w = wave;
  a.w.slots = uint32_t(std::min<uint64_t>(items, wave.slots));
  a.radiance = radiance;
  a.ray_count = ray_count;
  const LaunchDims over_slots = launch_dims_for<WaveShadeHit>(a.w.slots);
  LaunchDims extend = launch_dims_for<WaveExtend>(a.w.slots);
  extend.grid.x = persistent_blocks<WaveExtend>(dev_, extend.grid.x);
  LaunchDims connect = launch_dims_for<WaveConnect>(a.w.slots);
  connect.grid.x = persistent_blocks<WaveConnect>(dev_, connect.grid.x);
  LaunchDims one;  // one thread

  dev_.zero(a.w.counters, kWaveCounterCount * sizeof(uint32_t), s);
  launch_kernel<WaveFill>(dev_, launch_dims_for<WaveFill>(a.w.slots), a, s);
  const uint64_t bound = wavefront_round_bound(items, a.w.slots, std::max(1u, max_segments));
  const uint64_t chunks = (bound + kRoundsPerRead - 1) / kRoundsPerRead;
  // Reads only when the host could run more than the lookahead ahead.
  const bool reads = chunks > kReadsInFlight;
  auto* counts = counts_.as<uint32_t>();
  for (uint64_t c = 0; c < chunks; ++c) {
    const uint32_t ring = uint32_t(c % kReadsInFlight);
    if (reads && c >= kReadsInFlight) {
      // The read after chunk c - kReadsInFlight: no path left, no round more.
      dev_.synchronize(read_done_[ring].get());
      ++last_host_waits_;
      if (counts[ring] == 0) break;
    }
    for (uint64_t r = c * kRoundsPerRead; r < std::min(bound, (c + 1) * kRoundsPerRead); ++r) {
      a.round = uint32_t(r);
      launch_kernel<WaveBeginRound>(dev_, one, a, s);
      launch_kernel<WaveExtend>(dev_, extend, a, s);
      launch_kernel<WaveShadeMiss>(dev_, over_slots, a, s);
      launch_kernel<WaveShadeHit>(dev_, over_slots, a, s);
      launch_kernel<WaveConnect>(dev_, connect, a, s);
      launch_kernel<WaveRetire>(dev_, over_slots, a, s);
      ++last_rounds_;
    }
    if (reads) {
      // Paths queued for the next round: 0 once the batch is done.
      dev_.copy_to_host(&counts[ring], &a.w.counters[kWaveNextExtend], sizeof(uint32_t), s);
      dev_.record(read_done_[ring].get(), s);
    }
  }
  launch_kernel<WaveCountRays>(dev_, one, a, s);
}

void launch_megakernel(DeviceOps& dev, const KernelData* kd, const TileBatch& batch, Vec3* radiance,
                       unsigned long long* ray_count, DeviceStream s) {
  if (batch.items() == 0) return;
  launch_kernel<Megakernel>(dev, launch_dims_for<Megakernel>(batch.items()),
                            MegakernelArgs{kd, batch, radiance, ray_count}, s);
}

void launch_reduce_samples(DeviceOps& dev, const TileBatch& batch, const Vec3* radiance,
                           double* pixel_sums, DeviceStream s) {
  if (batch.pixel_count == 0) return;
  launch_kernel<ReduceSamples>(dev, launch_dims_for<ReduceSamples>(batch.pixel_count),
                               ReduceSamplesArgs{batch, radiance, pixel_sums}, s);
}

void launch_accumulate_film(DeviceOps& dev, const TileBatch& batch, const double* pixel_sums,
                            uint32_t sample_count, const DeviceFilmView& film, DeviceStream s) {
  if (batch.pixel_count == 0) return;
  launch_kernel<AccumulateFilm>(dev, launch_dims_for<AccumulateFilm>(batch.pixel_count),
                                AccumulateFilmArgs{batch, pixel_sums, film, sample_count}, s);
}

void launch_resolve_film(DeviceOps& dev, const DeviceFilmView& film, float* rgb, DeviceStream s) {
  const uint64_t n = uint64_t(film.width) * film.height;
  if (n == 0) return;
  launch_kernel<ResolveFilm>(dev, launch_dims_for<ResolveFilm>(n), ResolveFilmArgs{film, rgb}, s);
}

void launch_tone_map_film(DeviceOps& dev, const DeviceFilmView& film, float exposure_scale,
                          uint32_t curve, uint8_t* rgb8, DeviceStream s) {
  const uint64_t n = uint64_t(film.width) * film.height;
  if (n == 0) return;
  launch_kernel<ToneMapFilm>(dev, launch_dims_for<ToneMapFilm>(n),
                             ToneMapFilmArgs{film, rgb8, exposure_scale, curve}, s);
}

void launch_trace_rays(DeviceOps& dev, const KernelData* kd, const Ray* rays,
                       const uint32_t* alpha_keys, uint32_t n, bool any_hit, Hit* hits,
                       uint32_t* work_counter, DeviceStream s) {
  if (n == 0) return;
  LaunchDims d = launch_dims_for<TraceRays>(n);
  d.grid.x = persistent_blocks<TraceRays>(dev, d.grid.x);
  launch_kernel<TraceRays>(
      dev, d, TraceRaysArgs{kd, rays, alpha_keys, hits, work_counter, n, any_hit ? 1u : 0u}, s);
}

LaunchDims svgf_launch_dims(uint32_t width, uint32_t height) {
  static_assert(Features::kThreads == kSvgfBlockSide * kSvgfBlockSide, "16 x 16 blocks");
  LaunchDims d;
  d.block = {kSvgfBlockSide, kSvgfBlockSide, 1};
  d.grid = {(width + kSvgfBlockSide - 1) / kSvgfBlockSide,
            (height + kSvgfBlockSide - 1) / kSvgfBlockSide, 1};
  return d;
}

void launch_features(DeviceOps& dev, const KernelData* kd, const FeaturePass& pass, uint32_t width,
                     uint32_t height, PixelFeatures* out, DeviceStream s) {
  if (width == 0 || height == 0) return;
  launch_kernel<Features>(dev, svgf_launch_dims(width, height),
                          FeaturesArgs{kd, pass, out, width, height}, s);
}

}  // namespace tandem
