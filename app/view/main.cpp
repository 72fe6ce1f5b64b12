// tandem-view: interactive, progressive path tracing of a scene in a window
// (default: the dynamic builtin:arena), or a scripted headless run that
// writes the last frame (`--frames N --screenshot out.png`, for tests under
// Xvfb). Exit codes as `tandem`: 1 bad input, 2 bad usage.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "app/backend_list.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/scene_setup.h"
#include "app/view/view_session.h"
#include "app/view/view_window.h"
#include "core/image/image.h"
#include "core/util/activity.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"

namespace tandem {
namespace {

const std::vector<OptionSpec>& view_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      image_size_options("1280", "720"),
      backend_options(false),
      thread_options(),
      {
          {"target-fps", true, "frame rate to hold while things move", "F", "30"},
          {"scale", true, "fixed resolution scale in (0, 1]; disables adaptation", "S"},
          {"min-scale", true,
           "lowest resolution scale adaptation may choose while things move (docs/performance.md "
           "measures what each shows)",
           "S", "0.15"},
      },
      path_depth_options("4"),
      light_sampler_options(),
      {{"max-spp", true, "most samples per pixel per frame when still", "N", "16"},
       {"target-spp", true, "a still image is done at N samples per pixel", "N", "1024"}},
      display_options(false),
      {
          {"exposure", true, "display exposure in stops", "E", "0"},
          {"no-denoise", false, "show the raw samples (no SVGF denoiser)"},
          {"show", true,
           "buffer to show: image, albedo, normal, depth, motion, variance, history (B cycles)",
           "NAME", "image"},
          {"split-view", false, "tint tiles by the backend that rendered them"},
          {"frames", true, "scripted run: render N frames along a camera path, then exit", "N"},
          {"still-frames", true,
           "with --frames: then N frames with the camera and scene held still (a still image "
           "refining; its input waits are measured, its frames are not in the frame rate)",
           "N", "0"},
          {"screenshot", true, "PNG for the last scripted frame (and F12)", "FILE"},
          {"no-window", false, "scripted run without opening a window (needs --frames)"},
          {"stats", true,
           "write the run's frame rate, frame times, input waits and what was shown as JSON",
           "FILE"},
          {"motion-reference-spp", true,
           "with --no-window --frames: the relMSE of four frames as shown against references of "
           "N spp",
           "N"},
      },
      scene_options(),
      environment_options(),
      help_options(),
      {{"version", false, "print the version"}},
  });
  return specs;
}

// The figures a scripted run is judged by: frames presented per second,
// frame times, how long input waited, and the resolution and samples shown.
void write_view_stats(const std::string& path, ViewSession& session,
                      const std::vector<double>& frame_seconds, uint32_t still_frames,
                      const InputWaits& waits, const std::vector<double>& motion_relmse) {
  double total = 0.0;
  for (double s : frame_seconds)
    total += s;
  const TracerSettings& t = session.tracer().settings();
  JsonValue report = bench_report("view", tbb::info::default_concurrency());
  report.set("tool", std::string("tandem-view"))
      .set("scene", session.options().scene)
      .set("frames", uint64_t(frame_seconds.size()))
      .set("still_frames", uint64_t(still_frames))
      .set("fps", frame_seconds.empty() ? 0.0 : double(frame_seconds.size()) / total)
      .set("frame_ms_p50", percentile(frame_seconds, 0.5) * 1e3)
      .set("frame_ms_p99", percentile(frame_seconds, 0.99) * 1e3)
      .set("max_input_wait_ms", waits.max_ms())
      .set("p99_input_wait_ms", waits.p99_ms())
      .set("output_width", uint64_t(session.options().width))
      .set("output_height", uint64_t(session.options().height))
      .set("shown_width", uint64_t(t.render.width))
      .set("shown_height", uint64_t(t.render.height))
      .set("spp_per_frame", uint64_t(t.samples_per_frame))
      .set("accumulated_spp", uint64_t(session.accumulated_spp()))
      .set("denoise", session.denoise());
  if (!motion_relmse.empty()) {
    double sum = 0.0;
    for (double e : motion_relmse)
      sum += e;
    report.set("motion_relmse", sum / double(motion_relmse.size()))
        .set("motion_relmse_frames", json_number_list(motion_relmse));
  }
  write_json_report(path, report);
}

