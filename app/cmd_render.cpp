// `tandem render SCENE ...`: offline render to an image file.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "app/backend_list.h"
#include "app/cli_args.h"
#include "app/commands.h"
#include "app/progress.h"
#include "app/render_denoise.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/scene/kernel_scene.h"
#include "core/tracer/core_tracer.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"
#include "core/util/log.h"
#include "scenes/scene_loader.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& render_options() {
  static const std::vector<OptionSpec> specs = {
      {"width", true, "image width in pixels (default: from the camera aspect, height 720)", "W"},
      {"height", true, "image height in pixels", "H"},
      {"spp", true, "samples per pixel (default 64)", "N"},
      {"max-depth", true, "maximum scattering events per path; 1 = direct light only (default 8)",
       "D"},
      {"backend", true,
       "cpu | host | cuda | hetero | auto (default auto), or a list such as cpu+host to split each "
       "frame "
       "between backends",
       "B"},
      {"kernel", true,
       "megakernel | wavefront (mega, wave): how the cuda and host backends trace paths "
       "(default megakernel; both give the same image)",
       "K"},
      {"split", true,
       "fixed share of each frame for the first backend, 0..1 (default: balanced from measured "
       "throughput)",
       "F"},
      {"no-stealing", false, "backends never take tiles planned for another"},
      {"seed", true, "random seed; same seed, same image (default 0)", "S"},
      {"exposure", true, "exposure in stops applied to PNG output (default 0)", "E"},
      {"tonemap", true, "PNG tone curve: standard | aces | reinhard (default standard)", "T"},
      {"output", true,
       "output file: .png (tone mapped sRGB), .exr or .pfm (linear) (default render.png)", "FILE"},
      {"gltf-scene", true, "glTF scene index to render (default: the file's default scene)", "N"},
      {"env", true, "equirectangular environment map (.hdr, .exr, .pfm)", "FILE"},
      {"env-color", true, "constant environment radiance, e.g. 0.5 or 0.2,0.3,0.4", "RGB"},
      {"env-intensity", true, "multiplier of the environment (default 1)", "X"},
      {"env-rotation", true, "environment rotation about +y in degrees (default 0)", "DEG"},
      {"aperture", true,
       "thin-lens aperture radius in scene units (default: the camera's, usually 0)", "R"},
      {"focus-distance", true, "distance to the plane in focus, scene units", "F"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"tile-size", true, "tile edge in pixels (default 32)", "N"},
      {"clamp", true, "clamp per-sample radiance to this value (biased; default off)", "X"},
      {"denoise", false, "filter the image guided by primary-hit features (SVGF, one frame)"},
      {"aov", true,
       "also write the feature buffers (albedo, normal, depth, motion, ids) to DIR as EXR", "DIR"},
      {"quiet", false, "no progress bar or summary"},
      {"save-on-interrupt", false,
       "on Ctrl-C (SIGINT) or SIGTERM, write the samples rendered so far to --output"},
      {"allow-outside-uris", false,
       "let glTF buffer/image URIs name files outside the scene file's folder"},
      {"help", false, "show this help"},
  };
  return specs;
}

glm::vec3 parse_color(const std::string& text) {
  std::vector<float> values;
  // split_list keeps empty items, so "1,2,3," and ",1" are errors too.
  for (const std::string& item : split_list(text, ',')) {
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v) || v < 0.0 ||
        v > double(std::numeric_limits<float>::max())) {
      throw UsageError("render: --env-color expects R,G,B or one value >= 0, got '" + text + "'");
    }
    values.push_back(float(v));
  }
  if (values.size() == 1) return glm::vec3(values[0]);
  if (values.size() == 3) return {values[0], values[1], values[2]};
  throw UsageError("render: --env-color expects R,G,B or one value, got '" + text + "'");
}

// Radiance is accumulated in float over many samples: a colour times an
// intensity near float's range becomes infinity and renders black. 1e30
// leaves room for the sums of any realistic number of samples.
constexpr double kMaxEnvironmentRadiance = 1e30;

void check_environment_radiance(const glm::vec3& color, float intensity) {
  for (int k = 0; k < 3; ++k) {
    const double radiance = double(color[k]) * double(intensity);
    if (radiance > kMaxEnvironmentRadiance) {
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "render: --env-color %g times --env-intensity %g is %g, beyond the largest "
                    "radiance that can be rendered (%g)",
                    double(color[k]), double(intensity), radiance, kMaxEnvironmentRadiance);
      throw UsageError(buf);
    }
  }
}

