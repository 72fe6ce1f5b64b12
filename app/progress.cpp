#include "app/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <string>

namespace tandem {

bool stderr_is_terminal() {
  return ::isatty(STDERR_FILENO) == 1;
}

ProgressBar::ProgressBar(bool enabled)
    : enabled_(enabled), start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() {
  finish();
}

void ProgressBar::update(double fraction) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  fraction = std::clamp(fraction, 0.0, 1.0);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  constexpr int kWidth = 30;
  const int filled = int(fraction * kWidth + 0.5);
  std::string bar(size_t(filled), '#');
  bar.resize(kWidth, '.');
  char eta[32] = "";
  if (fraction > 0.02 && fraction < 1.0) {
    std::snprintf(eta, sizeof eta, "  eta %.0fs", elapsed * (1.0 - fraction) / fraction);
  }
  std::fprintf(stderr, "\r[%s] %3d%%  %.1fs%s   ", bar.c_str(), int(fraction * 100.0 + 0.5),
               elapsed, eta);
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (enabled_ && drawn_) {
    std::fprintf(stderr, "\r%*s\r", 60, "");
    std::fflush(stderr);
  }
  drawn_ = false;
}

}  // namespace tandem
