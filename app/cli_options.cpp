#include "app/cli_options.h"

#include "core/util/errors.h"
#include "core/world/kernel_scene.h"

namespace tandem {

const char* tandem_version() {
  return TANDEM_VERSION;
}

OptionGroup help_options() {
  return {{"help", false, "show this help (also -h)"}};
}

OptionGroup scene_options() {
  return {
      {"gltf-scene", true, "glTF scene index (default: the file's default scene)", "N"},
      {"camera", true,
       "use the scene's camera N (0 = its first; `tandem info` lists them; default: the first)",
       "N"},
      {"allow-outside-uris", false,
       "let glTF buffer/image URIs name files outside the scene file's folder"},
  };
}

OptionGroup environment_options() {
  return {
      {"env", true,
       "equirectangular environment map (.hdr, .exr, .pfm); without --env and --env-color a "
       "glTF scene is lit by the built-in sky (data/env/sky.hdr), built-in scenes by their own "
       "lights",
       "FILE"},
      {"env-color", true,
       "constant environment radiance, e.g. 0.5 or 0.2,0.3,0.4 (0: no environment light); "
       "not with --env",
       "RGB"},
      {"env-intensity", true, "multiplier of the environment", "X", "1"},
      {"env-rotation", true, "environment rotation about +y in degrees", "DEG", "0"},
  };
}

OptionGroup image_size_options(const std::string& width_default,
                               const std::string& height_default) {
  return {
      {"width", true, "image width in pixels", "W", width_default},
      {"height", true, "image height in pixels", "H", height_default},
  };
}

OptionGroup path_depth_options(const std::string& depth_default) {
  return {{"max-depth", true, "maximum scattering events per path; 1 = direct light only", "D",
           depth_default}};
}

OptionGroup light_sampler_options() {
  return {{"light-sampler", true,
           "how each bounce chooses the light it samples: tree (a light BVH: the lights near "
           "the point and facing it, for scenes of many lights) or power (by power alone)",
           "S", RenderSettings{}.light_sampler == LightSampler::kTree ? "tree" : "power"}};
}

LightSampler parse_light_sampler(const ParsedArgs& args) {
  const std::string name = args.get_string("light-sampler");
  if (name == "tree") return LightSampler::kTree;
  if (name == "power") return LightSampler::kPower;
  throw UsageError("--light-sampler must be power or tree, got '" + name + "'");
}

OptionGroup backend_options(bool allow_lists) {
  return {
      {"backend", true,
       allow_lists ? "cpu | host | cuda | hetero | auto, or a list such as cpu+host to split each "
                     "frame between backends"
                   : "cpu | host | cuda | hetero | auto",
       "B", "auto"},
      {"kernel", true,
       "megakernel | wavefront (mega, wave): how the cuda and host backends trace paths (both "
       "give the same image)",
       "K", "megakernel"},
  };
}

OptionGroup thread_options() {
  return {{"threads", true, "CPU worker threads (default: all cores)", "N"}};
}

OptionGroup json_report_options() {
  return {{"json", true, "also write every figure, with the machine and run facts, to FILE as JSON",
           "FILE"}};
}

OptionGroup display_options(bool tone_curve) {
  OptionGroup g = {{"exposure", true, "exposure in stops of 8-bit (PNG) output", "E", "0"}};
  if (tone_curve) {
    g.push_back(
        {"tonemap", true, "tone curve of PNG output: standard | aces | reinhard", "T", "standard"});
  }
  return g;
}

}  // namespace tandem
