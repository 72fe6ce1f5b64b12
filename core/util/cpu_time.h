// CPU time of this process and of the calling thread, in seconds. The
// benches report them next to wall time: on a machine shared with other
// work wall time swells, CPU time does not (and an MPI rank whose CPU time
// exceeds its rendering time is spending cores on something else: waiting
// that spins, packing, copying).
#pragma once

#include <time.h>

namespace tandem {

inline double cpu_clock_seconds(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return double(ts.tv_sec) + double(ts.tv_nsec) * 1e-9;
}
inline double process_cpu_seconds() {
  return cpu_clock_seconds(CLOCK_PROCESS_CPUTIME_ID);
}
inline double thread_cpu_seconds() {
  return cpu_clock_seconds(CLOCK_THREAD_CPUTIME_ID);
}

}  // namespace tandem
