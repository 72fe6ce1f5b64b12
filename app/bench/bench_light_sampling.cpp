// The light samplers at equal time. Each sampler renders the scene in
// rounds of a few samples per pixel (each round with a seed of its own)
// until its time is up; the time counted is the rendering's, the same
// Embree scene for both. Their averages are compared with a reference of
// many more samples (the tree's, with seeds of its own), so the speed-up in
// time to equal noise is the ratio of relMSE x time. The reference's own
// noise adds to both figures: it is estimated from the tree's run (its
// relMSE scaled by their sample counts) and taken off before the ratio.
#include "app/bench/bench_light_sampling.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "app/bench/bench_mode.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/json_writer.h"
#include "app/render_denoise.h"
#include "app/scene_setup.h"
#include "backends/cpu/cpu_backend.h"
#include "core/image/image.h"
#include "core/render/offline_render.h"
#include "core/util/errors.h"
#include "sync/scene_sync.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& light_sampling_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      {{"light-sampling", false, "this benchmark"}},
      image_size_options("256", "160"),
      path_depth_options("8"),
      {{"seconds", true, "rendering time of each sampler", "S", "10"},
       {"reference-spp", true, "samples per pixel of the reference (the tree's)", "N", "1024"},
       {"reference-cache", true,
        "keep the reference as .pfm in DIR and reuse it on later runs with the same scene, size, "
        "depth and sample count (for tuning)",
        "DIR"},
       {"images", true, "write PNGs of both samplers' images and the reference to DIR", "DIR"}},
      thread_options(),
      scene_options(),
      environment_options(),
      json_report_options(),
      help_options(),
  });
  return specs;
}

using Clock = std::chrono::steady_clock;

const char* sampler_name(LightSampler s) {
  return s == LightSampler::kTree ? "tree" : "power";
}

struct SamplerRun {
  LightSampler sampler;
  ImageRGB image;
  uint32_t spp = 0;
  double seconds = 0.0;  // rendering only
  double relmse = 0.0;
};

// Renders `scene` with `sampler` for about `seconds`: rounds of `chunk`
// spp (doubled while a round takes under a fifth of a second), seeds
// seed_base, seed_base + 1, ...; the average of all of them.
SamplerRun render_for(Scene& scene, RenderSettings settings, LightSampler sampler, double seconds,
                      uint32_t seed_base) {
  SceneSync sync(SceneSyncSettings::arrays_only());
  CpuBackend backend{CpuTraversal::kEmbree};
  settings.light_sampler = sampler;
  SamplerRun run;
  run.sampler = sampler;
  std::vector<double> sum(size_t(settings.width) * settings.height * 3, 0.0);
  uint32_t chunk = 1;
  for (uint32_t round = 0; run.seconds < seconds; ++round) {
    settings.seed = seed_base + round;
    const SceneDelta delta = sync.update(scene, settings).changes;
    backend.sync(sync.kernel_scene(), delta);
    OfflineRenderOptions options;
    options.spp = chunk;
    const OfflineRenderResult r = render_offline(backend, settings.width, settings.height, options);
    for (size_t i = 0; i < sum.size(); ++i)
      sum[i] += double(r.image.rgb[i]) * chunk;
    run.spp += chunk;
    run.seconds += r.seconds;
    if (r.seconds < 0.2) chunk = std::min(chunk * 2, 64u);
  }
  run.image = ImageRGB(settings.width, settings.height);
  for (size_t i = 0; i < sum.size(); ++i)
    run.image.rgb[i] = float(sum[i] / run.spp);
  return run;
}

ImageRGB render_reference(Scene& scene, RenderSettings settings, uint32_t spp) {
  SceneSync sync(SceneSyncSettings::arrays_only());
  CpuBackend backend{CpuTraversal::kEmbree};
  settings.light_sampler = LightSampler::kTree;
  settings.seed = 0x5eed0000u;
  backend.sync(sync.kernel_scene(), sync.update(scene, settings).changes);
  OfflineRenderOptions options;
  options.spp = spp;
  return render_offline(backend, settings.width, settings.height, options).image;
}

// What building each sampler's light tables costs: the compile that
// switches to it (the light list, then the alias table, or the tree),
// the median of three switches each way.
struct TableCosts {
  double power_seconds = 0.0, tree_seconds = 0.0;
  size_t tree_bytes = 0, light_list_bytes = 0;
  uint32_t tree_nodes = 0, triangle_lights = 0, emissive_instances = 0, punctual_lights = 0,
           infinite_lights = 0;
  float tree_fraction = 0.0f;
};

