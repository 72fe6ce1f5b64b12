// The wavefront pipeline of core/kernel/wavefront.h on the CPU: every stage
// a TBB loop over its queue, in the order the GPU launches its kernels. The
// CPU backend renders with it (--kernel wavefront) and the simulated GPU
// runs the CUDA backend's wavefront variant with it, so CI runs the GPU's
// queue logic and checks that it gives the megakernel's bits.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <vector>

#include "core/kernel/wavefront.h"
#include "core/render/backend.h"

namespace tandem {

// Host storage of a pipeline's arrays.
class CpuWavefrontStorage {
 public:
  WavefrontArrays arrays(uint32_t slots) {
    if (paths_.size() < slots) {
      paths_.resize(slots);
      hits_.resize(slots);
      shadows_.resize(slots);
      for (std::vector<uint32_t>* v :
           {&slot_item_, &extend_[0], &extend_[1], &hit_, &miss_, &shadow_, &retire_})
        v->resize(slots);
    }
    WavefrontArrays w;
    w.paths = paths_.data();
    w.hits = hits_.data();
    w.shadows = shadows_.data();
    w.slot_item = slot_item_.data();
    w.extend_queues[0] = extend_[0].data();
    w.extend_queues[1] = extend_[1].data();
    w.hit_queue = hit_.data();
    w.miss_queue = miss_.data();
    w.shadow_queue = shadow_.data();
    w.retire_queue = retire_.data();
    w.counters = counters_.data();
    w.slots = slots;
    return w;
  }

 private:
  std::vector<PathState> paths_;
  std::vector<Hit> hits_;
  std::vector<ShadowRay> shadows_;
  std::vector<uint32_t> slot_item_, extend_[2], hit_, miss_, shadow_, retire_;
  std::array<uint32_t, kWaveCounterCount> counters_{};
};

// A tracer that also answers packets of up to kPacketSize rays at once
// (Embree's rtcIntersect16 / rtcOccluded16): the extend and connect stages
// then hand it queue slices instead of one ray at a time.
constexpr uint32_t kPacketSize = 16;
template <class T>
concept PacketTracer = requires(const T& t, const Ray* rays, const uint32_t* keys, Hit* hits,
                                bool* occluded) {
  t.intersect_packet(rays, keys, 1u, hits);
  t.occluded_packet(rays, keys, 1u, occluded);
};

namespace detail {
template <class F>
void parallel_over(uint32_t n, const F& f) {
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, 64),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      for (uint32_t i = r.begin(); i != r.end(); ++i)
                        f(i);
                    });
}
}  // namespace detail

// Traces every item of `batch` into radiance[item] with the w.slots paths
// of `w` in flight; returns the rays traced.
template <class Tracer>
uint64_t run_wavefront_on_cpu(const KernelData& kd, const Tracer& tracer, const TileBatch& batch,
                              const WavefrontArrays& w, Vec3* radiance) {
  const uint32_t slots = w.slots;
  if (slots == 0 || batch.items() == 0) return 0;
  std::fill(w.counters, w.counters + kWaveCounterCount, 0u);
  detail::parallel_over(
      slots, [&](uint32_t s) { wavefront_regenerate(kd, batch, w, kWavefrontFillRound, s); });
  for (uint32_t round = 0;; ++round) {
    wavefront_begin_round(w);
    const uint32_t n = w.counters[kWaveExtend];
    if (n == 0) break;
    if constexpr (PacketTracer<Tracer>) {
      detail::parallel_over((n + kPacketSize - 1) / kPacketSize, [&](uint32_t chunk) {
        const uint32_t first = chunk * kPacketSize, m = std::min(kPacketSize, n - first);
        // Zeroed although only the first m are read: GCC cannot see that
        // through a tracer compiled in another file, and warns.
        Ray rays[kPacketSize]{};
        uint32_t keys[kPacketSize]{};
        Hit hits[kPacketSize];
        for (uint32_t j = 0; j < m; ++j)
          rays[j] = wavefront_extend_ray(w, round, first + j, &keys[j]);
        tracer.intersect_packet(rays, keys, m, hits);
        for (uint32_t j = 0; j < m; ++j)
          wavefront_extend_done(w, round, first + j, hits[j]);
      });
    } else {
      detail::parallel_over(n, [&](uint32_t i) { wavefront_extend(tracer, w, round, i); });
    }
    detail::parallel_over(w.counters[kWaveMiss], [&](uint32_t i) {
      wavefront_shade_miss(kd, batch, w, round, i, radiance);
    });
    detail::parallel_over(w.counters[kWaveHit], [&](uint32_t i) {
      wavefront_shade_hit(kd, batch, w, round, i, radiance);
    });
    const uint32_t shadows = w.counters[kWaveShadow];
    if constexpr (PacketTracer<Tracer>) {
      detail::parallel_over((shadows + kPacketSize - 1) / kPacketSize, [&](uint32_t chunk) {
        const uint32_t first = chunk * kPacketSize, m = std::min(kPacketSize, shadows - first);
        Ray rays[kPacketSize]{};  // zeroed as above
        uint32_t keys[kPacketSize]{};
        bool occluded[kPacketSize];
        for (uint32_t j = 0; j < m; ++j) {
          const ShadowRay& sr = wavefront_connect_ray(w, first + j);
          rays[j] = sr.ray;
          keys[j] = sr.alpha_key;
        }
        tracer.occluded_packet(rays, keys, m, occluded);
        for (uint32_t j = 0; j < m; ++j)
          wavefront_connect_done(w, round, first + j, occluded[j]);
      });
    } else {
      detail::parallel_over(shadows, [&](uint32_t i) { wavefront_connect(tracer, w, round, i); });
    }
    detail::parallel_over(w.counters[kWaveRetire], [&](uint32_t i) {
      wavefront_retire_ended(kd, batch, w, round, i, radiance);
    });
  }
  return w.counters[kWaveRays];
}

