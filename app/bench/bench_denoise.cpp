// The denoiser's quality and cost along the scripted camera path. Every
// frame renders 1 spp with a new seed while the arena moves and the camera
// orbits, computes the features and runs the temporal denoiser, exactly as
// a frame loop would. At three frames along the path the frame is frozen
// and rendered again at 8 spp and at the reference sample count; the table
// (and --json) compare raw 1 spp, raw 8 spp and the denoised 1 spp frame
// (which has the history of the path so far) with that reference.
#include "app/bench/bench_denoise.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/bench/bench_mode.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "app/json_writer.h"
#include "app/render_denoise.h"
#include "app/view/scripted_path.h"
#include "backends/cpu/cpu_backend.h"
#include "core/render/offline_render.h"
#include "core/render/temporal_denoiser.h"
#include "core/util/errors.h"
#include "core/world/motion_history.h"
#include "scenes/arena_scene.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& denoise_bench_options() {
  static const std::vector<OptionSpec> specs = {
      {"denoise-quality", false, "this benchmark"},
      {"width", true, "frame width (default 640)", "W"},
      {"height", true, "frame height (default 360)", "H"},
      {"max-depth", true, "scattering events per path (default 4)", "D"},
      {"path-frames", true,
       "frames along the scripted path; measured at 1/4, 1/2 and the end (default 60)", "N"},
      {"reference-spp", true, "samples per pixel of the reference frames (default 1024)", "N"},
      {"reference-cache", true,
       "keep the reference frames as .pfm in DIR and reuse them on later runs with the same "
       "scene, size, depth, path and sample count (for tuning)",
       "DIR"},
      {"max-history", true, "frames the colour history averages at most (default 12)", "N"},
      {"kernel-radius", true, "a-trous taps: 1 = 3x3, 2 = 5x5 (default 1)", "R"},
      {"iterations", true, "a-trous iterations (default 4)", "N"},
      {"sigma-luminance", true, "luminance edge stop in standard deviations (default 4)", "S"},
      {"firefly-sigma", true,
       "clamp a sample above the history mean plus S standard deviations (default 3; 0: off)", "S"},
      {"repeat", true,
       "at the measured frames, time this many 1-spp renders and filter runs on the same inputs "
       "and report the median (default 5)",
       "N"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"images", true,
       "write PNGs of each measured frame, 2x2 at half resolution (raw 1 spp, raw 8 spp / "
       "denoised, reference) to DIR",
       "DIR"},
      {"json", true, "write a list with one object per measured frame to FILE", "FILE"},
      {"help", false, "show this help"},
  };
  return specs;
}

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// Half-resolution copies of four images in a 2x2 grid (so the PNG is the
// frame's size), tone mapped: row-major in the order given.
void write_grid(const std::filesystem::path& path, const std::vector<const ImageRGB*>& imgs) {
  const uint32_t w = imgs[0]->width / 2, h = imgs[0]->height / 2;
  ImageRGB out(w * 2, h * 2);
  for (size_t k = 0; k < imgs.size() && k < 4; ++k) {
    const uint32_t ox = uint32_t(k % 2) * w, oy = uint32_t(k / 2) * h;
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) {
          const ImageRGB& im = *imgs[k];
          out.pixel(ox + x, oy + y)[c] =
              0.25f * (im.pixel(2 * x, 2 * y)[c] + im.pixel(2 * x + 1, 2 * y)[c] +
                       im.pixel(2 * x, 2 * y + 1)[c] + im.pixel(2 * x + 1, 2 * y + 1)[c]);
        }
      }
    }
  }
  write_png_rgb8(path, out.width, out.height, tone_map_to_srgb8(out, 0.0f, ToneMap::kStandard));
}

// One frame's filter input for a replay: width, height (uint32), then the
// feature records and the radiance (3 floats a pixel), raw.
void dump_frame(const std::string& dir, uint32_t f, const std::vector<PixelFeatures>& features,
                const ImageRGB& radiance) {
  const std::string path = dir + "/frame_" + std::to_string(f) + ".bin";
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (!out) throw std::runtime_error("bench: cannot write " + path);
  const uint32_t wh[2] = {radiance.width, radiance.height};
  std::fwrite(wh, sizeof wh, 1, out);
  std::fwrite(features.data(), sizeof(PixelFeatures), features.size(), out);
  std::fwrite(radiance.rgb.data(), sizeof(float), radiance.rgb.size(), out);
  std::fclose(out);
}

}  // namespace

