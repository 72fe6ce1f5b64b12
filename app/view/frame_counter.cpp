#include "app/view/frame_counter.h"

#include <cstddef>

namespace tandem {

void FrameCounter::presented(double time, double render_seconds) {
  frames_.push_back({time, render_seconds});
  // Keep one frame older than the window as the start of the first interval.
  while (frames_.size() > 2 && time - frames_[1].time > window_)
    frames_.pop_front();
}

double FrameCounter::fps() const {
  if (frames_.size() < 2) return 0.0;
  const double span = frames_.back().time - frames_.front().time;
  return span > 0.0 ? double(frames_.size() - 1) / span : 0.0;
}

double FrameCounter::ms_per_rendered_frame() const {
  double sum = 0.0;
  int n = 0;
  // The intervals fps() counts: every frame after the first.
  for (std::size_t i = frames_.size() > 1 ? 1 : 0; i < frames_.size(); ++i) {
    if (frames_[i].render_seconds <= 0.0) continue;
    sum += frames_[i].render_seconds;
    ++n;
  }
  return n > 0 ? sum / n * 1e3 : 0.0;
}

}  // namespace tandem
