// The few MPI calls Tandem makes, behind one lock: rank 0 drives its peers
// from several threads (one per peer backend, as the core tracer renders
// every backend on its own thread), and MPI_THREAD_SERIALIZED is what every
// Open MPI build supports. Every wait is a poll (MPI_Test / MPI_Iprobe with
// sleeps in between that start at 20 us and double, so waiting costs next to
// no CPU) against a deadline, so a peer that stops answering ends the run
// instead of hanging it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tandem::mpi {

// A rank failed or stopped answering. The message names the rank and the
// reason; the run ends with exit status 1 on every rank.
class RankFailure : public std::runtime_error {
 public:
  RankFailure(int rank, const std::string& reason)
      : std::runtime_error("rank " + std::to_string(rank) + ": " + reason), rank_(rank) {}
  int rank() const { return rank_; }

 private:
  int rank_;
};

// Messages up to this size travel without their sender's help, once sent
// (Open MPI's shared-memory eager limit is raised to it): a worker's result
// message should fit (MpiPeerBackend sizes its batches by it).
inline constexpr size_t kEagerResultBytes = 64 * 1024;

// MPI_Init_thread once per process; later calls return at once. From then
// on, a process that leaves without finalize() (an error on any rank) calls
// MPI_Abort at exit, which ends every rank: nothing waits for a dead peer.
void initialize();
// MPI_Finalize (every rank, after the shutdown messages).
void finalize();
bool initialized();
int rank();
int size();
// Ends every rank now with `code`.
[[noreturn]] void abort_all(int code);

// The bounded wait for a peer's answer: TANDEM_MPI_TIMEOUT seconds
// (default 60). Throws InputError for a value that is not a positive number.
double answer_timeout_seconds();

struct Message {
  int source = -1, tag = 0;
  std::vector<uint8_t> bytes;
};

// Sends and waits until the buffer may be reused; RankFailure after
// `timeout_s` (<= 0: no limit).
void send(int dest, int tag, const std::vector<uint8_t>& bytes, double timeout_s);
// A message from `source` if one has arrived (any tag).
bool try_receive(int source, Message* out);
// Waits for a message from `source`; RankFailure after `timeout_s` seconds
// of silence (<= 0: no limit), naming `waiting_for`. `idle` runs between
// polls (a worker completes its outstanding sends there). Polls sleep in
// between, `first_nap_us` at first and twice as long each time up to
// `max_nap_us`: the defaults see an answer that is nearly there at once and
// wake about a thousand times a second during a long wait; a caller for
// whom a late answer costs nothing may nap longer.
Message receive(int source, double timeout_s, const std::string& waiting_for,
                const std::function<void()>& idle = {}, int first_nap_us = 20,
                int max_nap_us = 1000);

// Sends whose buffers are kept until MPI is done with them, so that a worker
// can go on rendering while its results travel. progress() must be called
// now and then (Open MPI moves large messages only inside MPI calls).
class PendingSends {
 public:
  PendingSends() = default;
  PendingSends(const PendingSends&) = delete;
  PendingSends& operator=(const PendingSends&) = delete;
  ~PendingSends();
  void start(int dest, int tag, std::vector<uint8_t> bytes);
  void progress();
  // Waits for all of them; RankFailure after `timeout_s`.
  void drain(double timeout_s);
  bool empty() const { return sends_.empty(); }

 private:
  struct Send;
  std::vector<Send*> sends_;
};

}  // namespace tandem::mpi
