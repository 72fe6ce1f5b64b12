#include "tracer/tile_scheduler.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace tandem {

// The per-backend view of the frame that Backend::render() pulls from.
class TileScheduler::BackendSource final : public TileSource {
 public:
  BackendSource(TileScheduler* owner, size_t backend) : owner_(owner), backend_(backend) {}
  bool next(Tile* tile) override { return owner_->take(backend_, tile); }

 private:
  TileScheduler* owner_;
  size_t backend_;
};

TileScheduler::TileScheduler(SchedulerSettings settings) : settings_(settings) {}
TileScheduler::~TileScheduler() = default;

void TileScheduler::reset(std::vector<Tile> tiles, size_t backend_count) {
  tiles_ = std::move(tiles);
  // Until a tile has been measured its cost is its pixel count, relative to
  // the mean: edge tiles of a frame not divisible by the tile size are cheap.
  cost_.assign(tiles_.size(), 1.0);
  double mean = 0.0;
  for (const Tile& t : tiles_)
    mean += double(t.pixel_count());
  mean /= std::max<size_t>(tiles_.size(), 1);
  for (size_t i = 0; i < tiles_.size(); ++i)
    cost_[i] = mean > 0.0 ? double(tiles_[i].pixel_count()) / mean : 1.0;
  rate_.assign(backend_count, 0.0);
  enabled_.assign(backend_count, true);
  log_speed_.assign(backend_count, 0.0);
  speed_known_.assign(backend_count, false);
  last_seconds_.assign(tiles_.size(), -1.0);
  timed_by_.assign(tiles_.size(), -1);
  cost_measured_ = false;
  planned_.assign(backend_count, backend_count ? 1.0 / double(backend_count) : 0.0);
  segments_.assign(backend_count, Segment{});
  owner_.assign(tiles_.size(), -1);
  sources_.clear();
  for (size_t b = 0; b < backend_count; ++b)
    sources_.push_back(std::make_unique<BackendSource>(this, b));
}

void TileScheduler::set_enabled(const std::vector<bool>& enabled) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (enabled.size() != enabled_.size()) return;
  // At least one backend must render.
  if (std::find(enabled.begin(), enabled.end(), true) == enabled.end()) return;
  enabled_ = enabled;
}

std::vector<double> TileScheduler::target_shares() const {
  const size_t n = rate_.size();
  std::vector<double> share(n, 0.0);
  if (n == 0) return share;
  if (n == 1) return {1.0};
  // Unmeasured backends are assumed as fast as the mean of the measured ones
  // (or all equal on the first frame).
  double known = 0.0;
  size_t known_count = 0;
  for (double r : rate_) {
    if (r > 0.0) {
      known += r;
      ++known_count;
    }
  }
  std::vector<double> rate(rate_);
  for (double& r : rate) {
    if (!(r > 0.0)) r = known_count ? known / double(known_count) : 1.0;
  }
  size_t first_balanced = 0;
  double remaining = 1.0;
  if (settings_.forced_split >= 0.0f) {
    share[0] = std::clamp(double(settings_.forced_split), 0.0, 1.0);
    remaining -= share[0];
    first_balanced = 1;
  }
  const double sum = std::accumulate(rate.begin() + long(first_balanced), rate.end(), 0.0);
  for (size_t b = first_balanced; b < n; ++b)
    share[b] = remaining * rate[b] / sum;
  if (settings_.forced_split < 0.0f) {
    // Keep every enabled backend measurable, then renormalise.
    double total = 0.0;
    for (size_t b = 0; b < n; ++b) {
      share[b] = enabled_[b] ? std::max(share[b], settings_.min_share) : 0.0;
      total += share[b];
    }
    for (double& s : share)
      s /= total;
  }
  return share;
}

std::vector<TileSource*> TileScheduler::begin_frame() {
  std::lock_guard<std::mutex> lock(mutex_);
  planned_ = target_shares();
  // A forced split is a share of the frame's pixels (hence of its samples),
  // as asked, whatever the tiles cost; a balanced split is a share of the
  // learned cost, so that the backends finish together.
  std::vector<double> pixels;
  if (settings_.forced_split >= 0.0f) {
    pixels.reserve(tiles_.size());
    for (const Tile& t : tiles_)
      pixels.push_back(double(t.pixel_count()));
  }
  const std::vector<double>& weight = pixels.empty() ? cost_ : pixels;
  const double total = std::accumulate(weight.begin(), weight.end(), 0.0);
  // Cut the row-major list where the running weight crosses each backend's
  // cumulative share; a cut lands on the tile boundary nearest to it.
  size_t begin = 0;
  double cumulative_share = 0.0, running = 0.0;
  for (size_t b = 0; b < segments_.size(); ++b) {
    cumulative_share += planned_[b];
    size_t end = begin;
    if (b + 1 == segments_.size()) {
      end = tiles_.size();
    } else {
      const double target = cumulative_share * total;
      while (end < tiles_.size() && running + 0.5 * weight[end] < target)
        running += weight[end++];
    }
    segments_[b] = Segment{begin, end, 0};
    begin = end;
  }
  std::fill(owner_.begin(), owner_.end(), -1);
  std::vector<TileSource*> out;
  for (auto& s : sources_)
    out.push_back(s.get());
  return out;
}

