#include "core/util/interrupt.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstring>

namespace tandem {

namespace {

// Only async-signal-safe state: the handler reads these and calls unlink,
// signal and raise, nothing else.
volatile std::sig_atomic_t g_graceful = 0;
volatile std::sig_atomic_t g_signal = 0;
volatile std::sig_atomic_t g_temp_set = 0;
char g_temp[4096];

extern "C" void on_signal(int sig) {
  if (g_graceful && g_signal == 0) {
    g_signal = sig;
    return;
  }
  if (g_temp_set) ::unlink(g_temp);
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

}  // namespace

void install_interrupt_handlers() {
  static bool installed = false;
  if (installed) return;
  installed = true;
  for (int sig : {SIGINT, SIGTERM}) {
    struct sigaction old = {};
    if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    struct sigaction sa = {};
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    ::sigaction(sig, &sa, nullptr);
  }
}

GracefulStop::GracefulStop() {
  g_signal = 0;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  g_graceful = 1;
}
GracefulStop::~GracefulStop() {
  g_graceful = 0;
}
bool GracefulStop::requested() const {
  return g_signal != 0;
}
int GracefulStop::signal() const {
  return g_signal;
}

TempFileRegistration::TempFileRegistration(const char* path) {
  g_temp_set = 0;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  const size_t n = std::min(std::strlen(path), sizeof g_temp - 1);
  std::memcpy(g_temp, path, n);
  g_temp[n] = '\0';
  std::atomic_signal_fence(std::memory_order_seq_cst);
  g_temp_set = n == std::strlen(path) ? 1 : 0;  // a truncated name must not be unlinked
}
TempFileRegistration::~TempFileRegistration() {
  g_temp_set = 0;
}

const char* signal_name(int sig) {
  if (sig == SIGINT) return "SIGINT";
  if (sig == SIGTERM) return "SIGTERM";
  return "a signal";
}

}  // namespace tandem