TableCosts measure_tables(Scene& scene, RenderSettings settings) {
  SceneSync sync(SceneSyncSettings::arrays_only());
  TableCosts costs;
  std::vector<double> power, tree;
  for (int i = 0; i < 3; ++i) {
    for (LightSampler s : {LightSampler::kPower, LightSampler::kTree}) {
      settings.light_sampler = s;
      const auto start = Clock::now();
      sync.update(scene, settings);
      (s == LightSampler::kTree ? tree : power).push_back(seconds_since(start));
    }
  }
  costs.power_seconds = median(power);
  costs.tree_seconds = median(tree);
  const KernelScene& ks = sync.kernel_scene();  // the tree's, the last compiled
  costs.tree_nodes = uint32_t(ks.light_tree_nodes.size());
  costs.tree_bytes = ks.light_tree_nodes.size() * sizeof(KLightTreeNode) +
                     ks.light_tree_trails.size() * sizeof(uint64_t) +
                     ks.triangle_light_trails.size() * sizeof(uint64_t);
  costs.light_list_bytes = ks.lights.size() * sizeof(KLight) +
                           ks.light_alias.size() * sizeof(KAliasEntry) +
                           ks.instance_lights.size() * sizeof(uint32_t) +
                           ks.triangle_lights.size() * sizeof(KTriangleLight) +
                           ks.triangle_light_alias.size() * sizeof(KAliasEntry) +
                           ks.mesh_lights.size() * sizeof(KMeshLights);
  costs.triangle_lights = uint32_t(ks.triangle_lights.size());
  for (const KLight& l : ks.lights) {
    if (l.type == kLightMeshInstance) {
      ++costs.emissive_instances;
    } else if (l.type == kLightDirectional || l.type == kLightEnvironment) {
      ++costs.infinite_lights;
    } else {
      ++costs.punctual_lights;
    }
  }
  costs.tree_fraction = ks.constants.light_tree_fraction;
  return costs;
}

JsonValue run_json(const SamplerRun& r) {
  return JsonValue::object()
      .set("spp", r.spp)
      .set("seconds", r.seconds)
      .set("samples_per_second", double(r.spp) * r.image.width * r.image.height / r.seconds)
      .set("relmse", r.relmse);
}

}  // namespace

bool is_light_sampling_bench(const std::vector<std::string>& args) {
  return has_bench_flag(args, "--light-sampling");
}