bool TileScheduler::take(size_t backend, Tile* tile) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!enabled_[backend]) return false;
  Segment& own = segments_[backend];
  size_t index;
  if (own.next < own.end) {
    index = own.next++;
  } else {
    if (!settings_.stealing) return false;
    // Steal from the back of the segment with the most unstarted cost: the
    // tiles its owner would have reached last.
    size_t victim = segments_.size();
    double most = 0.0;
    for (size_t b = 0; b < segments_.size(); ++b) {
      const Segment& s = segments_[b];
      double left = 0.0;
      for (size_t i = s.next; i < s.end; ++i)
        left += cost_[i];
      if (left > most) {
        most = left;
        victim = b;
      }
    }
    // Taking the victim's very last tile is only worth it when it still has
    // more than that left; otherwise both would just race for it.
    if (victim == segments_.size() || segments_[victim].end - segments_[victim].next < 2)
      return false;
    index = --segments_[victim].end;
    own.stolen += 1;
  }
  owner_[index] = int32_t(backend);
  *tile = tiles_[index];
  return true;
}

void TileScheduler::end_frame(const std::vector<double>& backend_seconds,
                              const std::vector<double>& tile_seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  const double a = std::clamp(settings_.smoothing, 0.0, 1.0);
  const size_t n = rate_.size();
  const bool have_tile_times = tile_seconds.size() == tiles_.size();

  // Relative worker speeds. Tile costs and backend speeds cannot be told
  // apart from one backend's own tiles; a tile that was timed by one backend
  // and now by another tells their ratio. Such tiles appear every frame the
  // segment boundaries move or a backend steals.
  if (have_tile_times) {
    std::vector<double> log_sum(n, 0.0);
    std::vector<int> count(n, 0);
    for (size_t i = 0; i < tiles_.size(); ++i) {
      const int32_t b = owner_[i], prev = timed_by_[i];
      if (b < 0 || prev < 0 || prev == b || !(tile_seconds[i] > 0.0) || !(last_seconds_[i] > 0.0))
        continue;
      // log(speed_b) should be log(speed_prev) + log(t_b / t_prev).
      log_sum[size_t(b)] += log_speed_[size_t(prev)] + std::log(tile_seconds[i] / last_seconds_[i]);
      count[size_t(b)] += 1;
    }
    for (size_t b = 1; b < n; ++b) {
      if (count[b] == 0) continue;
      // The first ratio replaces the guess outright; later ones smooth.
      const double w = speed_known_[b] ? a : 1.0;
      log_speed_[b] = (1.0 - w) * log_speed_[b] + w * (log_sum[b] / double(count[b]));
      speed_known_[b] = true;
    }
    // Backend 0's observations pin everyone else relative to it.
    if (count[0] > 0) {
      const double shift = log_sum[0] / double(count[0]);  // what backend 0 "should" be
      for (size_t b = 1; b < n; ++b)
        log_speed_[b] -= a * shift;
    }
  }

  bool first_measurement = false;
  if (have_tile_times) {
    // Tile cost in backend 0's worker-seconds.
    for (size_t i = 0; i < tiles_.size(); ++i) {
      const int32_t b = owner_[i];
      if (b < 0 || !(tile_seconds[i] > 0.0)) continue;
      const double measured = tile_seconds[i] / std::exp(log_speed_[size_t(b)]);
      cost_[i] = cost_measured_ ? (1.0 - a) * cost_[i] + a * measured : measured;
      last_seconds_[i] = tile_seconds[i];
      timed_by_[i] = b;
    }
    // The first timed frame replaces the pixel-count guess wholesale (units
    // differ); tiles nobody timed keep the mean.
    if (!cost_measured_) {
      first_measurement = true;
      double sum = 0.0;
      size_t timed = 0;
      for (size_t i = 0; i < tiles_.size(); ++i) {
        if (timed_by_[i] >= 0) {
          sum += cost_[i];
          ++timed;
        }
      }
      if (timed > 0) {
        for (size_t i = 0; i < tiles_.size(); ++i) {
          if (timed_by_[i] < 0) cost_[i] = sum / double(timed);
        }
        cost_measured_ = true;
      }
    }
  }
  // Costs are now in backend 0's worker-seconds: rates measured against the
  // pixel-count guess are in other units and start over.
  if (first_measurement) std::fill(rate_.begin(), rate_.end(), 0.0);
  for (size_t b = 0; b < n; ++b) {
    double done = 0.0;
    for (size_t i = 0; i < tiles_.size(); ++i) {
      if (owner_[i] == int32_t(b)) done += cost_[i];
    }
    if (done > 0.0 && b < backend_seconds.size() && backend_seconds[b] > 0.0) {
      const double r = done / backend_seconds[b];
      rate_[b] = rate_[b] > 0.0 ? (1.0 - a) * rate_[b] + a * r : r;
    }
  }
}

std::vector<uint32_t> TileScheduler::stolen_counts() const {
  std::vector<uint32_t> out;
  for (const Segment& s : segments_)
    out.push_back(s.stolen);
  return out;
}

}  // namespace tandem
