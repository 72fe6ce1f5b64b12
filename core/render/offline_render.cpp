#include "core/render/offline_render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

namespace tandem {

OfflineRenderResult render_offline(Backend& backend, uint32_t width, uint32_t height,
                                   const OfflineRenderOptions& options) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  Film film(width, height);
  const std::vector<Tile> grid = make_tile_grid(width, height, options.tile_size);
  // A handful of passes gives a smooth progress bar without hurting the
  // per-tile locality of rendering many samples of the same pixels at once.
  const uint32_t spp = std::max(options.spp, 1u);
  const uint32_t pass_spp = std::max(1u, (spp + 7) / 8);
  const uint32_t passes = (spp + pass_spp - 1) / pass_spp;

  // All queues outlive the monitor thread, which may still be reading one.
  std::vector<std::unique_ptr<TileQueue>> queues;
  for (uint32_t p = 0; p < passes; ++p)
    queues.push_back(std::make_unique<TileQueue>(grid));
  std::atomic<const TileQueue*> current{nullptr};
  std::atomic<uint32_t> pass_index{0};
  std::mutex mutex;
  std::condition_variable done_cv;
  bool done = false;
  std::thread monitor;
  if (options.progress) {
    monitor = std::thread([&] {
      std::unique_lock<std::mutex> lock(mutex);
      while (!done_cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return done; })) {
        const TileQueue* q = current.load();
        const double in_pass = q && q->size() ? double(q->taken()) / double(q->size()) : 0.0;
        options.progress(std::min(1.0, (double(pass_index.load()) + in_pass) / double(passes)));
      }
    });
  }

  OfflineRenderResult result;
  for (uint32_t p = 0; p < passes; ++p) {
    RenderPass pass;
    pass.sample_begin = p * pass_spp;
    pass.sample_count = std::min(pass_spp, spp - pass.sample_begin);
    current = queues[p].get();
    pass_index = p;
    result.stats += backend.render(pass, *queues[p], film);
  }
  if (monitor.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      done = true;
    }
    done_cv.notify_all();
    monitor.join();
    options.progress(1.0);
  }
  result.image = film.resolve();
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace tandem
