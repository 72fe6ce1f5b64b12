// `tandem bench [SCENE...] --deform`: what deforming meshes cost per frame
// on the CPU: the skinning and morphing itself (SceneAnimator::pose), then
// SyncScene + UpdateAccStruc for the moved vertices (SceneSync::update: the
// compile and the BLAS refits), and the bytes the frame's delta would
// commit to a GPU.
#pragma once

#include <string>
#include <vector>

namespace tandem {

// Whether `args` ask for this benchmark (they contain --deform).
bool is_deform_bench(const std::vector<std::string>& args);
int run_deform_bench(const std::vector<std::string>& args);

}  // namespace tandem
