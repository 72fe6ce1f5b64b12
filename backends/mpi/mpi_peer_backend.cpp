#include "backends/mpi/mpi_peer_backend.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>

#include "backends/mpi/mpi_channel.h"
#include "core/util/cpu_time.h"

namespace tandem::mpi {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}
// What a tile adds to a result message: its sums, its seconds, itself.
size_t result_bytes_of(const Tile& t) {
  return size_t(t.pixel_count()) * 3 * sizeof(double) + sizeof(double) + sizeof(Tile);
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
    sends_.start(info_.rank, kTagReset, {});
    receiver_counts_.fill(0);
    reset_sent_ = true;
    worker_cpu_ = worker_render_cpu_ = 0;
  }
  if (!delta.any() && receiver_counts_ != ArrayCounts{}) return;
  // A worker that holds nothing gets everything, whatever changed.
  const bool empty = receiver_counts_ == ArrayCounts{};
  WireWriter w;
  encode_scene(scene, empty ? SceneDelta::everything() : delta, receiver_counts_, w);
  pending_.bytes_to_worker += w.bytes().size();
  pending_.scene_bytes += w.bytes().size();
  // Not waited for: the worker takes it when it next looks (it may be
  // rendering a batch of the previous frame), and the batches that follow
  // arrive after it (MPI keeps the order of one sender's messages).
  sends_.start(info_.rank, kTagSync, std::move(w.bytes()));
  pending_.sync_seconds += seconds_since(start);
}

Message MpiPeerBackend::wait_for_answer(const InFlight& oldest, bool last_batches) {
  // The worker renders its batches one after the other, and a batch takes
  // about as long as its fastest recent one at least (tiles' costs differ).
  // While more tiles are left, the batches queued behind the oldest keep the
  // worker busy, so an answer seen late costs nothing: poll half a batch
  // apart rather than every millisecond, as every wake-up costs CPU that a
  // renderer on this machine would use. Once the source is empty the frame
  // waits for these answers: back to the 1 ms cap of a plain wait.
  double fastest = 0.0;
  for (double t : recent_seconds_per_tile_)
    if (t > 0.0 && (fastest == 0.0 || t < fastest)) fastest = t;
  const double batch_s = fastest * double(oldest.tiles.size());
  const int half_batch_us = std::clamp(int(batch_s * 0.5e6), 20, 50000);
  const int first_nap_us = last_batches ? std::min(half_batch_us, 1000) : half_batch_us;
  const int max_nap_us = last_batches ? 1000 : std::max(half_batch_us, 1000);
  return receive(
      info_.rank, settings_.timeout_s, "the sums of a tile batch", [this] { sends_.progress(); },
      first_nap_us, max_nap_us);
}

BackendStats MpiPeerBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  const auto start = Clock::now();
  const double cpu_start = thread_cpu_seconds();
  BackendStats stats;
  PeerFrameStats& fs = pending_;
  std::map<uint32_t, InFlight> in_flight;  // batch id -> its tiles (the worker answers in order)
  bool source_empty = false;
  auto send_batch = [&]() {
    TileBatch b;
    b.id = next_batch_id_++;
    b.sample_begin = pass.sample_begin;
    b.sample_count = pass.sample_count;
    b.film_width = film.width();
    b.film_height = film.height();
    // As many tiles as the settings say, as long as the result stays under
    // the eager limit (mpi_channel.h): then it reaches rank 0 as soon as the
    // worker hands it over, not at the worker's next MPI call.
    Tile t;
    size_t result_bytes = 256;  // the header, generously
    while (b.tiles.size() < settings_.tiles_per_batch) {
      if (!b.tiles.empty() && result_bytes + result_bytes_of(b.tiles.back()) > kEagerResultBytes)
        break;
      if (!tiles.next(&t)) break;
      b.tiles.push_back(t);
      result_bytes += result_bytes_of(t);
    }
    if (b.tiles.empty()) {
      source_empty = true;
      return;
    }
    WireWriter w;
    encode_batch(b, w);
    fs.bytes_to_worker += w.bytes().size();
    ++fs.batches;
    // Not waited for either: a send completes only once the worker looks
    // at its messages, which it does between tiles.
    sends_.start(info_.rank, kTagBatch, std::move(w.bytes()));
    in_flight.emplace(b.id, InFlight{std::move(b.tiles)});
  };
  while (!source_empty && in_flight.size() < settings_.batches_in_flight)
    send_batch();
  while (!in_flight.empty()) {
    sends_.progress();
    Message m;
    if (!try_receive(info_.rank, &m)) m = wait_for_answer(in_flight.begin()->second, source_empty);
    if (m.tag == kTagError) {
      WireReader r(m.bytes, "error message of rank " + std::to_string(info_.rank));
      throw RankFailure(info_.rank, r.get_string());
    }
    if (m.tag != kTagResult) throw RankFailure(info_.rank, "sent an unexpected message");
    fs.bytes_from_worker += m.bytes.size();
    WireReader r(m.bytes, "result from rank " + std::to_string(info_.rank));
    const BatchResult res = decode_result(r);
    auto it = in_flight.find(res.id);
    if (it == in_flight.end() || it->second.tiles.size() != res.tiles.size() ||
        std::memcmp(it->second.tiles.data(), res.tiles.data(), res.tiles.size() * sizeof(Tile)) !=
            0)
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
    if (!res.tiles.empty() && res.busy_seconds > 0.0) {
      recent_seconds_per_tile_[recent_at_++ % recent_seconds_per_tile_.size()] =
          res.busy_seconds / double(res.tiles.size());
    }
    stats.rays += res.rays;
    stats.samples += res.samples;
    fs.worker_busy_seconds += res.busy_seconds;
    fs.worker_cpu_seconds += std::max(0.0, res.cpu_seconds - worker_cpu_);
    fs.worker_render_cpu_seconds += std::max(0.0, res.render_cpu_seconds - worker_render_cpu_);
    worker_cpu_ = res.cpu_seconds;
    worker_render_cpu_ = res.render_cpu_seconds;
  }
  // Every batch was answered, so the worker has taken every message: this
  // only completes the requests.
  sends_.drain(settings_.timeout_s);
  fs.driver_cpu_seconds += thread_cpu_seconds() - cpu_start;
  stats.commit_bytes = fs.scene_bytes;
  stats.seconds = seconds_since(start);
  last_ = fs;
  pending_ = PeerFrameStats{};
  return stats;
}

}  // namespace tandem::mpi
