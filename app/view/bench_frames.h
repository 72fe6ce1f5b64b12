// `tandem bench --scene SCENE --frames N`: the interactive frame loop
// measured along the scripted camera path.
#pragma once

#include <string>
#include <vector>

#include "app/cli_args.h"

namespace tandem {

// Whether `args` ask for the frame-loop benchmark (they contain --frames).
bool is_frame_bench(const std::vector<std::string>& args);
int run_frame_bench(const std::vector<std::string>& args);
// Its options (for `tandem bench --help`).
const std::vector<OptionSpec>& frame_bench_options();

}  // namespace tandem
