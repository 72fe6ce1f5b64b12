#include "backends/mpi/mpi_channel.h"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>

#include "core/util/errors.h"

namespace tandem::mpi {

namespace {

std::mutex& mpi_lock() {
  static std::mutex m;
  return m;
}

bool g_initialized = false;
bool g_finalized = false;

using Clock = std::chrono::steady_clock;

// The sleep between two polls of one wait. MPI's own blocking calls spin
// a core at 100%, and so would a loop of tests; every wake-up also preempts
// a renderer when a machine runs as many renderers as it has cores. The
// first naps are short, so an answer that is nearly there costs little
// latency, and each doubles up to a cap, so that a long wait (a worker
// between frames, rank 0 waiting for a batch) wakes about a thousand times
// a second at most.
class Backoff {
 public:
  Backoff() = default;
  Backoff(int first_us, int max_us)
      : max_(std::clamp(max_us, 1, 1000000)), step_(std::clamp(first_us, 1, int(max_.count()))) {}
  // Never past the wait's deadline (`timeout_s` after `start`; <= 0: none),
  // so a peer that stopped answering is named as soon as before.
  void nap(Clock::time_point start, double timeout_s) {
    auto sleep = step_;
    if (timeout_s > 0.0) {
      const auto left = std::chrono::duration_cast<std::chrono::microseconds>(
          start + std::chrono::duration<double>(timeout_s) - Clock::now());
      sleep = std::clamp(left + std::chrono::microseconds(1), std::chrono::microseconds(1), sleep);
    }
    std::this_thread::sleep_for(sleep);
    step_ = std::min(step_ * 2, max_);
  }