// After SIGINT/SIGTERM during the render: say so, optionally keep the image,
// and exit as the shell expects for that signal (128 + its number).
int finish_interrupted(int sig, const CoreTracer& tracer, uint32_t spp, const std::string& output,
                       const ImageWriteOptions& write_options, bool save) {
  const uint32_t done = tracer.accumulated_spp();
  if (save && done > 0) {
    write_image(output, tracer.image(), write_options);
    std::fprintf(stderr,
                 "tandem: interrupted by %s after %u of %u spp; wrote the image so far to %s\n",
                 signal_name(sig), done, spp, output.c_str());
  } else {
    std::fprintf(stderr, "tandem: interrupted by %s after %u of %u spp; no image written%s\n",
                 signal_name(sig), done, spp,
                 save ? " (no sample was complete)" : " (--save-on-interrupt keeps it)");
  }
  return 128 + sig;
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
    throw UsageError(
        "render: expected exactly one SCENE argument (a .gltf/.glb file or builtin:NAME)");
  }
  const std::string scene_spec = args.positionals()[0];
  const bool quiet = args.has("quiet");
  const uint32_t spp = args.get_u32("spp", 64, 1, 1u << 20);
  RenderSettings settings;
  settings.max_depth = args.get_u32("max-depth", 8, 0, 1024);
  settings.seed = args.get_u32("seed", 0, 0, 0xffffffffu);
  settings.radiance_clamp = args.get_float("clamp", 0.0f, 0.0f, 1e30f);
  const std::string backend_spec = args.get_string("backend", "auto");
  // Usage errors before loading.
  const BackendOptions backend_options =
      parse_kernel_option(args.value("kernel"), parse_backend_list(backend_spec));
  const float split = args.has("split") ? args.get_float("split", 0.5f, 0.0f, 1.0f) : -1.0f;
  ImageWriteOptions write_options;
  write_options.exposure = args.get_float("exposure", 0.0f, -50.0f, 50.0f);
  write_options.tone_map = parse_tone_map(args.get_string("tonemap", "standard"));
  const std::string output = args.get_string("output", "render.png");
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  const uint32_t tile_size = args.get_u32("tile-size", 32, 1, 4096);
  SceneLoadOptions load_options;
  load_options.gltf_scene = args.get_int("gltf-scene", -1, 0, 1 << 20);
  load_options.allow_outside_uris = args.has("allow-outside-uris");
  std::optional<tbb::global_control> thread_limit;
  if (threads) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);

  // Check the output extension before spending time on loading/rendering.
  {
    std::string ext = std::filesystem::path(output).extension().string();
    for (char& c : ext)
      c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".png" && ext != ".exr" && ext != ".pfm") {
      throw UsageError("render: --output must end in .png, .exr or .pfm, got '" + output + "'");
    }
  }
  // ... and that it can be written at all: a render is too costly to throw away at the end.
  check_output_path(output);
  if (auto aov = args.value("aov")) check_aov_directory(*aov);

  Scene scene = load_scene(scene_spec, load_options);
  if (auto env = args.value("env")) {
    load_environment_map(scene, *env, args.get_float("env-intensity", 1.0f, 0.0f, 1e9f));
  } else if (auto color = args.value("env-color")) {
    Environment& e = scene.edit_environment();
    e.color = parse_color(*color);
    e.intensity = args.get_float("env-intensity", 1.0f, 0.0f, 1e9f);
    check_environment_radiance(e.color, e.intensity);
  } else if (args.has("env-intensity")) {
    scene.edit_environment().intensity = args.get_float("env-intensity", 1.0f, 0.0f, 1e9f);
  }
  if (args.has("env-rotation")) {
    scene.edit_environment().rotation =
        args.get_float("env-rotation", 0.0f, -1e6f, 1e6f) * float(M_PI) / 180.0f;
  }
  // (An empty glTF scene has been reported by the loader already.)

  // Resolution: explicit, or from the camera's aspect ratio.
  const float aspect =
      scene.camera().aspect_ratio > 0.0f ? scene.camera().aspect_ratio : 16.0f / 9.0f;
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

  TracerSettings tracer_settings;
  tracer_settings.render = settings;
  tracer_settings.tile_size = tile_size;
  tracer_settings.scheduler.forced_split = split;
  tracer_settings.scheduler.stealing = !args.has("no-stealing");
  // The samples are rendered as a few frames of the core tracer: the tile
  // split is rebalanced between them, and they drive the progress bar.
  const uint32_t frames = std::min(spp, 32u);
  const uint32_t per_frame = (spp + frames - 1) / frames;
  tracer_settings.samples_per_frame = per_frame;
  CoreTracer tracer(make_backend_list(backend_spec, backend_options), tracer_settings);

  ProgressBar bar(!quiet && stderr_is_terminal());
  const auto start = std::chrono::steady_clock::now();
  std::vector<BackendFrameMetrics> totals;
  double render_seconds = 0.0;
  // Ctrl-C / SIGTERM while rendering: finish the frame in flight, then stop.
  std::optional<GracefulStop> stop(std::in_place);
  while (tracer.accumulated_spp() < spp && !stop->requested()) {
    const uint32_t left = spp - tracer.accumulated_spp();
    if (left < tracer_settings.samples_per_frame) {
      tracer_settings.samples_per_frame = left;  // does not restart accumulation
      tracer.set_settings(tracer_settings);
    }
    const FrameMetrics& m = tracer.render_frame(scene);
    render_seconds += m.render_seconds;
    totals.resize(m.backends.size());
    for (size_t b = 0; b < m.backends.size(); ++b) {
      BackendFrameMetrics& t = totals[b];
      const BackendFrameMetrics& f = m.backends[b];
      t.name = f.name;
      t.tiles += f.tiles;
      t.stolen += f.stolen;
      t.seconds += f.seconds;
      t.idle_seconds += f.idle_seconds;
      t.rays += f.rays;
      t.samples += f.samples;
      t.commit_bytes += f.commit_bytes;
      t.planned_share = f.planned_share;  // the last frame's plan
    }
    if (bar.enabled()) bar.update(double(tracer.accumulated_spp()) / double(spp));
  }
  bar.finish();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const int stop_signal = stop->signal();
  stop.reset();  // from here a signal ends the process (and removes a partial output)
  if (stop_signal != 0)
    return finish_interrupted(stop_signal, tracer, spp, output, write_options,
                              args.has("save-on-interrupt"));

  ImageRGB final_image = tracer.image();
  if (args.has("denoise") || args.has("aov")) {
    const std::vector<PixelFeatures> features = render_scene_features(scene, settings);
    if (auto aov = args.value("aov"))
      write_feature_aovs(*aov, features, settings.width, settings.height);
    if (args.has("denoise")) final_image = denoise_offline_image(features, final_image, spp);
  }
  write_image(output, final_image, write_options);

  if (!quiet) {
    uint64_t samples = 0, rays = 0;
    std::string names;
    for (const BackendFrameMetrics& t : totals) {
      samples += t.samples;
      rays += t.rays;
      names += (names.empty() ? "" : "+") + t.name;
    }
    const int worker_threads = threads ? int(threads) : tbb::info::default_concurrency();
    if (totals.size() > 1) {
      for (const BackendFrameMetrics& t : totals) {
        std::fprintf(
            stderr,
            "tandem:   %-5s %5u tiles (%u stolen), %.1f%% of samples, busy %.2f s, idle %.2f s, "
            "%.1f Mrays/s, last planned share %.2f, %llu commit bytes\n",
            t.name.c_str(), t.tiles, t.stolen,
            samples ? 100.0 * double(t.samples) / double(samples) : 0.0, t.seconds, t.idle_seconds,
            t.mrays_per_second(), t.planned_share, static_cast<unsigned long long>(t.commit_bytes));
      }
    }
    std::fprintf(
        stderr,
        "tandem: %ux%u, %u spp, max depth %u on %s (%d threads): %.2f s, %.2f M samples/s, "
        "%.1f Mrays/s -> %s\n",
        settings.width, settings.height, spp, settings.max_depth, names.c_str(), worker_threads,
        seconds, double(samples) / seconds * 1e-6, double(rays) / seconds * 1e-6, output.c_str());
  }
  return 0;
}

}  // namespace tandem
