// The one way the commands (render, bench in both modes, info, tandem-view)
// turn their SCENE argument and the scene and environment options into a
// Scene, so that a glTF file looks the same in every one of them.
//
// The environment rule: --env FILE or --env-color RGB set the environment.
// Without either, a glTF scene (which has no sky of its own) is lit by the
// default sky built into the binary (data/env/sky.hdr, embedded at build
// time), announced once on stderr with how to turn it off (--env-color 0);
// built-in scenes keep their own lighting. --env-intensity and
// --env-rotation apply to whichever environment results.
#pragma once

#include <optional>
#include <string>

#include "app/cli_args.h"
#include "core/world/scene.h"
#include "scenes/scene_loader.h"

namespace tandem {

struct EnvironmentRequest {
  std::optional<std::string> map;         // --env
  std::optional<glm::vec3> color;         // --env-color
  std::optional<float> intensity;         // --env-intensity
  std::optional<float> rotation_degrees;  // --env-rotation
};

struct SceneRequest {
  std::string spec;  // builtin:NAME or a .gltf/.glb path
  SceneLoadOptions load;
  EnvironmentRequest environment;
  // Apply the environment rule above (false for `tandem info`, which
  // renders nothing).
  bool default_environment = true;
};

// Reads the scene_options() and environment_options() of `args` (either
// group may be absent from the command's table): every usage error now,
// before anything is loaded.
SceneRequest parse_scene_request(const ParsedArgs& args, const std::string& spec);

// Parses an --env-color value ("0.5" or "0.2,0.3,0.4"); `command` prefixes
// the usage error.
glm::vec3 parse_env_color(const std::string& text, const std::string& command);

// Whether `request` gets the default sky (a glTF file, no --env/--env-color).
bool uses_default_environment(const SceneRequest& request);

// Loads the scene and sets its environment as described above. `program`
// ("tandem", "tandem-view") prefixes the one-line notice of the default sky.
// Throws InputError naming the file and the reason.
Scene load_requested_scene(const SceneRequest& request, const std::string& program);

}  // namespace tandem
