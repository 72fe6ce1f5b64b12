// tandem-view: interactive, progressive path tracing of a scene in a window
// (default: the dynamic builtin:arena), or a scripted headless run that
// writes the last frame (`--frames N --screenshot out.png`, for tests under
// Xvfb). Exit codes as `tandem`: 1 bad input, 2 bad usage.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <new>
#include <string>
#include <vector>

#include "app/cli_args.h"
#include "app/view/view_session.h"
#include "app/view/view_window.h"
#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"

namespace tandem {
namespace {

const std::vector<OptionSpec>& view_options() {
  static const std::vector<OptionSpec> specs = {
      {"width", true, "window width (default 1280)", "W"},
      {"height", true, "window height (default 720)", "H"},
      {"backend", true, "auto, cpu, host, cuda or hetero (default auto)", "B"},
      {"target-fps", true, "frame rate to hold while things move (default 30)", "F"},
      {"scale", true, "fixed resolution scale in (0, 1]; disables adaptation", "S"},
      {"max-depth", true, "scattering events per path (default 4)", "D"},
      {"max-spp", true, "most samples per pixel per frame when still (default 16)", "N"},
      {"target-spp", true, "a still image is done at N samples per pixel (default 1024)", "N"},
      {"exposure", true, "display exposure in stops (default 0)", "E"},
      {"no-denoise", false, "do not filter low-sample motion frames"},
      {"split-view", false, "tint tiles by the backend that rendered them"},
      {"frames", true, "scripted run: render N frames along a camera path, then exit", "N"},
      {"screenshot", true, "PNG for the last scripted frame (and F12)", "FILE"},
      {"no-window", false, "scripted run without opening a window"},
      {"allow-outside-uris", false,
       "let glTF buffer/image URIs name files outside the scene file's folder"},
      {"help", false, "show this help"},
  };
  return specs;
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
  if (args.positionals().size() > 1) throw UsageError("expected at most one SCENE argument");
  ViewOptions o;
  if (!args.positionals().empty()) o.scene = args.positionals()[0];
  o.width = args.get_u32("width", 1280, 16, 16384);
  o.height = args.get_u32("height", 720, 16, 16384);
  o.backend = parse_backend_kind(args.get_string("backend", "auto"));
  o.target_fps = args.get_float("target-fps", 30.0f, 1.0f, 1000.0f);
  o.fixed_scale = args.get_float("scale", 0.0f, 0.01f, 1.0f);
  o.max_depth = args.get_u32("max-depth", 4, 1, 1024);
  o.max_spp_per_frame = args.get_u32("max-spp", 16, 1, 4096);
  o.target_spp = args.get_u32("target-spp", 1024, 1, 1u << 24);
  o.exposure = args.get_float("exposure", 0.0f, -20.0f, 20.0f);
  o.denoise = !args.has("no-denoise");
  o.split_view = args.has("split-view");
  o.allow_outside_uris = args.has("allow-outside-uris");
  const uint32_t frames = args.get_u32("frames", 0, 1, 1u << 24);
  const std::string screenshot = args.get_string("screenshot", "");
  if (!screenshot.empty() && frames == 0 && args.has("no-window")) {
    throw UsageError("--no-window needs --frames");
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

  ViewSession session(o);
  if (frames > 0 && args.has("no-window")) {
    run_headless_script(session, frames, screenshot);
    return 0;
  }
  WindowRunOptions w;
  w.scripted_frames = frames;
  w.screenshot = screenshot;
  std::string error;
  if (!run_view_window(session, w, &error)) {
    if (frames == 0) throw InputError(error);
    // A scripted run still produces its frames without a display.
    std::fprintf(stderr, "tandem-view: %s; rendering the script without a window\n", error.c_str());
    run_headless_script(session, frames, screenshot);
  }
  if (frames > 0) {
    std::printf("tandem-view: %u frames, last %ux%u, %u spp accumulated%s%s\n", frames,
                session.tracer().settings().render.width, session.tracer().settings().render.height,
                session.tracer().accumulated_spp(), screenshot.empty() ? "" : ", wrote ",
                screenshot.c_str());
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
    std::fprintf(stderr, "tandem-view: error: %s\nRun 'tandem-view --help' for usage.\n", e.what());
    return 2;
  } catch (const tandem::InputError& e) {
    std::fprintf(stderr, "tandem-view: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "tandem-view: error: not enough memory (try a smaller window or scene)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tandem-view: error: %s\n", e.what());
    return 1;
  }
}
