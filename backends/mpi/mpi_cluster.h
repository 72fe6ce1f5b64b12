// Distributed rendering over MPI: what `--distributed` runs on each rank.
//
// Rank 0 runs the core tracer as in a single process; every other rank is a
// worker that renders tiles with its own local backends and is represented
// on rank 0 by an MpiPeerBackend. A run starts with a handshake (every
// worker sends its build fingerprint and its backends; a mismatch ends the
// run) and ends with rank 0's shutdown message. Any failure ends the run on
// every rank with exit status 1 (mpi_channel.h).
//
// Fault injection for the tests: TANDEM_MPI_FAULT=KIND@RANK makes worker
// RANK fail at its first tile batch: `throw` (an exception in its
// renderer), `oom` (std::bad_alloc), `hang` (stops answering), `exit` (the
// process ends), or at the handshake: `version` (reports another protocol).
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "backends/mpi/mpi_peer_backend.h"
#include "core/render/backend.h"

namespace tandem::mpi {

enum class FaultKind { kNone, kThrow, kOom, kHang, kExit, kVersion };
struct Fault {
  FaultKind kind = FaultKind::kNone;
  int rank = -1;
};
// Parses TANDEM_MPI_FAULT (unset or empty: none); InputError otherwise.
Fault parse_fault(const char* text);

// Initializes MPI (once per process) and returns this rank.
int start();
int rank_count();

// On a worker rank: creates the local backends with `make_backends` (what
// `--backend` says; a failure is reported to rank 0), answers the handshake,
// then renders what rank 0 sends until it shuts the run down. Returns the
// exit status.
int serve_as_worker(const std::function<std::vector<std::unique_ptr<Backend>>()>& make_backends);

// On rank 0: waits for every worker's handshake (bounded), checks their
// builds, and returns one peer backend per worker (the first call; later
// calls make fresh peers of the same workers, which resend the scene).
std::vector<std::unique_ptr<MpiPeerBackend>> connect_peers();

// On rank 0, after the last frame: tells the workers to leave and finalizes
// MPI. Without it (an error), leaving the process ends every rank.
void finish();

}  // namespace tandem::mpi
