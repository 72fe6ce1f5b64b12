// The tile scheduler on its own: every tile handed out exactly once under
// concurrent pulls, segments follow the forced split, and the balancer
// converges when one backend is artificially slow.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "tracer/tile_scheduler.h"

namespace tandem {
namespace {

// Pulls every tile the scheduler gives each "backend" from several threads
// per backend, as TBB workers would; returns how often each tile was seen.
std::vector<int> drain(TileScheduler& s, int threads_per_backend,
                       std::vector<int>* per_backend = nullptr) {
  std::vector<TileSource*> sources = s.begin_frame();
  std::vector<std::atomic<int>> seen(s.tile_count());
  std::vector<std::atomic<int>> counts(sources.size());
  std::vector<std::thread> threads;
  for (size_t b = 0; b < sources.size(); ++b) {
    for (int t = 0; t < threads_per_backend; ++t) {
      threads.emplace_back([&, b] {
        Tile tile;
        while (sources[b]->next(&tile)) {
          seen[tile.index]++;
          counts[b]++;
        }
      });
    }
  }
  for (std::thread& t : threads)
    t.join();
  std::vector<int> out;
  for (auto& v : seen)
    out.push_back(v.load());
  if (per_backend) {
    per_backend->clear();
    for (auto& c : counts)
      per_backend->push_back(c.load());
  }
  return out;
}

TEST(TileScheduler, EveryTileExactlyOnceForAnySplitWithAndWithoutStealing) {
  for (bool stealing : {true, false}) {
    for (float split : {-1.0f, 0.0f, 0.1f, 0.5f, 0.9f, 1.0f}) {
      for (size_t backends : {1u, 2u, 3u}) {
        SchedulerSettings st;
        st.forced_split = split;
        st.stealing = stealing;
        TileScheduler s(st);
        s.reset(make_tile_grid(100, 70, 16), backends);
        for (int frame = 0; frame < 3; ++frame) {
          const std::vector<int> seen = drain(s, 3);
          for (size_t i = 0; i < seen.size(); ++i) {
            ASSERT_EQ(seen[i], 1) << "tile " << i << " split " << split << " stealing " << stealing
                                  << " backends " << backends << " frame " << frame;
            ASSERT_GE(s.owners()[i], 0);
          }
          s.end_frame(std::vector<double>(backends, 0.01), {});
        }
      }
    }
  }
}

TEST(TileScheduler, ForcedSplitGivesBackendZeroItsShareWithoutStealing) {
  SchedulerSettings st;
  st.stealing = false;
  for (float split : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f}) {
    st.forced_split = split;
    TileScheduler s(st);
    s.reset(make_tile_grid(64, 64, 8), 2);  // 64 equal tiles
    std::vector<int> per_backend;
    drain(s, 2, &per_backend);
    EXPECT_EQ(per_backend[0], int(split * 64.0f + 0.5f)) << "split " << split;
    EXPECT_EQ(per_backend[0] + per_backend[1], 64);
  }
}

TEST(TileScheduler, StealingTakesUnstartedTilesFromTheBusyBackend) {
  SchedulerSettings st;
  st.forced_split = 0.5f;
  TileScheduler s(st);
  s.reset(make_tile_grid(64, 64, 8), 2);
  std::vector<TileSource*> src = s.begin_frame();
  // Backend 1 drains everything before backend 0 starts: it must take all of
  // backend 0's tiles but the one backend 0 could still be working on.
  Tile t;
  int taken = 0;
  while (src[1]->next(&t))
    ++taken;
  EXPECT_EQ(taken, 63);
  EXPECT_EQ(s.stolen_counts()[1], 31u);
  ASSERT_TRUE(src[0]->next(&t));
  EXPECT_EQ(t.index, 0u);
  EXPECT_FALSE(src[0]->next(&t));
}

// Two simulated backends on a simulated clock (no sleeping, so the test
// means the same on a loaded machine): backend 1 takes `slow` times as long
// per unit of tile cost as backend 0, and tiles in the top half cost 3x.
// Whichever backend is earlier in simulated time pulls the next tile, as
// concurrent backends would.
std::vector<double> fake_frame(TileScheduler& s, double slow, double* finish0, double* finish1) {
  std::vector<TileSource*> src = s.begin_frame();
  std::vector<double> tile_seconds(s.tile_count(), -1.0);
  double clock[2] = {0.0, 0.0};
  bool done[2] = {false, false};
  while (!done[0] || !done[1]) {
    const size_t b = done[0] ? 1 : done[1] ? 0 : (clock[1] < clock[0] ? 1 : 0);
    Tile t;
    if (!src[b]->next(&t)) {
      done[b] = true;
      continue;
    }
    const double seconds = (t.y0 < 32 ? 3.0 : 1.0) * (b == 1 ? slow : 1.0) * 1e-3;
    tile_seconds[t.index] = seconds;
    clock[b] += seconds;
  }
  *finish0 = clock[0];
  *finish1 = clock[1];
  s.end_frame({clock[0], clock[1]}, tile_seconds);
  return s.planned_shares();
}

TEST(TileScheduler, BalancerConvergesWhenOneBackendIsSlowed) {
  SchedulerSettings st;
  st.stealing = false;  // so the plan alone has to balance the frame
  TileScheduler s(st);
  s.reset(make_tile_grid(64, 64, 8), 2);
  double f0 = 0, f1 = 0;
  std::vector<double> shares;
  for (int frame = 0; frame < 10; ++frame)
    shares = fake_frame(s, 4.0, &f0, &f1);
  // Backend 0 is 4x faster: it should plan ~80% of the cost.
  EXPECT_NEAR(shares[0], 0.8, 0.08);
  // The learned costs see the expensive top half.
  double top = 0, bottom = 0;
  for (const Tile& t : s.tiles())
    (t.y0 < 32 ? top : bottom) += s.tile_costs()[t.index];
  EXPECT_GT(top, 2.0 * bottom);
  // And the backends now finish close together, without stealing (one tile
  // of backend 1 is 12 ms of a ~100 ms frame).
  fake_frame(s, 4.0, &f0, &f1);
  EXPECT_LT(std::max(f0, f1) / std::min(f0, f1), 1.25) << f0 << " vs " << f1;
}

}  // namespace
}  // namespace tandem
