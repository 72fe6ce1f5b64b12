// `tandem render SCENE ...`: offline render to an image file.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "app/backend_list.h"
#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/commands.h"
#include "app/distributed.h"
#include "app/progress.h"
#include "app/render_denoise.h"
#include "app/render_frames.h"
#include "app/scene_setup.h"
#include "backends/backend_factory.h"
#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"
#include "core/util/log.h"
#include "core/world/kernel_scene.h"
#include "scenes/scene_animator.h"
#include "scenes/scene_loader.h"
#include "tracer/core_tracer.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& render_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      image_size_options("", "720"),
      {
          {"width", true, "image width in pixels (default: from the camera aspect and the height)",
           "W"},
          {"spp", true, "samples per pixel", "N", "64"},
      },
      path_depth_options("8"),
      backend_options(true),
      {
          {"split", true,
           "share of each frame's pixels (so of its samples) planned for the first backend, "
           "0..1, to the nearest tile (default: balanced from measured throughput); backends "
           "that finish early still steal tiles unless --no-stealing",
           "F"},
          {"no-stealing", false,
           "backends never take tiles planned for another (the split is then exactly the plan)"},
          {"seed", true, "random seed; same seed, same image", "S", "0"},
      },
      display_options(true),
      {
          {"output", true,
           "output file: .png (tone mapped sRGB), .exr or .pfm (linear radiance, without "
           "--exposure and --tonemap)",
           "FILE", "render.png"},
          {"exr-pixel", true, "pixel type of .exr output: float | half", "T", "float"},
          {"exr-compression", true,
           "compression of .exr output: zip | piz | dwaa | dwab | zips | rle | pxr24 | b44 | "
           "b44a | none (dwa and b44 are lossy)",
           "C", "zip"},
      },
      scene_options(),
      environment_options(),
      {
          {"aperture", true,
           "thin-lens aperture radius in scene units (default: the camera's, usually 0)", "R"},
          {"focus-distance", true, "distance to the plane in focus, scene units", "F"},
      },
      light_sampler_options(),
      thread_options(),
      {
          {"tile-size", true, "tile edge in pixels", "N", "32"},
          {"clamp", true, "clamp per-sample radiance to this value (biased; 0 = off)", "X", "0"},
          {"denoise", false, "filter the image guided by primary-hit features (SVGF, one frame)"},
          {"aov", true,
           "also write the feature buffers (albedo, normal, depth, motion, ids) to DIR as EXR",
           "DIR"},
          {"quiet", false, "no progress bar, summary or note that no GPU is used"},
          {"distributed", false,
           "under mpirun -np N: every rank renders tiles of each frame, rank 0 writes the output "
           "(docs/distributed.md)"},
          {"save-on-interrupt", false,
           "on Ctrl-C (SIGINT) or SIGTERM, write the samples rendered so far to --output"},
      },
      {
          // Animation frames (see render_frames.h).
          {"frame", true, "render the scene's animation at frame N (time N / fps)", "N"},
          {"frames", true,
           "render animation frames A..B; --output then needs a #### frame-number pattern", "A..B"},
          {"fps", true, "animation frames per second for --frame/--frames", "F", "24"},
      },
      help_options(),
  });
  return specs;
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
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
  const uint32_t spp = args.get_u32("spp", 1, 1u << 20);
  RenderSettings settings;
  settings.max_depth = args.get_u32("max-depth", 0, 1024);
  settings.seed = args.get_u32("seed", 0, 0xffffffffu);
  settings.radiance_clamp = args.get_float("clamp", 0.0f, 1e30f);
  settings.light_sampler = parse_light_sampler(args);
  const std::string backend_spec = args.get_string("backend");
  // Usage errors before loading.
  BackendOptions backend_options =
      parse_kernel_option(args.value("kernel"), parse_backend_list(backend_spec));
  backend_options.announce_cpu_fallback = !quiet;
  const float split = args.has("split") ? args.get_float("split", 0.0f, 1.0f) : -1.0f;
  ImageWriteOptions write_options;
  write_options.exposure = args.get_float("exposure", -50.0f, 50.0f);
  write_options.tone_map = parse_tone_map(args.get_string("tonemap"));
  write_options.exr_pixel_type = parse_exr_pixel_type(args.get_string("exr-pixel"));
  write_options.exr_compression = parse_exr_compression(args.get_string("exr-compression"));
  const std::string output_spec = args.get_string("output");
  const std::optional<RenderFrames> frame_range = parse_render_frames(
      args.value("frame"), args.value("frames"), args.value("fps"), output_spec);
  // A still render writes `output_spec` as given (a '#' in it is only a pattern with frames).
  const std::string output =
      frame_range ? frame_output_name(output_spec, frame_range->first) : output_spec;
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  const uint32_t tile_size = args.get_u32("tile-size", 1, 4096);
  const SceneRequest scene_request = parse_scene_request(args, scene_spec);
  std::optional<tbb::global_control> thread_limit;
  if (threads) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  // A worker rank serves rank 0 from here on and never touches the output.
  const bool distributed = args.has("distributed");
  if (distributed) {
    const int worker_status = start_distributed("render", backend_spec, backend_options);
    if (worker_status >= 0) return worker_status;
  }

  // Check the output extension before spending time on loading/rendering.
  const std::string ext = lower_extension(output);
  if (ext != ".png" && ext != ".exr" && ext != ".pfm") {
    throw UsageError("render: --output must end in .png, .exr or .pfm, got '" + output + "'");
  }
  // ... and that every frame's output can be written, and destroys no
  // input: a render is too costly to throw away at the end.
  // (builtin:NAME names no file, and is never one.)
  std::vector<std::string> inputs = {scene_request.spec};
  if (scene_request.environment.map) inputs.push_back(*scene_request.environment.map);
  check_render_outputs(output_spec, frame_range, inputs);
  if (ext != ".png" && (args.has("exposure") || args.has("tonemap"))) {
    const bool both = args.has("exposure") && args.has("tonemap");
    std::fprintf(stderr,
                 "tandem: warning: %s %s only to PNG output; %s is written as linear radiance "
                 "without %s\n",
                 both                   ? "--exposure and --tonemap"
                 : args.has("exposure") ? "--exposure"
                                        : "--tonemap",
                 both ? "apply" : "applies", output.c_str(), both ? "them" : "it");
  }
  if (ext != ".exr" && (args.has("exr-pixel") || args.has("exr-compression"))) {
    std::fprintf(stderr,
                 "tandem: warning: --exr-pixel and --exr-compression apply only to .exr "
                 "output; %s is not one\n",
                 output.c_str());
  }
  if (auto aov = args.value("aov")) {
    if (frame_range && (frame_range->count() > 1 || frame_range->whole_animation))
      throw UsageError("render: --aov writes one frame's feature buffers; use it with --frame N");
    check_aov_directory(*aov);
  }

  GltfAnimations animations;
  SceneRequest scene_load = scene_request;
  if (frame_range) scene_load.load.animations = &animations;
  const auto load_start = std::chrono::steady_clock::now();
  Scene scene = load_requested_scene(scene_load, "tandem");
  const double load_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();
  std::unique_ptr<SceneAnimator> animator = make_scene_animator(scene, std::move(animations));
  // (An empty glTF scene has been reported by the loader already.)
  RenderFrames range = frame_range.value_or(RenderFrames{});
  if (range.whole_animation) {
    resolve_whole_animation(range, animator->duration());
    check_render_outputs(output_spec, range, inputs);
  }
  if (frame_range && !quiet) {
    const std::string past_end = frames_past_end_notice(range, animator->duration());
    if (!past_end.empty()) std::fprintf(stderr, "tandem: %s\n", past_end.c_str());
  }

  // Resolution: explicit, or from the camera's aspect ratio.
  const float aspect =
      scene.camera().aspect_ratio > 0.0f ? scene.camera().aspect_ratio : 16.0f / 9.0f;
  // A side derived from the camera's aspect ratio (a file's value) is held
  // to the limit --width and --height have, before anything is allocated.
  const auto derived_side = [&](double side, const char* given) {
    if (side <= 32768.0) return std::max(1u, uint32_t(std::lround(side)));
    char text[64];
    std::snprintf(text, sizeof text, "%g", double(aspect));
    throw InputError(scene_request.spec + ": the camera's aspect ratio " + text + " with " + given +
                     " asks for an image " + std::to_string(std::llround(std::min(side, 1e15))) +
                     " pixels " + (std::string(given).rfind("--width", 0) == 0 ? "high" : "wide") +
                     ", over the limit of 32768; give both --width and --height");
  };
  if (args.has("width") && args.has("height")) {
    settings.width = args.get_u32("width", 0, 1, 32768);
    settings.height = args.get_u32("height", 0, 1, 32768);
  } else if (args.has("width")) {
    settings.width = args.get_u32("width", 0, 1, 32768);
    settings.height = derived_side(double(settings.width) / double(aspect),
                                   ("--width " + std::to_string(settings.width)).c_str());
  } else {
    settings.height = args.get_u32("height", 1, 32768);
    settings.width = derived_side(double(settings.height) * double(aspect),
                                  ((args.has("height") ? "--height " : "the default height ") +
                                   std::to_string(settings.height))
                                      .c_str());
  }
  if (uint64_t(settings.width) * settings.height > (1ull << 28)) {
    throw UsageError("render: image of " + std::to_string(settings.width) + "x" +
                     std::to_string(settings.height) + " pixels is too large");
  }

  if (!scene.has_camera()) {
    // With frames, over one loop of the animation, not only the rest pose
    // (a moving object may leave it), so that frame N is framed the same
    // alone or in a sequence.
    const SceneBounds bounds = frame_range ? animation_bounds(*animator, scene) : scene.bounds();
    scene.set_camera(
        frame_bounds_camera(bounds, 0.6911112f, float(settings.width) / float(settings.height)));
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
  // The samples are rendered as a few frames of the core tracer.
  const uint32_t frames = offline_frame_count(spp);
  const uint32_t per_frame = (spp + frames - 1) / frames;
  tracer_settings.samples_per_frame = per_frame;
  std::vector<std::unique_ptr<Backend>> backends = make_backend_list(backend_spec, backend_options);
  if (distributed) add_distributed_peers(backends);
  CoreTracer tracer(std::move(backends), tracer_settings);

  // Animation frames: frame f is the scene posed at f / fps. The next
  // frame is posed while the last samples of this one render, so from one
  // frame to the next only the moved instances are committed.
  if (frame_range) {
    if (!animator->animated() && !quiet)
      std::fprintf(stderr, "tandem: %s has no animation; every frame is the same image\n",
                   scene_spec.c_str());
    animator->pose(range.time(range.first), scene);
  }
  ProgressBar bar(!quiet && stderr_is_terminal());
  const auto start = std::chrono::steady_clock::now();
  std::vector<BackendFrameMetrics> totals;
  const bool with_features = args.has("denoise") || args.has("aov");
  // The set-up (BVH builds, the environment's sampling tables: seconds for
  // a big map) before signals become a polled flag: until then Ctrl-C or
  // SIGTERM ends the process at once, with nothing written.
  tracer.set_settings(tracer_settings);
  tracer.sync_scene(scene);
  // Ctrl-C / SIGTERM while rendering: finish the frame in flight, then stop.
  std::optional<GracefulStop> stop(std::in_place);
  for (uint32_t frame = range.first; frame <= range.final_frame(); frame += range.step) {
    const std::string frame_output = frame_range ? frame_output_name(output_spec, frame) : output;
    tracer.reset_accumulation();  // even if nothing moved since the last frame
    tracer_settings.samples_per_frame = per_frame;
    tracer.set_settings(tracer_settings);
    // The tracer's count restarts at this frame's first pass.
    uint32_t done = 0;
    while (done < spp && !stop->requested()) {
      const uint32_t left = spp - done;
      if (left < tracer_settings.samples_per_frame) {
        tracer_settings.samples_per_frame = left;  // does not restart accumulation
        tracer.set_settings(tracer_settings);
      }
      std::function<void(Scene&)> pose_next;
      // (Not with features: they are traced from the scene as this frame has it.)
      if (frame < range.final_frame() && left <= tracer_settings.samples_per_frame &&
          !with_features) {
        const double next_time = range.time(frame + range.step);
        pose_next = [&animator, next_time](Scene& s) { animator->pose(next_time, s); };
      }
      const FrameMetrics& m = tracer.render_frame(scene, pose_next);
      done = tracer.accumulated_spp();
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
      if (bar.enabled())
        bar.update((double(range.index(frame)) + double(done) / double(spp)) /
                   double(range.count()));
    }
    if (stop->requested()) {
      bar.finish();
      const int stop_signal = stop->signal();
      stop.reset();  // from here a signal ends the process (and removes a partial output)
      // Before this frame's first pass the film still holds the previous frame.
      return finish_interrupted(stop_signal, tracer, spp, frame_output, write_options,
                                args.has("save-on-interrupt") && done > 0);
    }
    ImageRGB final_image = tracer.image();
    if (with_features) {
      const std::vector<PixelFeatures> features = render_scene_features(scene, settings);
      if (auto aov = args.value("aov"))
        write_feature_aovs(*aov, features, settings.width, settings.height);
      if (args.has("denoise")) final_image = denoise_offline_image(features, final_image, spp);
    }
    write_image(frame_output, final_image, write_options);
    if (with_features && frame < range.final_frame())
      animator->pose(range.time(frame + range.step), scene);
    if (frame_range && range.count() > 1 && !quiet && !bar.enabled())
      std::fprintf(stderr, "tandem: frame %u (t = %.4f s) -> %s\n", frame, range.time(frame),
                   frame_output.c_str());
  }
  bar.finish();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop.reset();

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
        "tandem: %ux%u, %u spp, max depth %u on %s (%d threads): loaded in %.2f s, rendered in "
        "%.2f s, %.2f M samples/s, %.1f Mrays/s -> %s\n",
        settings.width, settings.height, spp, settings.max_depth, names.c_str(), worker_threads,
        load_seconds, seconds, double(samples) / seconds * 1e-6, double(rays) / seconds * 1e-6,
        frame_range && range.count() > 1 ? output_spec.c_str() : output.c_str());
  }
  if (distributed) finish_distributed();
  return 0;
}

}  // namespace tandem
