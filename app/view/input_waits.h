// How long input waited to be read: the time between successive reads of
// the event queue, through renders, denoising and presenting alike. The
// viewer's promise is that no key waits more than about 50 ms, whatever the
// frame costs; `tandem-view --stats` and `bench --frames` report these.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace tandem {

class InputWaits {
 public:
  // The queue was read at `time` (seconds, non-decreasing).
  void polled(double time) {
    if (have_last_) {
      const double gap = time - last_;
      max_ = std::max(max_, gap);
      if (gaps_.size() < kKept) gaps_.push_back(gap);
    }
    last_ = time;
    have_last_ = true;
  }
  // The next read starts afresh (time spent on something else than the
  // loop, such as a reference render, is not a wait).
  void pause() { have_last_ = false; }
  double max_ms() const { return max_ * 1e3; }
  // The 99th percentile of the gaps (the first kKept of them).
  double p99_ms() const {
    if (gaps_.empty()) return 0.0;
    std::vector<double> v = gaps_;
    const size_t i = std::min(v.size() - 1, size_t(0.99 * double(v.size() - 1) + 0.5));
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(i), v.end());
    return v[i] * 1e3;
  }
  size_t count() const { return gaps_.size(); }

 private:
  static constexpr size_t kKept = 1 << 20;
  std::vector<double> gaps_;
  double last_ = 0.0, max_ = 0.0;
  bool have_last_ = false;
};

}  // namespace tandem
