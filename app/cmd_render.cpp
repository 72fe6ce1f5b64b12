// `tandem render SCENE ...`: offline render to an image file.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>

#include "app/cli_args.h"
#include "app/commands.h"
#include "app/progress.h"
#include "backends/backend_factory.h"
#include "core/render/renderer.h"
#include "core/scene/kernel_scene.h"
#include "core/util/errors.h"
#include "core/util/log.h"
#include "scenes/scene_loader.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& render_options() {
  static const std::vector<OptionSpec> specs = {
      {"width", true, "image width in pixels (default: from the camera aspect, height 720)", "W"},
      {"height", true, "image height in pixels", "H"},
      {"spp", true, "samples per pixel (default 64)", "N"},
      {"max-depth", true, "maximum scattering events per path; 1 = direct light only (default 8)", "D"},
      {"backend", true, "cpu | host | cuda | hetero | auto (default auto)", "B"},
      {"seed", true, "random seed; same seed, same image (default 0)", "S"},
      {"exposure", true, "exposure in stops applied to PNG output (default 0)", "E"},
      {"tonemap", true, "PNG tone curve: standard | aces | reinhard (default standard)", "T"},
      {"output", true, "output file: .png (tone mapped sRGB), .exr or .pfm (linear) (default render.png)",
       "FILE"},
      {"gltf-scene", true, "glTF scene index to render (default: the file's default scene)", "N"},
      {"env", true, "equirectangular environment map (.hdr, .exr, .pfm)", "FILE"},
      {"env-color", true, "constant environment radiance, e.g. 0.5 or 0.2,0.3,0.4", "RGB"},
      {"env-intensity", true, "multiplier of the environment (default 1)", "X"},
      {"env-rotation", true, "environment rotation about +y in degrees (default 0)", "DEG"},
      {"aperture", true, "thin-lens aperture radius in scene units (default: the camera's, usually 0)",
       "R"},
      {"focus-distance", true, "distance to the plane in focus, scene units", "F"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"tile-size", true, "tile edge in pixels (default 32)", "N"},
      {"clamp", true, "clamp per-sample radiance to this value (biased; default off)", "X"},
      {"quiet", false, "no progress bar or summary"},
      {"help", false, "show this help"},
  };
  return specs;
}

glm::vec3 parse_color(const std::string& text) {
  std::vector<float> values;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const float v = std::strtof(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v) || v < 0.0f) {
      throw UsageError("render: --env-color expects R,G,B or one value >= 0, got '" + text + "'");
    }
    values.push_back(v);
  }
  if (values.size() == 1) return glm::vec3(values[0]);
  if (values.size() == 3) return {values[0], values[1], values[2]};
  throw UsageError("render: --env-color expects R,G,B or one value, got '" + text + "'");
}

}  // namespace

void print_render_help() {
  std::printf(
      "usage: tandem render SCENE [options]\n\n"
      "Renders SCENE (a .gltf/.glb file or builtin:NAME) to an image.\n\n%s",
      format_options_help(render_options()).c_str());
}

