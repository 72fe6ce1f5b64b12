// The option groups that several commands share, declared once so that
// `tandem render`, `tandem bench` (both modes), `tandem info` and
// `tandem-view` spell, describe and default them alike. A command composes
// its table with compose_options() and may replace a spec of a group (its
// own default or wording) by listing one of the same name after it.
#pragma once

#include <cstdint>
#include <string>

#include "app/cli_args.h"

namespace tandem {

enum class LightSampler : uint8_t;  // core/world/kernel_scene.h

// "0.1.0": the project version, for --version.
const char* tandem_version();

// --help (and -h).
OptionGroup help_options();

// --gltf-scene, --allow-outside-uris: which scene of a file, and where its
// URIs may point. Read by parse_scene_request() (app/scene_setup.h).
OptionGroup scene_options();

// --env, --env-color, --env-intensity, --env-rotation. Without --env or
// --env-color a glTF scene gets the default sky (app/scene_setup.h).
OptionGroup environment_options();

// --width, --height with the command's defaults.
OptionGroup image_size_options(const std::string& width_default, const std::string& height_default);

// --max-depth with the command's default.
OptionGroup path_depth_options(const std::string& depth_default);

// --backend (a single kind, or with `allow_lists` a list such as cpu+host)
// and --kernel.
OptionGroup backend_options(bool allow_lists);

// --light-sampler power|tree (core/kernel/lights.h), defaulting to
// RenderSettings' sampler; parse_light_sampler() reads it.
OptionGroup light_sampler_options();
LightSampler parse_light_sampler(const ParsedArgs& args);

// --threads.
OptionGroup thread_options();

// --json FILE for the benchmarks.
OptionGroup json_report_options();

// --exposure (and with `tone_curve` --tonemap) for 8-bit output.
OptionGroup display_options(bool tone_curve);

}  // namespace tandem
