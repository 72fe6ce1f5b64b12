// `tandem bench --scene SCENE --frames N`: the interactive frame loop
// measured along the scripted camera path (issue 6).
#pragma once

#include <string>
#include <vector>

namespace tandem {

// Whether `args` ask for the frame-loop benchmark (they contain --frames).
bool is_frame_bench(const std::vector<std::string>& args);
int run_frame_bench(const std::vector<std::string>& args);

}  // namespace tandem