int run_render(const std::vector<std::string>& argv) {
  const ParsedArgs args("render", render_options(), argv);
  if (args.has("help")) {
    print_render_help();
    return 0;
  }
  if (args.positionals().size() != 1) {
    throw UsageError("render: expected exactly one SCENE argument (a .gltf/.glb file or builtin:NAME)");
  }
  const std::string scene_spec = args.positionals()[0];
  const bool quiet = args.has("quiet");
  const uint32_t spp = args.get_u32("spp", 64, 1, 1u << 20);
  RenderSettings settings;
  settings.max_depth = args.get_u32("max-depth", 8, 0, 1024);
  settings.seed = args.get_u32("seed", 0, 0, 0xffffffffu);
  settings.radiance_clamp = args.get_float("clamp", 0.0f, 0.0f, 1e30f);
  const BackendKind backend_kind = parse_backend_kind(args.get_string("backend", "auto"));
  ImageWriteOptions write_options;
  write_options.exposure = args.get_float("exposure", 0.0f, -50.0f, 50.0f);
  write_options.tone_map = parse_tone_map(args.get_string("tonemap", "standard"));
  const std::string output = args.get_string("output", "render.png");
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  const uint32_t tile_size = args.get_u32("tile-size", 32, 1, 4096);
  SceneLoadOptions load_options;
  load_options.gltf_scene = args.get_int("gltf-scene", -1, 0, 1 << 20);
  std::optional<tbb::global_control> thread_limit;
  if (threads) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);

  // Check the output extension before spending time on loading/rendering.
  {
    std::string ext = std::filesystem::path(output).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".png" && ext != ".exr" && ext != ".pfm") {
      throw UsageError("render: --output must end in .png, .exr or .pfm, got '" + output + "'");
    }
  }

  Scene scene = load_scene(scene_spec, load_options);
  if (auto env = args.value("env")) {
    load_environment_map(scene, *env, args.get_float("env-intensity", 1.0f, 0.0f, 1e9f));
  } else if (auto color = args.value("env-color")) {
    Environment& e = scene.edit_environment();
    e.color = parse_color(*color);
    e.intensity = args.get_float("env-intensity", 1.0f, 0.0f, 1e9f);
  } else if (args.has("env-intensity")) {
    scene.edit_environment().intensity = args.get_float("env-intensity", 1.0f, 0.0f, 1e9f);
  }
  if (args.has("env-rotation")) {
    scene.edit_environment().rotation = args.get_float("env-rotation", 0.0f, -1e6f, 1e6f) * float(M_PI) / 180.0f;
  }
  if (scene.triangle_count_instanced() == 0) log_warning(scene_spec + ": the scene has no triangles");

  // Resolution: explicit, or from the camera's aspect ratio.
  const float aspect = scene.camera().aspect_ratio > 0.0f ? scene.camera().aspect_ratio : 16.0f / 9.0f;
  if (args.has("width") && args.has("height")) {
    settings.width = args.get_u32("width", 0, 1, 32768);
    settings.height = args.get_u32("height", 0, 1, 32768);
  } else if (args.has("width")) {
    settings.width = args.get_u32("width", 0, 1, 32768);
    settings.height = std::max(1u, uint32_t(std::lround(float(settings.width) / aspect)));
  } else {
    settings.height = args.get_u32("height", 720, 1, 32768);
    settings.width = std::max(1u, uint32_t(std::lround(float(settings.height) * aspect)));
  }
  if (uint64_t(settings.width) * settings.height > (1ull << 28)) {
    throw UsageError("render: image of " + std::to_string(settings.width) + "x" +
                     std::to_string(settings.height) + " pixels is too large");
  }

  if (!scene.has_camera()) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  if (args.has("aperture") || args.has("focus-distance")) {
    Camera& cam = scene.edit_camera();
    cam.aperture_radius = args.get_float("aperture", cam.aperture_radius, 0.0f, 1e9f);
    cam.focus_distance = args.get_float("focus-distance", cam.focus_distance, 1e-6f, 1e9f);
  }

  KernelScene kernel_scene;
  SceneCompiler compiler;
  const SceneDelta delta = compiler.compile(scene, settings, kernel_scene);

  std::vector<std::unique_ptr<Backend>> backends = create_backends(backend_kind);
  Backend& backend = *backends.front();
  backend.sync(kernel_scene, delta);

  ProgressBar bar(!quiet && stderr_is_terminal());
  OfflineRenderOptions render_options;
  render_options.spp = spp;
  render_options.tile_size = tile_size;
  if (bar.enabled()) render_options.progress = [&bar](double f) { bar.update(f); };
  const OfflineRenderResult result = render_offline(backend, settings.width, settings.height, render_options);
  bar.finish();

  write_image(output, result.image, write_options);

  if (!quiet) {
    const double samples_per_s = double(result.stats.samples) / result.seconds;
    const double rays_per_s = double(result.stats.rays) / result.seconds;
    const int worker_threads = threads ? int(threads) : tbb::info::default_concurrency();
    std::fprintf(stderr,
                 "tandem: %ux%u, %u spp, max depth %u on %s (%d threads): %.2f s, %.2f M samples/s, "
                 "%.1f Mrays/s -> %s\n",
                 settings.width, settings.height, spp, settings.max_depth, backend.name().c_str(),
                 worker_threads, result.seconds, samples_per_s * 1e-6, rays_per_s * 1e-6, output.c_str());
  }
  return 0;
}

}  // namespace tandem