int run(const std::vector<std::string>& argv) {
  const ParsedArgs args("tandem-view", view_options(), argv);
  if (args.has("help")) {
    std::printf(
        "usage: tandem-view [SCENE] [options]\n\nSCENE: a .gltf/.glb file or builtin:NAME "
        "(default builtin:arena).\nControls: F1 in the window.\n\n%s",
        format_options_help(view_options()).c_str());
    return 0;
  }
  if (args.has("version")) {
    std::printf("tandem-view %s\n", tandem_version());
    return 0;
  }
  if (args.positionals().size() > 1) throw UsageError("expected at most one SCENE argument");
  ViewOptions o;
  if (!args.positionals().empty()) o.scene = args.positionals()[0];
  o.width = args.get_u32("width", 16, 16384);
  o.height = args.get_u32("height", 16, 16384);
  o.backend = parse_backend_kind(args.get_string("backend"));
  o.backend_options = parse_kernel_option(args.value("kernel"), {o.backend});
  o.target_fps = args.get_float("target-fps", 1.0f, 1000.0f);
  o.fixed_scale = args.get_float("scale", 0.0f, 0.01f, 1.0f);
  o.min_scale = args.get_float("min-scale", o.min_scale, 0.01f, 1.0f);
  o.max_depth = args.get_u32("max-depth", 1, 1024);
  o.light_sampler = parse_light_sampler(args);
  o.max_spp_per_frame = args.get_u32("max-spp", 1, 4096);
  o.target_spp = args.get_u32("target-spp", 1, 1u << 24);
  o.exposure = args.get_float("exposure", -20.0f, 20.0f);
  o.denoise = !args.has("no-denoise");
  if (args.value("show")) {
    const std::optional<ViewBuffer> b = parse_view_buffer(*args.value("show"));
    if (!b) {
      throw UsageError("--show: unknown buffer '" + *args.value("show") +
                       "' (image, albedo, normal, depth, motion, variance, history)");
    }
    o.view_buffer = *b;
  }
  o.split_view = args.has("split-view");
  const SceneRequest scene_request = parse_scene_request(args, o.scene);
  o.scene_load = scene_request.load;
  o.environment = scene_request.environment;
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  std::optional<tbb::global_control> thread_limit;
  if (threads) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  const uint32_t frames = args.get_u32("frames", 0, 1, 1u << 24);
  const uint32_t still_frames = args.get_u32("still-frames", 0, 0, 1u << 24);
  if (still_frames > 0 && frames == 0) {
    throw UsageError("--still-frames follows a scripted run: add --frames N");
  }
  const std::string screenshot = args.get_string("screenshot", "");
  if (args.has("no-window") && frames == 0) {
    throw UsageError(
        "--no-window runs a script and needs a frame count: add --frames N (and --screenshot "
        "FILE.png to keep the last frame)");
  }
  if (!screenshot.empty()) {
    // Screenshots are what the window shows: tone-mapped 8-bit PNG. Check
    // the name and the folder now, not after the frames are rendered.
    std::string ext = std::filesystem::path(screenshot).extension().string();
    for (char& c : ext)
      c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".png") {
      throw UsageError("--screenshot writes PNG; the file name must end in .png, got '" +
                       screenshot + "'");
    }
    check_output_path(screenshot);
  }

  const std::optional<std::string> stats_path = args.value("stats");
  if (stats_path) check_json_output_path(*stats_path);  // before the run
  const uint32_t reference_spp = args.get_u32("motion-reference-spp", 0, 1, 1u << 20);
  if (reference_spp > 0 && !(args.has("no-window") && frames >= 5)) {
    throw UsageError(
        "--motion-reference-spp measures a scripted run without a window: add --no-window "
        "--frames N (N >= 5)");
  }

  ViewSession session(o);
  InputWaits waits;
  std::vector<double> frame_seconds, motion_relmse;
  const ScriptRecord record{&waits, &frame_seconds, reference_spp, &motion_relmse};
  WindowRunOptions w;
  w.scripted_frames = frames;
  w.still_frames = still_frames;
  w.screenshot = screenshot;
  w.input_waits = &waits;
  w.frame_seconds = &frame_seconds;
  std::string error;
  if (frames > 0 && args.has("no-window")) {
    run_headless_script(session, frames, still_frames, screenshot, record);
  } else if (!run_view_window(session, w, &error)) {
    if (frames == 0) throw InputError(error);
    // A scripted run still produces its frames without a display.
    std::fprintf(stderr, "tandem-view: %s; rendering the script without a window\n", error.c_str());
    run_headless_script(session, frames, still_frames, screenshot, record);
  }
  if (frames > 0) {
    std::printf(
        "tandem-view: %u frames, last %ux%u, %u spp accumulated, input read every %.1f ms at "
        "most (p99 %.1f)%s%s\n",
        frames + still_frames, session.tracer().settings().render.width,
        session.tracer().settings().render.height, session.tracer().accumulated_spp(),
        waits.max_ms(), waits.p99_ms(), screenshot.empty() ? "" : ", wrote ", screenshot.c_str());
  }
  if (!motion_relmse.empty()) {
    std::printf("tandem-view: motion relMSE (shown against %u spp references):", reference_spp);
    for (double e : motion_relmse)
      std::printf(" %.4f", e);
    std::printf("\n");
  }
  if (stats_path)
    write_view_stats(*stats_path, session, frame_seconds, still_frames, waits, motion_relmse);
  if (frames == 0) {
    // The user quit the window, which is closed and every output written:
    // the system frees the scene, the BVHs and the thread pool faster than
    // their destructors (60-120 ms on FlightHelmet, most of Esc's 100 ms).
    std::fflush(nullptr);
    std::_Exit(0);
  }
  return 0;
}

}  // namespace
}  // namespace tandem

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  // A signal while a screenshot is written removes its temporary file.
  tandem::install_interrupt_handlers();
  try {
    return tandem::run(args);
  } catch (const tandem::UsageError& e) {
    std::fprintf(stderr, "tandem-view: error: %s\nsee 'tandem-view --help'\n", e.what());
    return 2;
  } catch (const tandem::InputError& e) {
    std::fprintf(stderr, "tandem-view: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    const std::string activity = tandem::current_activity();
    std::fprintf(stderr,
                 "tandem-view: error: not enough memory%s%s (try a smaller window or scene)\n",
                 activity.empty() ? "" : " while ", activity.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tandem-view: error: %s\n", e.what());
    return 1;
  }
}
