// The `--distributed` hooks of `tandem render` and `tandem bench`, free of
// MPI types so the commands compile the same with and without MPI
// (TANDEM_HAVE_MPI). Run under `mpirun -np N`: rank 0 reads the scene,
// renders with its own backends plus one peer backend per other rank, and
// writes the output; the other ranks serve tiles and print only errors.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/backend_factory.h"
#include "core/render/backend.h"

namespace tandem {

// Whether this build has distributed rendering.
bool distributed_built_in();

// Starts MPI. On a worker rank, serves rank 0 with the backends of
// `backend_spec` (created on this machine: `auto` is its GPU if it has one)
// and returns the exit status once the run ends; on rank 0 returns -1 (go
// on). Throws InputError naming `command` in a build without MPI.
int start_distributed(const std::string& command, const std::string& backend_spec,
                      const BackendOptions& options);

// On rank 0: appends one backend per worker rank to `backends`.
void add_distributed_peers(std::vector<std::unique_ptr<Backend>>& backends);

// On rank 0 after the output is written: ends the run on every rank.
void finish_distributed();

// `tandem bench --distributed ...` (app/bench/bench_distributed.cpp).
int run_distributed_bench(const std::vector<std::string>& args);

}  // namespace tandem
