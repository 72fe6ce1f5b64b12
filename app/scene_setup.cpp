#include "app/scene_setup.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>

#include "core/image/image.h"
#include "core/util/activity.h"
#include "core/util/errors.h"

namespace tandem {

namespace {

// Radiance is accumulated in float over many samples: a colour times an
// intensity near float's range becomes infinity and renders black. 1e30
// leaves room for the sums of any realistic number of samples.
constexpr double kMaxEnvironmentRadiance = 1e30;

void check_environment_radiance(const glm::vec3& color, float intensity,
                                const std::string& command) {
  for (int k = 0; k < 3; ++k) {
    const double radiance = double(color[k]) * double(intensity);
    if (radiance > kMaxEnvironmentRadiance) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    ": --env-color %g times --env-intensity %g is %g, beyond the largest "
                    "radiance that can be rendered (%g)",
                    double(color[k]), double(intensity), radiance, kMaxEnvironmentRadiance);
      throw UsageError(command + buf);
    }
  }
}

bool is_builtin(const std::string& spec) {
  return spec.rfind("builtin:", 0) == 0;
}

}  // namespace

glm::vec3 parse_env_color(const std::string& text, const std::string& command) {
  std::vector<float> values;
  // split_list keeps empty items, so "1,2,3," and ",1" are errors too.
  for (const std::string& item : split_list(text, ',')) {
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v) || v < 0.0 ||
        v > double(std::numeric_limits<float>::max())) {
      throw UsageError(command + ": --env-color expects R,G,B or one value >= 0, got '" + text +
                       "'");
    }
    values.push_back(float(v));
  }
  if (values.size() == 1) return glm::vec3(values[0]);
  if (values.size() == 3) return {values[0], values[1], values[2]};
  throw UsageError(command + ": --env-color expects R,G,B or one value, got '" + text + "'");
}

SceneRequest parse_scene_request(const ParsedArgs& args, const std::string& spec) {
  SceneRequest r;
  r.spec = spec;
  const std::string& command = args.command();
  if (args.has("gltf-scene")) r.load.gltf_scene = args.get_int("gltf-scene", -1, 0, 1 << 20);
  if (args.has("camera")) r.load.camera = args.get_int("camera", -1, 0, 1 << 20);
  r.load.allow_outside_uris = args.has("allow-outside-uris");
  EnvironmentRequest& e = r.environment;
  if (args.has("env") && args.has("env-color")) {
    throw UsageError(command + ": give either --env or --env-color, not both");
  }
  e.map = args.value("env");
  if (auto color = args.value("env-color")) e.color = parse_env_color(*color, command);
  if (args.has("env-intensity")) e.intensity = args.get_float("env-intensity", 1.0f, 0.0f, 1e9f);
  if (args.has("env-rotation"))
    e.rotation_degrees = args.get_float("env-rotation", 0.0f, -1e6f, 1e6f);
  if (e.color) check_environment_radiance(*e.color, e.intensity.value_or(1.0f), command);
  return r;
}

bool uses_default_environment(const SceneRequest& request) {
  return request.default_environment && !is_builtin(request.spec) && !request.environment.map &&
         !request.environment.color;
}

Scene load_requested_scene(const SceneRequest& request, const std::string& program) {
  std::optional<ScopedActivity> activity;
  activity.emplace("loading " + request.spec);
  Scene scene = load_scene(request.spec, request.load);
  const EnvironmentRequest& e = request.environment;
  const float intensity = e.intensity.value_or(1.0f);
  activity.reset();
  activity.emplace("setting up the environment");
  if (e.map) {
    activity.reset();
    activity.emplace("loading the environment map " + *e.map);
    load_environment_map(scene, *e.map, intensity);
  } else if (e.color) {
    Environment& env = scene.edit_environment();
    env = Environment{};
    env.color = *e.color;
    env.intensity = intensity;
  } else if (uses_default_environment(request)) {
    set_environment_map(scene, default_environment_image(), kDefaultEnvironmentName, intensity);
    std::fprintf(stderr,
                 "%s: lighting %s with the built-in sky (%s) because no --env or --env-color was "
                 "given; --env-color 0 turns it off\n",
                 program.c_str(), request.spec.c_str(), kDefaultEnvironmentName);
  } else if (e.intensity) {
    scene.edit_environment().intensity = intensity;
  }
  if (e.rotation_degrees)
    scene.edit_environment().rotation = *e.rotation_degrees * float(M_PI) / 180.0f;
  return scene;
}

}  // namespace tandem
