// What the scene looked like one frame ago, for motion vectors: the camera
// and every instance's object-to-world transform as of the previous feature
// pass. Kept beside the compiled scene rather than in it so that the scene
// compiler and the kernel arrays stay as they are; instances keep their
// indices from frame to frame, which is all the matching needs.
#pragma once

#include <vector>

#include "core/kernel/features.h"

namespace tandem {

class MotionHistory {
 public:
  // The FeaturePass for a frame of `kd`, measuring motion from the frame of
  // the previous advance() (no motion on the first call or after reset()),
  // and remembers `kd`'s camera and transforms for the next call. The pass
  // points into this object: valid until the next advance() or reset().
  FeaturePass advance(const KernelData& kd);
  void reset() { has_last_ = false; }

 private:
  bool has_last_ = false;
  KCamera last_camera_{};
  std::vector<Mat34> last_, prev_;
};

}  // namespace tandem
