// `tandem bench --hetero LIST`: the core tracer's frame loop with every
// backend of LIST alone and with all of them together, same scene, same
// frames, in one run.
#pragma once

#include <string>

#include "app/json_writer.h"
#include "backends/backend_factory.h"
#include "core/world/kernel_scene.h"
#include "core/world/scene.h"

namespace tandem {

// Prints the figures; returns them for the JSON report.
JsonValue run_hetero_bench(Scene& scene, const RenderSettings& settings, uint32_t frames,
                           const std::string& list, const BackendOptions& options = {});

}  // namespace tandem
