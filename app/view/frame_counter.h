// The viewer's frame-rate readout. Both figures come from the caller's one
// steady clock over the same sliding window: frames presented per second
// (present to present), and the mean time spent rendering a frame (a
// converged still image that is only presented again adds no render time).
// The first frame alone says nothing about a rate: fps() stays 0 until two
// frames were presented.
#pragma once

#include <deque>

namespace tandem {

class FrameCounter {
 public:
  explicit FrameCounter(double window_seconds = 1.0) : window_(window_seconds) {}

  // A frame was presented at `time` (seconds, non-decreasing) after
  // `render_seconds` of rendering (0: it was not rendered again).
  void presented(double time, double render_seconds);
  double fps() const;
  double ms_per_rendered_frame() const;
  void reset() { frames_.clear(); }

 private:
  struct Frame {
    double time, render_seconds;
  };
  double window_;
  std::deque<Frame> frames_;
};

}  // namespace tandem
