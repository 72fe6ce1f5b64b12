// The CPU backend's tile loop: TBB workers pull tiles from a TileSource and
// trace each pixel's samples with the shared integrator. Its traversals
// differ only in their Tracer (Embree, or Tandem's own BVH).
#pragma once

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <vector>

#include "core/kernel/integrator.h"
#include "core/render/backend.h"

namespace tandem {

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
    Tile tile;
    while (tiles.next(&tile)) {
      const auto tile_start = std::chrono::steady_clock::now();
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
