// `tandem bench [SCENE] --light-sampling`: the two light samplers
// (--light-sampler power|tree) rendering the same scene for the same time,
// each one's relative MSE against a converged reference, the speed-up in
// time to equal noise, and what the light tree costs to build and hold.
#pragma once

#include <string>
#include <vector>

namespace tandem {

// Whether `args` ask for this benchmark (they contain --light-sampling).
bool is_light_sampling_bench(const std::vector<std::string>& args);
int run_light_sampling_bench(const std::vector<std::string>& args);

}  // namespace tandem
