// Splitting one frame's tiles between backends (Brigade's per-frame
// CPU/GPU split), so that all backends finish together.
//
// The scheduler keeps two estimates, both learned from measurements:
//   - a cost per tile, in seconds of one worker of backend 0 (before the
//     first measurement: relative pixel count): sky tiles are cheap, tiles
//     full of glass are not, and that ranking is the same for every backend;
//   - a throughput per backend, in tile-cost units per second.
// Each frame the tile list (row-major) is cut into one contiguous segment per
// backend whose summed cost is proportional to that backend's throughput.
// A backend pulls tiles from the front of its own segment; once it is empty
// it may steal unstarted tiles from the back of the segment with the most
// cost left (the tiles its owner would have reached last). The split only
// decides who renders a tile, never what is rendered: a pixel's samples are
// fixed by (pixel, sample index, seed), so the image does not depend on it.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "core/render/tiles.h"

namespace tandem {

struct SchedulerSettings {
  // < 0: balance by measured throughput. Otherwise the share of the frame's
  // pixels (so of its samples) planned for backend 0 (the GPU in a cuda+cpu
  // run), to the nearest tile boundary; the rest is balanced by cost.
  // Stealing can still move tiles; without it the split is what was asked.
  float forced_split = -1.0f;
  bool stealing = true;
  // Weight of the newest frame in the running estimates (1: only the last).
  double smoothing = 0.5;
  // Every backend gets at least this share of the cost, so its throughput
  // keeps being measured and it can win tiles back when it speeds up.
  double min_share = 0.02;
};

class TileScheduler {
 public:
  explicit TileScheduler(SchedulerSettings settings = {});
  ~TileScheduler();
  TileScheduler(const TileScheduler&) = delete;
  TileScheduler& operator=(const TileScheduler&) = delete;

  // New tile list (resolution or tile size changed) and backend count:
  // forgets all estimates.
  void reset(std::vector<Tile> tiles, size_t backend_count);
  void set_settings(const SchedulerSettings& s) { settings_ = s; }
  // Disabled backends get no tiles and steal none (the core tracer's choice
  // among backends that share the CPU cores). All are enabled after reset().
  void set_enabled(const std::vector<bool>& enabled);
  bool enabled(size_t backend) const { return enabled_[backend]; }
  const SchedulerSettings& settings() const { return settings_; }

  // Cuts this frame's segments and returns one TileSource per backend. The
  // sources stay valid until the next begin_frame().
  std::vector<TileSource*> begin_frame();
  // Measurements of the finished frame: every backend's wall time inside
  // render(), and the per-tile seconds backends reported (indexed by
  // Tile::index; negative where a backend measured nothing per tile).
  void end_frame(const std::vector<double>& backend_seconds,
                 const std::vector<double>& tile_seconds);

  size_t tile_count() const { return tiles_.size(); }
  size_t backend_count() const { return rate_.size(); }
  const std::vector<Tile>& tiles() const { return tiles_; }
  // Backend that rendered each tile in the current/last frame (-1: none).
  const std::vector<int32_t>& owners() const { return owner_; }
  // Planned share of the frame's cost per backend (sums to 1).
  const std::vector<double>& planned_shares() const { return planned_; }
  // Tiles each backend took from another's segment this frame.
  std::vector<uint32_t> stolen_counts() const;
  const std::vector<double>& tile_costs() const { return cost_; }
  const std::vector<double>& backend_rates() const { return rate_; }

 private:
  class BackendSource;
  bool take(size_t backend, Tile* tile);
  std::vector<double> target_shares() const;

  SchedulerSettings settings_;
  std::vector<Tile> tiles_;
  std::vector<double> cost_;  // per tile, mean 1
  std::vector<double> rate_;  // per backend, cost units / s (0: unknown)
  std::vector<double> planned_;
  std::vector<bool> enabled_;
  std::vector<double> log_speed_;  // per backend: log worker-seconds per cost unit, backend 0 = 0
  std::vector<bool> speed_known_;
  std::vector<double> last_seconds_;  // per tile: last measured worker-seconds
  std::vector<int32_t> timed_by_;     // per tile: backend that measured it (-1: none)
  bool cost_measured_ = false;
  struct Segment {
    size_t next = 0, end = 0;  // unstarted tiles are [next, end)
    uint32_t stolen = 0;
  };
  std::vector<Segment> segments_;
  std::vector<int32_t> owner_;
  std::vector<std::unique_ptr<BackendSource>> sources_;
  std::mutex mutex_;
};

}  // namespace tandem
