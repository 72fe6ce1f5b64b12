// `tandem bench [SCENE] --denoise-quality`: the temporal denoiser measured
// along the scripted camera path (default builtin:arena, 640x360, 1 spp per
// frame) against references of the same frozen frames.
#pragma once

#include <string>
#include <vector>

namespace tandem {

// Whether `args` ask for this benchmark (they contain --denoise-quality).
bool is_denoise_quality_bench(const std::vector<std::string>& args);
int run_denoise_quality_bench(const std::vector<std::string>& args);

}  // namespace tandem