// The same with at most `max_slots` paths in host storage.
template <class Tracer>
uint64_t run_wavefront_on_cpu(const KernelData& kd, const Tracer& tracer, const TileBatch& batch,
                              uint32_t max_slots, CpuWavefrontStorage& storage, Vec3* radiance) {
  const uint32_t slots = uint32_t(std::min<uint64_t>(batch.items(), max_slots));
  return run_wavefront_on_cpu(kd, tracer, batch, storage.arrays(slots), radiance);
}

// The CPU backend's tile loop in wavefront form: tiles are pulled from the
// frame's source in batches, each batch's samples traced by the pipeline,
// summed per pixel in sample order and double precision (what the
// megakernel's tile loop does) and added to the film. A batch of the wavefront pipeline: up to 16
// tiles of 32x32 (fewer, larger batches would leave less for the tile scheduler to balance), traced
// in chunks of at most kWavefrontMaxItems pixel samples with at most kWavefrontSlots paths in
// flight (enough to keep every core busy in each stage).
constexpr uint32_t kWavefrontBatchPixels = 16 * 32 * 32;
constexpr uint64_t kWavefrontMaxItems = 1u << 18;
constexpr uint32_t kWavefrontSlots = 1u << 14;

template <class Tracer>
BackendStats render_tiles_wavefront_on_cpu(const KernelData& kd, const Tracer& tracer,
                                           const RenderPass& pass, TileSource& source, Film& film,
                                           CpuWavefrontStorage& storage) {
  const auto start = std::chrono::steady_clock::now();
  BackendStats stats;
  std::vector<Tile> tiles;
  std::vector<DeviceTile> batch_tiles;
  std::vector<Vec3> radiance;
  std::vector<double> sums;
  for (;;) {
    tiles.clear();
    batch_tiles.clear();
    uint32_t pixels = 0;
    Tile t;
    while (pixels < kWavefrontBatchPixels && source.next(&t)) {
      tiles.push_back(t);
      batch_tiles.push_back(DeviceTile{t.x0, t.y0, t.x1, t.y1, pixels});
      pixels += t.pixel_count();
    }
    if (tiles.empty()) break;
    TileBatch batch;
    batch.tiles = batch_tiles.data();
    batch.tile_count = uint32_t(batch_tiles.size());
    batch.pixel_count = pixels;
    const uint32_t chunk = uint32_t(std::max<uint64_t>(1, kWavefrontMaxItems / pixels));
    sums.assign(3 * size_t(pixels), 0.0);
    for (uint32_t done = 0; done < pass.sample_count; done += chunk) {
      batch.sample_begin = pass.sample_begin + done;
      batch.sample_count = std::min(chunk, pass.sample_count - done);
      radiance.resize(batch.items());
      stats.rays +=
          run_wavefront_on_cpu(kd, tracer, batch, kWavefrontSlots, storage, radiance.data());
      // Sample order and double precision per pixel, as the tile loop sums.
      detail::parallel_over(pixels, [&](uint32_t p) {
        reduce_pixel_samples(batch, radiance.data(), p, sums.data());
      });
    }
    size_t p = 0;
    for (const Tile& tile : tiles) {
      for (uint32_t y = tile.y0; y < tile.y1; ++y)
        for (uint32_t x = tile.x0; x < tile.x1; ++x, ++p)
          film.add(x, y, &sums[3 * p], pass.sample_count);
      stats.tiles += 1;
      stats.pixels += tile.pixel_count();
      stats.samples += uint64_t(tile.pixel_count()) * pass.sample_count;
    }
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace tandem