bool is_denoise_quality_bench(const std::vector<std::string>& args) {
  return has_bench_flag(args, "--denoise-quality");
}

int run_denoise_quality_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", denoise_bench_options(), argv);
  if (print_bench_help(args, "tandem bench [SCENE] --denoise-quality [options]",
                       denoise_bench_options()))
    return 0;
  if (args.positionals().size() > 1) throw UsageError("bench: expected at most one SCENE argument");
  const std::string spec = args.positionals().empty() ? "builtin:arena" : args.positionals()[0];
  const BenchThreads threads(args);
  RenderSettings settings;
  settings.width = args.get_u32("width", 640, 16, 16384);
  settings.height = args.get_u32("height", 360, 16, 16384);
  settings.max_depth = args.get_u32("max-depth", 4, 1, 1024);
  const uint32_t frames = args.get_u32("path-frames", 60, 4, 1u << 20);
  const uint32_t ref_spp = args.get_u32("reference-spp", 1024, 8, 1u << 20);
  const uint32_t repeat = args.get_u32("repeat", 5, 1, 1000);
  // For profiling the filter alone, without rendering (callgrind of a
  // loop over dumped frames): TANDEM_DENOISE_DUMP=DIR writes the features
  // and 1-spp radiance of the first TANDEM_DENOISE_DUMP_FRAMES frames
  // (default 8) to DIR.
  std::optional<std::string> dump_dir;
  if (const char* d = std::getenv("TANDEM_DENOISE_DUMP")) dump_dir = d;
  uint32_t dump_frames = 8;
  if (const char* n = std::getenv("TANDEM_DENOISE_DUMP_FRAMES"))
    dump_frames = uint32_t(std::atoi(n));
  const std::optional<std::string> json_path = checked_json_path(args);
  const std::optional<std::string> images = args.value("images");
  if (images) check_aov_directory(*images);
  const std::optional<std::string> ref_cache = args.value("reference-cache");
  if (ref_cache) check_aov_directory(*ref_cache);

  Scene scene = load_scene(spec);
  if (!scene.has_camera()) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  std::optional<ArenaSimulation> arena;
  if (spec == "builtin:arena") arena.emplace(scene);
  const Camera base = scene.camera();
  const uint32_t measured[3] = {frames / 4, frames / 2, frames - 1};

  SceneSync scene_sync(SceneSyncSettings::arrays_only());  // Embree builds its own
  CpuBackend backend{CpuTraversal::kEmbree};
  MotionHistory motion;
  SvgfParams params = svgf_default_params(settings.width, settings.height);
  params.max_history = args.get_u32("max-history", params.max_history, 1, 1u << 16);
  params.kernel_radius = args.get_u32("kernel-radius", params.kernel_radius, 1, 2);
  params.iterations = args.get_u32("iterations", params.iterations, 0, 10);
  params.sigma_luminance =
      args.get_float("sigma-luminance", params.sigma_luminance, 0.01f, 1000.0f);
  params.firefly_sigma = args.get_float("firefly-sigma", params.firefly_sigma, 0.0f, 1000.0f);
  TemporalDenoiser denoiser(params);
  std::vector<PixelFeatures> features;
  JsonValue list = JsonValue::array();
  const uint32_t w = settings.width, h = settings.height;
  std::printf(
      "scene %s, %ux%u, max depth %u, %u frames on the scripted path, reference %u spp, %d "
      "threads, filter loops %s\n",
      spec.c_str(), w, h, settings.max_depth, frames, ref_spp, threads.used(),
      svgf_cpu_isa_name(svgf_cpu_isa()));
  std::printf("%6s %12s %12s %14s %9s %9s %9s %10s %11s %10s\n", "frame", "raw1_relmse",
              "raw8_relmse", "denoised_relmse", "raw1_ssim", "raw8_ssim", "den_ssim", "filter_ms",
              "feature_ms", "render_ms");
  auto render = [&](uint32_t seed, uint32_t spp) {
    settings.seed = seed;
    backend.sync(scene_sync.kernel_scene(), scene_sync.update(scene, settings).changes);
    OfflineRenderOptions o;
    o.spp = spp;
    return render_offline(backend, w, h, o).image;
  };
  for (uint32_t f = 0; f < frames; ++f) {
    const double t = double(f) * kScriptedFrameStep;
    if (arena) arena->advance_to(t, scene);
    scene.edit_camera() = scripted_camera(base, t);
    const bool is_measured =
        std::find(std::begin(measured), std::end(measured), f) != std::end(measured);
    // At a measured frame the 1-spp render (same seed: the same image) and
    // the filter run `repeat` times on the same inputs, and the medians are
    // reported: single runs vary by 20% and more on a loaded machine. The
    // filter's extra runs go to copies of the denoiser (its history as it
    // was before this frame); the last run is the denoiser's own, which
    // carries the history on.
    const uint32_t runs = is_measured ? repeat : 1;
    std::vector<double> render_samples, filter_samples;
    ImageRGB raw1;
    for (uint32_t r = 0; r < runs; ++r) {
      const auto render_start = Clock::now();
      raw1 = render(f, 1);
      render_samples.push_back(ms_since(render_start));
    }
    const double render_ms = median(render_samples);
    const auto feature_start = Clock::now();
    features.resize(size_t(w) * h);
    backend.render_features(motion.advance(scene_sync.view()), features.data(), {});
    const double feature_ms = ms_since(feature_start);
    for (uint32_t r = 0; r + 1 < runs; ++r) {
      TemporalDenoiser trial = denoiser;
      (void)trial.process(features, raw1);
      filter_samples.push_back(trial.last_seconds().total() * 1e3);
    }
    if (dump_dir && f < dump_frames) dump_frame(*dump_dir, f, features, raw1);
    const ImageRGB denoised = denoiser.process(features, raw1);
    filter_samples.push_back(denoiser.last_seconds().total() * 1e3);
    const double filter_ms = median(filter_samples);
    if (std::getenv("TANDEM_DENOISE_STAGES")) {
      const SvgfStageSeconds& st = denoiser.last_seconds();
      std::fprintf(stderr, "frame %u: temporal %.2f variance %.2f atrous %.2f modulate %.2f ms\n",
                   f, st.temporal * 1e3, st.variance * 1e3, st.atrous * 1e3, st.modulate * 1e3);
    }
    if (!is_measured) continue;
    // The same frozen frame: 8 spp and the reference, with seeds of their own.
    const ImageRGB raw8 = render(0x10000000u + f, 8);
    ImageRGB ref;
    std::filesystem::path cached;
    if (ref_cache) {
      std::string scene_name = spec;
      for (char& c : scene_name)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      cached = std::filesystem::path(*ref_cache) /
               (scene_name + "_" + std::to_string(w) + "x" + std::to_string(h) + "_d" +
                std::to_string(settings.max_depth) + "_p" + std::to_string(frames) + "_f" +
                std::to_string(f) + "_" + std::to_string(ref_spp) + "spp.pfm");
    }
    if (!cached.empty() && std::filesystem::exists(cached)) {
      ref = read_image(cached);
    } else {
      ref = render(0x20000000u + f, ref_spp);
      if (!cached.empty()) write_image(cached, ref);
    }
    const double e1 = relative_mse(raw1, ref), e8 = relative_mse(raw8, ref),
                 ed = relative_mse(denoised, ref);
    const double s1 = ssim_luminance(raw1, ref), s8 = ssim_luminance(raw8, ref),
                 sd = ssim_luminance(denoised, ref);
    std::printf("%6u %12.4f %12.4f %14.4f %9.3f %9.3f %9.3f %10.2f %11.2f %10.2f\n", f, e1, e8, ed,
                s1, s8, sd, filter_ms, feature_ms, render_ms);
    std::fflush(stdout);
    list.push(JsonValue::object()
                  .set("frame", f)
                  .set("raw1_relmse", e1)
                  .set("raw8_relmse", e8)
                  .set("denoised_relmse", ed)
                  .set("raw1_ssim", s1)
                  .set("raw8_ssim", s8)
                  .set("denoised_ssim", sd)
                  .set("filter_ms", filter_ms)
                  .set("feature_ms", feature_ms)
                  .set("render_1spp_ms", render_ms)
                  .set("filter_ms_samples", json_number_list(filter_samples))
                  .set("render_1spp_ms_samples", json_number_list(render_samples))
                  .set("filter_over_render_1spp", filter_ms / render_ms)
                  .set("reference_spp", ref_spp));
    if (images) {
      write_grid(std::filesystem::path(*images) / ("denoise_frame_" + std::to_string(f) + ".png"),
                 {&raw1, &raw8, &denoised, &ref});
    }
  }
  write_json_report(json_path, list);
  return 0;
}

}  // namespace tandem
