// Rank 0's stand-in for one worker rank: a Backend like the local ones, so
// the core tracer syncs it, hands it tiles through its TileSource and learns
// its throughput (and lets it steal) like any other.
//
//   sync()   sends the scene the first time, then only the frame's changed
//            kernel-array ranges (mpi_protocol.h);
//   render() pulls tiles from the source into small batches, keeps several
//            batches in flight so the worker never waits for the network,
//            and adds the returned sums to the film.
//
// Neither waits for a send to complete (the worker takes messages between
// tiles), and render() polls for answers as rarely as their pace allows: on
// a machine with as many renderers as cores, this thread's wake-ups come out
// of a renderer's time.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "backends/mpi/mpi_channel.h"
#include "backends/mpi/mpi_protocol.h"
#include "core/render/backend.h"

namespace tandem::mpi {

// What a worker said about itself in the handshake.
struct WorkerInfo {
  int rank = 0;
  std::string backends;  // its local backends, e.g. "cpu" or "cuda"
  bool needs_bvh = false;
};

// Traffic and work of one render() (and the syncs before it).
struct PeerFrameStats {
  uint64_t bytes_to_worker = 0;    // scene deltas + tile batches
  uint64_t bytes_from_worker = 0;  // results
  uint64_t scene_bytes = 0;        // of bytes_to_worker: scene deltas
  double worker_busy_seconds = 0;  // inside the worker's own backends
  // The worker's process CPU time since its previous frame's last result (its
  // waiting between frames included), and the part inside its backends
  // (rendering and syncing the scene).
  double worker_cpu_seconds = 0, worker_render_cpu_seconds = 0;
  // CPU time of the rank 0 thread that drives this worker (render()).
  double driver_cpu_seconds = 0;
  double sync_seconds = 0;  // rank 0 sending the scene delta
  uint32_t batches = 0;
};

struct PeerSettings {
  uint32_t tiles_per_batch = 2;
  // Batches sent ahead: while the worker renders one, the next waits in its
  // queue and the previous one's sums travel back.
  uint32_t batches_in_flight = 3;
  double timeout_s = 60.0;
};

class MpiPeerBackend final : public Backend {
 public:
  MpiPeerBackend(WorkerInfo info, PeerSettings settings);
  std::string name() const override;
  BackendTraits traits() const override;
  void sync(const KernelScene& scene, const SceneDelta& delta) override;
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override;

  const WorkerInfo& info() const { return info_; }
  // Of the last render() and the syncs before it.
  const PeerFrameStats& last_frame() const { return last_; }

 private:
  struct InFlight {
    std::vector<Tile> tiles;
  };
  // Waits for the worker's next answer; `oldest` is its oldest batch in
  // flight, `last_batches`: the frame has no more tiles to send.
  Message wait_for_answer(const InFlight& oldest, bool last_batches);

  WorkerInfo info_;
  PeerSettings settings_;
  ArrayCounts receiver_counts_{};
  bool reset_sent_ = false;
  uint32_t next_batch_id_ = 0;
  // The worker's CPU counters (since the reset) at its last result.
  double worker_cpu_ = 0, worker_render_cpu_ = 0;
  // The worker's time per tile in its last batches: when its next answer
  // is due (the fastest of them, as tiles' costs differ).
  std::array<double, 4> recent_seconds_per_tile_{};
  size_t recent_at_ = 0;
  // Resets, scene deltas and batches on their way to the worker.
  PendingSends sends_;
  PeerFrameStats pending_{}, last_{};
};

}  // namespace tandem::mpi
