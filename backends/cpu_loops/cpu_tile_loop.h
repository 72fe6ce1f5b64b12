// The CPU backend's tile loop: TBB workers pull tiles from a TileSource and
// trace each pixel's samples with the shared integrator. Its traversals
// differ only in their Tracer (Embree, or Tandem's own BVH). A tracer that
// answers coherent packets (EmbreePacketTracer::intersect_coherent) gets a
// tile's camera rays in batches of 8: the first hits of 8 consecutive
// (pixel, sample) paths of a tile row, as coherent as rays get, in one
// rtcIntersect8; every path then runs the shared loop from its first hit
// (render_path_from_hit).
#pragma once

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <memory>
#include <vector>

#include "core/kernel/integrator.h"
#include "core/render/backend.h"

namespace tandem {

template <class T>
concept CameraPacketTracer = requires(const T& t, const Ray* rays, const uint32_t* keys,
                                      Hit* hits) {
  t.intersect_coherent(rays, keys, 1u, hits);
};

// The pixels of a tile in row order and each pixel's samples of the pass
// in a row, as one sequence of paths cut into batches of kCameraBatch: a
// batch's camera rays are traced together, then its paths one by one. A
// batch spans at most kCameraBatch consecutive pixels, so slot
// (pixel % kCameraBatch) holds a pixel's generator cache and sum while its
// samples are in flight. Samples are summed in index order as in the
// per-pixel loop, and paths depend only on (pixel, sample, seed).
constexpr uint32_t kCameraBatch = 8;

struct CameraBatchState {
  PixelRngCache cache[kCameraBatch];
  double sum[kCameraBatch][3];
  PathState path[kCameraBatch];
  Ray ray[kCameraBatch];
  uint32_t key[kCameraBatch];
  Hit hit[kCameraBatch];
};

template <class Tracer>
void render_tile_batched(const KernelData& kd, const Tracer& tracer, const RenderPass& pass,
                         const Tile& tile, Film& film, CameraBatchState& b, BackendStats& st) {
  const uint32_t tile_w = tile.x1 - tile.x0;
  const uint64_t spp = pass.sample_count;
  const uint64_t total = uint64_t(tile.pixel_count()) * spp;
  uint32_t rays = 0;
  if (spp == 0) {  // as the per-pixel loop: every pixel gets its (empty) sum
    const double zero[3] = {0.0, 0.0, 0.0};
    for (uint32_t y = tile.y0; y < tile.y1; ++y)
      for (uint32_t x = tile.x0; x < tile.x1; ++x)
        film.add(x, y, zero, 0);
  }
  for (uint64_t begin = 0; begin < total; begin += kCameraBatch) {
    const uint32_t n = uint32_t(total - begin < kCameraBatch ? total - begin : kCameraBatch);
    for (uint32_t j = 0; j < n; ++j) {
      const uint64_t i = begin + j;
      const uint32_t pixel = uint32_t(i / spp), s = uint32_t(i % spp);
      const uint32_t slot = pixel % kCameraBatch;
      const uint32_t x = tile.x0 + pixel % tile_w, y = tile.y0 + pixel / tile_w;
      if (s == 0) {
        pixel_rng_cache_reset(&b.cache[slot], y * kd.constants.camera.width + x,
                              kd.constants.integrator.seed);
        b.sum[slot][0] = b.sum[slot][1] = b.sum[slot][2] = 0.0;
      }
      path_generate_cached(kd, x, y, pass.sample_begin + s, &b.cache[slot], &b.path[j]);
      b.ray[j] = b.path[j].ray;
      b.key[j] = path_alpha_key(b.path[j]);
    }
    tracer.intersect_coherent(b.ray, b.key, n, b.hit);
    for (uint32_t j = 0; j < n; ++j) {
      const uint64_t i = begin + j;
      const uint32_t pixel = uint32_t(i / spp), s = uint32_t(i % spp);
      const uint32_t slot = pixel % kCameraBatch;
      PathState& p = b.path[j];
      const Vec3 l = render_path_from_hit(kd, tracer, p, CachedPathRng{p.rng, &b.cache[slot]},
                                          b.hit[j], &rays);
      b.sum[slot][0] += l.x;
      b.sum[slot][1] += l.y;
      b.sum[slot][2] += l.z;
      if (s + 1 == spp) {
        film.add(tile.x0 + pixel % tile_w, tile.y0 + pixel / tile_w, b.sum[slot],
                 pass.sample_count);
      }
    }
  }
  st.rays += rays;
}

template <class Tracer>
BackendStats render_tiles_on_cpu(const KernelData& kd, const Tracer& tracer, const RenderPass& pass,
                                 TileSource& tiles, Film& film) {
  const auto start = std::chrono::steady_clock::now();
  const int workers = tbb::this_task_arena::max_concurrency();
  std::vector<BackendStats> per_worker(static_cast<size_t>(workers));
  tbb::parallel_for(0, workers, [&](int w) {
    BackendStats& st = per_worker[size_t(w)];
    // A pixel's samples of the pass run in a row: their sample-independent
    // random-number seeds are computed once per pixel (and bounce).
    PixelRngCache rng_cache;
    [[maybe_unused]] std::unique_ptr<CameraBatchState> batch;
    if constexpr (CameraPacketTracer<Tracer>) batch = std::make_unique<CameraBatchState>();
    Tile tile;
    while (tiles.next(&tile)) {
      const auto tile_start = std::chrono::steady_clock::now();
      if constexpr (CameraPacketTracer<Tracer>) {
        render_tile_batched(kd, tracer, pass, tile, film, *batch, st);
      } else {
        for (uint32_t y = tile.y0; y < tile.y1; ++y) {
          for (uint32_t x = tile.x0; x < tile.x1; ++x) {
            uint32_t rays = 0;
            double sum[3] = {0.0, 0.0, 0.0};
            pixel_rng_cache_reset(&rng_cache, y * kd.constants.camera.width + x,
                                  kd.constants.integrator.seed);
            // Samples are summed in index order, so a pixel's value never
            // depends on which worker rendered it.
            for (uint32_t s = 0; s < pass.sample_count; ++s) {
              const Vec3 l = render_pixel_sample_cached(kd, tracer, x, y, pass.sample_begin + s,
                                                        &rng_cache, &rays);
              sum[0] += l.x;
              sum[1] += l.y;
              sum[2] += l.z;
            }
            film.add(x, y, sum, pass.sample_count);
            st.rays += rays;
          }
        }
      }
      if (pass.tile_seconds) {
        pass.tile_seconds[tile.index] =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - tile_start).count();
      }
      st.tiles += 1;
      st.pixels += tile.pixel_count();
      st.samples += uint64_t(tile.pixel_count()) * pass.sample_count;
    }
  });
  BackendStats total;
  for (const BackendStats& s : per_worker)
    total += s;
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace tandem
