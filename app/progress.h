// A one-line progress bar on stderr, drawn only when stderr is a terminal
// (so logs and pipes stay clean).
#pragma once

#include <chrono>
#include <mutex>

namespace tandem {

class ProgressBar {
 public:
  explicit ProgressBar(bool enabled);
  ~ProgressBar();
  void update(double fraction);
  void finish();
  bool enabled() const { return enabled_; }

 private:
  bool enabled_;
  bool drawn_ = false;
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_;
};

// True when stderr is an interactive terminal.
bool stderr_is_terminal();

}  // namespace tandem