 private:
  std::chrono::microseconds max_{1000};
  std::chrono::microseconds step_{20};
};

void abort_if_unfinished() {
  // An error left main() on this rank: the others may be waiting for it.
  if (g_initialized && !g_finalized) {
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
}

bool past(Clock::time_point start, double timeout_s) {
  return timeout_s > 0.0 && std::chrono::duration<double>(Clock::now() - start).count() > timeout_s;
}

std::string seconds_text(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g s", s);
  return buf;
}

}  // namespace

void initialize() {
  std::lock_guard<std::mutex> lock(mpi_lock());
  if (g_initialized) return;
  // A worker makes no MPI call while it renders a tile, and Open MPI's
  // shared-memory transport moves a message above its eager limit (4 KiB by
  // default) only inside MPI calls of the sender when it cannot map the
  // other process's memory (containers: single_copy_mechanism=none). A
  // batch's sums (48 KiB for two 32x32 tiles) would then wait for the
  // worker's next tile boundary while rank 0 polls for them; below this
  // limit they are copied out when the worker hands them over. Not set
  // when the user chose a value (mpirun --mca or the environment).
  setenv("OMPI_MCA_btl_vader_eager_limit", std::to_string(kEagerResultBytes).c_str(), 0);
  int provided = 0;
  if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
    throw InputError("--distributed: MPI could not be initialized");
  g_initialized = true;
  std::atexit(abort_if_unfinished);
  if (provided < MPI_THREAD_SERIALIZED) {
    throw InputError(
        "--distributed: this MPI library does not allow calls from several threads "
        "(MPI_THREAD_SERIALIZED)");
  }
}

void finalize() {
  std::lock_guard<std::mutex> lock(mpi_lock());
  if (!g_initialized || g_finalized) return;
  MPI_Finalize();
  g_finalized = true;
}

bool initialized() {
  return g_initialized && !g_finalized;
}

int rank() {
  std::lock_guard<std::mutex> lock(mpi_lock());
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int size() {
  std::lock_guard<std::mutex> lock(mpi_lock());
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

void abort_all(int code) {
  std::fflush(stderr);
  std::fflush(stdout);
  MPI_Abort(MPI_COMM_WORLD, code);
  std::_Exit(code);  // not reached
}

double answer_timeout_seconds() {
  const char* v = std::getenv("TANDEM_MPI_TIMEOUT");
  if (!v || !*v) return 60.0;
  char* end = nullptr;
  const double s = std::strtod(v, &end);
  if (*end != '\0' || !(s > 0.0) || s > 1e9)
    throw InputError(std::string("TANDEM_MPI_TIMEOUT must be a number of seconds > 0, got '") + v +
                     "'");
  return s;
}

// Tests `request` until it completes, napping between tests; past the
// bound, `rank` is the one that failed, for the reason `failure()` gives.
template <class Failure>
void wait_for_request(MPI_Request& request, int rank, double timeout_s, Failure failure) {
  const auto start = Clock::now();
  Backoff backoff;
  for (;;) {
    int done = 0;
    {
      std::lock_guard<std::mutex> lock(mpi_lock());
      MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    }
    if (done) return;
    if (past(start, timeout_s)) throw RankFailure(rank, failure());
    backoff.nap(start, timeout_s);
  }
}

void send(int dest, int tag, const std::vector<uint8_t>& bytes, double timeout_s) {
  MPI_Request request;
  {
    std::lock_guard<std::mutex> lock(mpi_lock());
    MPI_Isend(bytes.data(), int(bytes.size()), MPI_BYTE, dest, tag, MPI_COMM_WORLD, &request);
  }
  wait_for_request(request, dest, timeout_s, [&] {
    return "did not take a message within " + seconds_text(timeout_s) + " (stopped answering)";
  });
}

bool try_receive(int source, Message* out) {
  MPI_Request request;
  {
    std::lock_guard<std::mutex> lock(mpi_lock());
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(source, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
    if (!flag) return false;
    int count = 0;
    MPI_Get_count(&status, MPI_BYTE, &count);
    out->source = status.MPI_SOURCE;
    out->tag = status.MPI_TAG;
    out->bytes.resize(size_t(count));
    MPI_Irecv(out->bytes.data(), count, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD,
              &request);
  }
  // A large message arrives only as fast as its sender lets MPI move it (a
  // worker between two tiles): wait without holding the lock, so the other
  // peers' threads go on meanwhile. Bounded like every other wait.
  const double timeout_s = answer_timeout_seconds();
  wait_for_request(request, out->source, timeout_s, [&] {
    return "stopped answering in the middle of a message (" + seconds_text(timeout_s) + ")";
  });
  return true;
}

Message receive(int source, double timeout_s, const std::string& waiting_for,
                const std::function<void()>& idle, int first_nap_us, int max_nap_us) {
  Message m;
  const auto start = Clock::now();
  Backoff backoff(first_nap_us, max_nap_us);
  while (!try_receive(source, &m)) {
    if (idle) idle();
    if (past(start, timeout_s))
      throw RankFailure(source, "did not answer within " + seconds_text(timeout_s) +
                                    " (waiting for " + waiting_for + ")");
    backoff.nap(start, timeout_s);
  }
  return m;
}

struct PendingSends::Send {
  std::vector<uint8_t> bytes;
  MPI_Request request;
  int dest;
};

PendingSends::~PendingSends() {
  // Only reached with sends outstanding when the run is ending on an error
  // (MPI_Abort follows); the buffers must outlive the requests.
  if (!sends_.empty() && initialized()) return;  // leaked on purpose
  for (Send* s : sends_)
    delete s;
}

void PendingSends::start(int dest, int tag, std::vector<uint8_t> bytes) {
  auto* s = new Send{std::move(bytes), MPI_REQUEST_NULL, dest};
  {
    std::lock_guard<std::mutex> lock(mpi_lock());
    MPI_Isend(s->bytes.data(), int(s->bytes.size()), MPI_BYTE, dest, tag, MPI_COMM_WORLD,
              &s->request);
  }
  sends_.push_back(s);
}

void PendingSends::progress() {
  std::lock_guard<std::mutex> lock(mpi_lock());
  for (size_t i = 0; i < sends_.size();) {
    int done = 0;
    MPI_Test(&sends_[i]->request, &done, MPI_STATUS_IGNORE);
    if (done) {
      delete sends_[i];
      sends_.erase(sends_.begin() + std::ptrdiff_t(i));
    } else {
      ++i;
    }
  }
}

void PendingSends::drain(double timeout_s) {
  const auto start = Clock::now();
  Backoff backoff;
  for (;;) {
    progress();
    if (sends_.empty()) return;
    if (past(start, timeout_s))
      throw RankFailure(sends_.front()->dest,
                        "did not take a message within " + seconds_text(timeout_s));
    backoff.nap(start, timeout_s);
  }
}

}  // namespace tandem::mpi
