#include "backends/mpi/mpi_peer_backend.h"

#include <chrono>
#include <cstring>
#include <map>

#include "backends/mpi/mpi_channel.h"

namespace tandem::mpi {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}
}  // namespace

MpiPeerBackend::MpiPeerBackend(WorkerInfo info, PeerSettings settings)
    : info_(std::move(info)), settings_(settings) {
  if (settings_.tiles_per_batch == 0) settings_.tiles_per_batch = 1;
  if (settings_.batches_in_flight == 0) settings_.batches_in_flight = 1;
}

std::string MpiPeerBackend::name() const {
  return "rank" + std::to_string(info_.rank) + ":" + info_.backends;
}

BackendTraits MpiPeerBackend::traits() const {
  BackendTraits t;
  // Its kernel arrays come from rank 0's KernelScene: when the worker's
  // backends trace Tandem's BVH, rank 0 must build it.
  t.needs_bvh = info_.needs_bvh;
  t.uses_host_cores = false;  // another machine's cores
  // sync() copied everything render() needs to the worker.
  t.reads_host_scene_while_rendering = false;
  t.syncs_while_rendering = false;
  return t;
}

void MpiPeerBackend::sync(const KernelScene& scene, const SceneDelta& delta) {
  const auto start = Clock::now();
  if (!reset_sent_) {
    // The worker may still hold the scene of an earlier renderer: start over.
    send(info_.rank, kTagReset, {}, settings_.timeout_s);
    receiver_counts_.fill(0);
    reset_sent_ = true;
  }
  if (!delta.any() && receiver_counts_ != ArrayCounts{}) return;
  SceneDelta d = delta;
  if (receiver_counts_ == ArrayCounts{}) d.merge(SceneDelta::everything());
  WireWriter w;
  encode_scene(scene, d, receiver_counts_, w);
  send(info_.rank, kTagSync, w.bytes(), settings_.timeout_s);
  pending_.bytes_to_worker += w.bytes().size();
  pending_.scene_bytes += w.bytes().size();
  pending_.sync_seconds += seconds_since(start);
}

BackendStats MpiPeerBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  const auto start = Clock::now();
  BackendStats stats;
  PeerFrameStats& fs = pending_;
  std::map<uint32_t, std::vector<Tile>> in_flight;  // batch id -> its tiles
  bool source_empty = false;
  auto send_batch = [&]() {
    TileBatch b;
    b.id = next_batch_id_++;
    b.sample_begin = pass.sample_begin;
    b.sample_count = pass.sample_count;
    b.film_width = film.width();
    b.film_height = film.height();
    Tile t;
    while (b.tiles.size() < settings_.tiles_per_batch && tiles.next(&t))
      b.tiles.push_back(t);
    if (b.tiles.empty()) {
      source_empty = true;
      return;
    }
    WireWriter w;
    encode_batch(b, w);
    send(info_.rank, kTagBatch, w.bytes(), settings_.timeout_s);
    fs.bytes_to_worker += w.bytes().size();
    ++fs.batches;
    in_flight.emplace(b.id, std::move(b.tiles));
  };
  while (!source_empty && in_flight.size() < settings_.batches_in_flight)
    send_batch();
  while (!in_flight.empty()) {
    Message m = receive(info_.rank, settings_.timeout_s, "the sums of a tile batch");
    if (m.tag == kTagError) {
      WireReader r(m.bytes, "error message of rank " + std::to_string(info_.rank));
      throw RankFailure(info_.rank, r.get_string());
    }
    if (m.tag != kTagResult) throw RankFailure(info_.rank, "sent an unexpected message");
    fs.bytes_from_worker += m.bytes.size();
    WireReader r(m.bytes, "result from rank " + std::to_string(info_.rank));
    const BatchResult res = decode_result(r);
    auto it = in_flight.find(res.id);
    if (it == in_flight.end() || it->second.size() != res.tiles.size() ||
        std::memcmp(it->second.data(), res.tiles.data(), res.tiles.size() * sizeof(Tile)) != 0)
      throw RankFailure(info_.rank, "answered with tiles it was not sent");
    // Ask for more before adding, so the worker's queue never runs dry.
    in_flight.erase(it);
    if (!source_empty) send_batch();
    size_t at = 0;
    for (size_t i = 0; i < res.tiles.size(); ++i) {
      const Tile& t = res.tiles[i];
      for (uint32_t y = t.y0; y < t.y1; ++y) {
        for (uint32_t x = t.x0; x < t.x1; ++x, at += 3)
          film.add(x, y, &res.sums[at], pass.sample_count);
      }
      if (pass.tile_seconds && res.tile_seconds[i] >= 0.0)
        pass.tile_seconds[t.index] = res.tile_seconds[i];
      stats.tiles += 1;
      stats.pixels += t.pixel_count();
    }
    stats.rays += res.rays;
    stats.samples += res.samples;
    fs.worker_busy_seconds += res.busy_seconds;
  }
  stats.commit_bytes = fs.scene_bytes;
  stats.seconds = seconds_since(start);
  last_ = fs;
  pending_ = PeerFrameStats{};
  return stats;
}

}  // namespace tandem::mpi
