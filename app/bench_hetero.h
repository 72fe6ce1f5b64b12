// `tandem bench --hetero LIST`: the core tracer's frame loop with every
// backend of LIST alone and with all of them together, same scene, same
// frames, in one run (issue 5's benchmark).
#pragma once

#include <string>

#include "core/scene/kernel_scene.h"
#include "core/scene/scene.h"

namespace tandem {

void run_hetero_bench(Scene& scene, const RenderSettings& settings, uint32_t frames,
                      const std::string& list);

}  // namespace tandem
