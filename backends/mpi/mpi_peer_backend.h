// Rank 0's stand-in for one worker rank: a Backend like the local ones, so
// the core tracer syncs it, hands it tiles through its TileSource and learns
// its throughput (and lets it steal) like any other.
//
//   sync()   sends the scene the first time, then only the frame's changed
//            kernel-array ranges (mpi_protocol.h);
//   render() pulls tiles from the source into small batches, keeps several
//            batches in flight so the worker never waits for the network,
//            and adds the returned sums to the film.
#pragma once

#include <string>

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
  double sync_seconds = 0;         // rank 0 sending the scene delta
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
  WorkerInfo info_;
  PeerSettings settings_;
  ArrayCounts receiver_counts_{};
  bool reset_sent_ = false;
  uint32_t next_batch_id_ = 0;
  PeerFrameStats pending_{}, last_{};
};

}  // namespace tandem::mpi