int run_light_sampling_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", light_sampling_options(), argv);
  if (print_bench_help(args, "tandem bench [SCENE] --light-sampling [options]",
                       light_sampling_options()))
    return 0;
  if (args.positionals().size() > 1) throw UsageError("bench: expected at most one SCENE argument");
  const std::string spec =
      args.positionals().empty() ? "builtin:many-lights" : args.positionals()[0];
  RenderSettings settings;
  settings.width = args.get_u32("width", 1, 16384);
  settings.height = args.get_u32("height", 1, 16384);
  settings.max_depth = args.get_u32("max-depth", 0, 1024);
  const double seconds = args.get_float("seconds", 0.01f, 1e6f);
  const uint32_t ref_spp = args.get_u32("reference-spp", 1, 1u << 20);
  const BenchThreads threads(args);
  const std::optional<std::string> json_path = checked_json_path(args);
  const std::optional<std::string> ref_cache = args.value("reference-cache");
  if (ref_cache) check_aov_directory(*ref_cache);
  const std::optional<std::string> images = args.value("images");
  if (images) check_aov_directory(*images);
  const SceneRequest request = parse_scene_request(args, spec);

  Scene scene = load_requested_scene(request, "tandem");
  if (!scene.has_camera()) {
    scene.set_camera(frame_bounds_camera(scene.bounds(), 0.6911112f,
                                         float(settings.width) / float(settings.height)));
  }
  const TableCosts tables = measure_tables(scene, settings);
  std::printf(
      "scene %s: %u triangle lights in %u emissive instances, %u points and spots, %u at "
      "infinity; %ux%u, max depth %u, %.1f s per sampler, reference %u spp, %d threads\n",
      spec.c_str(), tables.triangle_lights, tables.emissive_instances, tables.punctual_lights,
      tables.infinite_lights, settings.width, settings.height, settings.max_depth, seconds, ref_spp,
      threads.used());

  ImageRGB ref;
  std::filesystem::path cached;
  if (ref_cache) {
    std::string name = spec;
    for (char& c : name)
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    cached = std::filesystem::path(*ref_cache) /
             (name + "_" + std::to_string(settings.width) + "x" + std::to_string(settings.height) +
              "_d" + std::to_string(settings.max_depth) + "_" + std::to_string(ref_spp) +
              "spp_lights.pfm");
  }
  const auto ref_start = Clock::now();
  const bool ref_cached = !cached.empty() && std::filesystem::exists(cached);
  if (ref_cached) {
    ref = read_image(cached);
    if (ref.width != settings.width || ref.height != settings.height) {
      throw InputError(cached.string() + ": the cached reference is not " +
                       std::to_string(settings.width) + "x" + std::to_string(settings.height));
    }
  } else {
    ref = render_reference(scene, settings, ref_spp);
    if (!cached.empty()) write_image(cached, ref);
  }
  const double ref_seconds = seconds_since(ref_start);

  SamplerRun runs[2] = {render_for(scene, settings, LightSampler::kPower, seconds, 0),
                        render_for(scene, settings, LightSampler::kTree, seconds, 0)};
  for (SamplerRun& r : runs)
    r.relmse = relative_mse(r.image, ref);
  const SamplerRun &power = runs[0], &tree = runs[1];
  // The reference's own noise, in both figures: the tree's at ref_spp.
  const double ref_share = double(tree.spp) / double(ref_spp);
  const double tree_true = tree.relmse / (1.0 + ref_share);
  const double ref_noise = tree_true * ref_share;
  const double power_true = std::max(power.relmse - ref_noise, 1e-30);
  const double speedup = (power_true * power.seconds) / (tree_true * tree.seconds);
  const double speedup_raw = (power.relmse * power.seconds) / (tree.relmse * tree.seconds);

  std::printf("sampler  spp    seconds  Msamples/s  relMSE\n");
  for (const SamplerRun& r : runs) {
    std::printf("%-7s %5u %9.2f %11.3f  %.5f\n", sampler_name(r.sampler), r.spp, r.seconds,
                double(r.spp) * r.image.width * r.image.height / r.seconds * 1e-6, r.relmse);
  }
  std::printf(
      "reference: %u spp (%s, %.1f s), its own noise about %.5f of each relMSE\n"
      "time to equal noise: the tree %.2fx faster than the power table (%.2fx with the "
      "reference's noise left in)\n"
      "light tables: power %.2f ms, tree %.2f ms (switching sampler: light list + tables); "
      "tree %u nodes, %.2f MB, beside %.2f MB of light list; %.3f of the power in the tree\n",
      ref_spp, ref_cached ? "cached" : "rendered", ref_seconds, ref_noise, speedup, speedup_raw,
      tables.power_seconds * 1e3, tables.tree_seconds * 1e3, tables.tree_nodes,
      double(tables.tree_bytes) / (1 << 20), double(tables.light_list_bytes) / (1 << 20),
      tables.tree_fraction);
  if (images) {
    const std::filesystem::path dir(*images);
    write_image(dir / "power.png", power.image);
    write_image(dir / "tree.png", tree.image);
    write_image(dir / "reference.png", ref);
    std::printf("images: %s/{power,tree,reference}.png\n", images->c_str());
  }

  JsonValue report = bench_report("light_sampling", threads.used());
  set_render_facts(report, spec, settings.width, settings.height, ref_spp, settings.max_depth);
  report.set("seconds_per_sampler", seconds);
  report.set("reference_spp", ref_spp);
  report.set("reference_noise_relmse", ref_noise);
  report.set("lights", JsonValue::object()
                           .set("triangles", tables.triangle_lights)
                           .set("emissive_instances", tables.emissive_instances)
                           .set("punctual", tables.punctual_lights)
                           .set("infinite", tables.infinite_lights)
                           .set("tree_fraction", double(tables.tree_fraction)));
  report.set("power", run_json(power));
  report.set("tree", run_json(tree));
  report.set("speedup_time_to_equal_noise", speedup);
  report.set("speedup_with_reference_noise", speedup_raw);
  report.set("tables", JsonValue::object()
                           .set("power_seconds", tables.power_seconds)
                           .set("tree_seconds", tables.tree_seconds)
                           .set("tree_nodes", tables.tree_nodes)
                           .set("tree_bytes", uint64_t(tables.tree_bytes))
                           .set("light_list_bytes", uint64_t(tables.light_list_bytes)));
  write_json_report(json_path, report);
  return 0;
}

}  // namespace tandem
