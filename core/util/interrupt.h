// SIGINT / SIGTERM for the command-line tools: stop cleanly, never leave a
// half-written temporary file behind.
#pragma once

namespace tandem {

// Installs the handlers (once; a signal the parent made us ignore stays
// ignored). Outside a GracefulStop a signal removes the registered
// temporary file, if any, and then ends the process as the signal would.
void install_interrupt_handlers();

// While one is alive, the first SIGINT/SIGTERM only sets a flag that the
// work loop polls between steps; a second one ends the process at once.
class GracefulStop {
 public:
  GracefulStop();
  ~GracefulStop();
  GracefulStop(const GracefulStop&) = delete;
  GracefulStop& operator=(const GracefulStop&) = delete;
  bool requested() const;
  int signal() const;  // the signal that asked to stop, 0 if none
};

// Names a temporary file for the handler to remove if a signal arrives
// while it exists (one at a time: writes are not nested).
class TempFileRegistration {
 public:
  explicit TempFileRegistration(const char* path);
  ~TempFileRegistration();
  TempFileRegistration(const TempFileRegistration&) = delete;
  TempFileRegistration& operator=(const TempFileRegistration&) = delete;
};

// "SIGINT", "SIGTERM", or "signal N".
const char* signal_name(int signal);

}  // namespace tandem
