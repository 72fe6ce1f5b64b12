#include "app/distributed.h"

#include "app/backend_list.h"
#include "core/util/errors.h"
#include "core/util/log.h"

#if TANDEM_HAVE_MPI
#include "backends/mpi/mpi_cluster.h"
#endif

namespace tandem {

bool distributed_built_in() {
  return TANDEM_HAVE_MPI != 0;
}

#if TANDEM_HAVE_MPI

int start_distributed(const std::string& command, const std::string& backend_spec,
                      const BackendOptions& options) {
  if (mpi::start() == 0) return -1;
  // Workers print nothing but errors (rank 0 speaks for the run): no
  // warnings such as the CPU fallback notice of every rank without a GPU.
  set_log_level(LogLevel::kQuiet);
  return mpi::serve_as_worker([&] { return make_backend_list(backend_spec, options); });
}

void add_distributed_peers(std::vector<std::unique_ptr<Backend>>& backends) {
  for (auto& peer : mpi::connect_peers())
    backends.push_back(std::move(peer));
}

void finish_distributed() {
  mpi::finish();
}

#else

int start_distributed(const std::string& command, const std::string&, const BackendOptions&) {
  throw InputError(command +
                   " --distributed: distributed rendering is not built in (this tandem was "
                   "configured without MPI; install libopenmpi-dev and reconfigure)");
}

void add_distributed_peers(std::vector<std::unique_ptr<Backend>>&) {}
void finish_distributed() {}

int run_distributed_bench(const std::vector<std::string>&) {
  return start_distributed("bench", "", {});
}

#endif

}  // namespace tandem
