// The deformation benchmark. Every frame poses the scene at t = frame / 30 s
// through its SceneAnimator (for a skinned glTF file: node animations and
// joint palettes; for the built-ins: their procedural rigs), then runs the
// per-frame update path on the result: SceneSync's update skins the posed
// meshes straight into the kernel arrays (SyncScene), then refits. The first frame is untimed (it
// builds everything); the figures are medians over the timed frames.
#include "app/bench/bench_deform.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <optional>

#include "app/bench/bench_mode.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "backends/cpu/cpu_backend.h"
#include "core/util/cpu_time.h"
#include "core/util/errors.h"
#include "core/world/kernel_scene.h"
#include "scenes/gltf_animation.h"
#include "scenes/scene_animator.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& deform_options() {
  static const std::vector<OptionSpec> specs = {
      {"deform", false,
       "measure per-frame skinning/morphing, SyncScene + UpdateAccStruc and delta bytes of "
       "deforming meshes (default scene: builtin:skinned-grid, 1 M skinned vertices)"},
      {"frames", true, "timed frames per scene (default 30)", "N"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"backends", true,
       "the backend configurations to measure, comma-separated: host, cpu+cuda, embree, "
       "both-layouts (default: all)",
       "LIST"},
      {"json", true, "also write the figures to FILE as JSON", "FILE"},
      {"help", false, "show this help"},
  };
  return specs;
}

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// CPU time of all the process's threads: on a machine shared with other
// work the wall time overstates what the code costs, so both are reported.
double cpu_ms_now() {
  return process_cpu_seconds() * 1e3;
}

// Which structures a frame keeps for its backends, as CoreTracer does:
//   host          the CPU backend on Tandem's BVH: AccelStructure with only
//                 the layout in use refit (kd.bvh.layout), nothing uploaded;
//   cpu+cuda      the same BVH for the CUDA backend, whose delta is
//                 uploaded, plus the CPU backend's Embree commit;
//   embree        the CPU backend on Embree alone (a GPU fell back, or none):
//                 no Tandem BVH, Embree's refit commit;
//   both-layouts  AccelStructure refitting both layouts every frame (callers
//                 that read the unused one: the figures before the frame
//                 loop kept only the layout in use).
enum class DeformConfig { kHost, kCpuCuda, kEmbree, kBothLayouts };
constexpr DeformConfig kDeformConfigs[] = {DeformConfig::kHost, DeformConfig::kCpuCuda,
                                           DeformConfig::kEmbree, DeformConfig::kBothLayouts};

const char* config_name(DeformConfig c) {
  switch (c) {
    case DeformConfig::kHost:
      return "host";
    case DeformConfig::kCpuCuda:
      return "cpu+cuda";
    case DeformConfig::kEmbree:
      return "embree";
    case DeformConfig::kBothLayouts:
      return "both-layouts";
  }
  return "?";
}

// Vertices of the meshes the last pose marked as moved.
size_t deformed_vertices(const Scene& scene) {
  size_t n = 0;
  for (uint32_t m : scene.dirty_meshes()) {
    if (scene.mesh_dirty()[m] & kDirtyVertices) n += scene.mesh_vertex_count(m);
  }
  return n;
}

struct DeformFigures {
  size_t vertices = 0;
  double pose = 0, pose_cpu = 0, update = 0, update_cpu = 0, sync = 0, sync_cpu = 0;
  double accstruc = 0, accstruc_cpu = 0, embree = 0, embree_cpu = 0, total = 0;
  double delta_bytes = 0, upload_bytes = 0;
};

// Poses `spec` frame after frame and runs the update path `config` needs.
DeformFigures run_config(const std::string& spec, DeformConfig config, uint32_t frames) {
  GltfAnimations animations;
  SceneLoadOptions load;
  load.animations = &animations;
  Scene scene = load_scene(spec, load);
  if (!scene.has_camera()) scene.set_camera(frame_bounds_camera(scene.bounds(), 0.69f, 1.0f));
  std::unique_ptr<SceneAnimator> animator = make_scene_animator(scene, std::move(animations));
  if (!animator->animated()) throw InputError(spec + ": nothing in the scene moves");
  const bool tandem_bvh = config != DeformConfig::kEmbree;
  const bool embree = config == DeformConfig::kEmbree || config == DeformConfig::kCpuCuda;
  const bool upload = config == DeformConfig::kCpuCuda || config == DeformConfig::kBothLayouts;
  SceneSyncSettings sync_settings;
  sync_settings.bvh = tandem_bvh;
  sync_settings.accel.refit_unused_layout = config == DeformConfig::kBothLayouts;
  // The layout the configuration's backends trace, as CoreTracer picks it:
  // the host backend's alone, the CUDA backend's with it.
  if (config == DeformConfig::kHost) {
    sync_settings.accel.layout = CpuBackend(CpuTraversal::kTandemBvh).traits().bvh_layout;
    sync_settings.accel.deforming_binary_only = true;
  }
  SceneSync scene_sync(sync_settings);
  std::unique_ptr<CpuBackend> cpu;
  if (embree) cpu = std::make_unique<CpuBackend>(CpuTraversal::kEmbree);
  RenderSettings settings;
  std::vector<double> pose_ms, update_ms, total_ms, bytes, uploaded, pose_cpu, update_cpu, sync_ms,
      accstruc_ms, sync_cpu, accstruc_cpu, embree_ms, embree_cpu;
  DeformFigures out;
  for (uint32_t f = 0; f <= frames; ++f) {
    const double c0 = cpu_ms_now();
    const auto t0 = Clock::now();
    // The pose only: the skinning itself runs in the update (SyncScene),
    // straight into the kernel arrays.
    animator->pose(double(f) / 30.0, scene);
    const double pose = ms_since(t0);
    const double c1 = cpu_ms_now();
    out.vertices = std::max(out.vertices, deformed_vertices(scene));
    const SceneSyncUpdate& up = scene_sync.update(scene, settings);
    const double compile = up.compile_seconds * 1e3;
    const double refit = up.accstruc_seconds * 1e3;
    const double c_refit = cpu_ms_now();
    const auto t3 = Clock::now();
    const KernelScene& ks = scene_sync.kernel_scene();
    if (cpu) cpu->sync(ks, up.changes);
    const double commit = ms_since(t3);
    const double c2 = cpu_ms_now();
    const size_t frame_bytes = up.changes.bytes(ks);
    if (f == 0) continue;  // the first frame builds everything
    pose_ms.push_back(pose);
    update_ms.push_back(compile + refit + commit);
    sync_ms.push_back(compile);
    accstruc_ms.push_back(refit);
    embree_ms.push_back(commit);
    total_ms.push_back(pose + compile + refit + commit);
    bytes.push_back(double(frame_bytes));
    uploaded.push_back(upload ? double(frame_bytes) : 0.0);
    pose_cpu.push_back(c1 - c0);
    update_cpu.push_back(c2 - c1);
    sync_cpu.push_back(up.compile_cpu_seconds * 1e3);
    accstruc_cpu.push_back(up.accstruc_cpu_seconds * 1e3);
    embree_cpu.push_back(c2 - c_refit);
  }
  out.pose = median(pose_ms);
  out.pose_cpu = median(pose_cpu);
  out.update = median(update_ms);
  out.update_cpu = median(update_cpu);
  out.sync = median(sync_ms);
  out.sync_cpu = median(sync_cpu);
  out.accstruc = median(accstruc_ms);
  out.accstruc_cpu = median(accstruc_cpu);
  out.embree = median(embree_ms);
  out.embree_cpu = median(embree_cpu);
  out.total = median(total_ms);
  out.delta_bytes = median(bytes);
  out.upload_bytes = median(uploaded);
  return out;
}

JsonValue figures_json(const DeformFigures& d) {
  return JsonValue::object()
      .set("pose_ms", d.pose)
      .set("update_ms", d.update)
      .set("sync_scene_ms", d.sync)
      .set("update_accstruc_ms", d.accstruc)
      .set("embree_commit_ms", d.embree)
      .set("total_ms", d.total)
      .set("delta_bytes", d.delta_bytes)
      .set("upload_bytes", d.upload_bytes)
      .set("pose_cpu_ms", d.pose_cpu)
      .set("update_cpu_ms", d.update_cpu)
      .set("sync_scene_cpu_ms", d.sync_cpu)
      .set("update_accstruc_cpu_ms", d.accstruc_cpu)
      .set("embree_commit_cpu_ms", d.embree_cpu);
}

}  // namespace

bool is_deform_bench(const std::vector<std::string>& args) {
  return has_bench_flag(args, "--deform");
}

int run_deform_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", deform_options(), argv);
  if (print_bench_help(args, "tandem bench [SCENE...] --deform [options]", deform_options()))
    return 0;
  const uint32_t frames = args.get_u32("frames", 30, 1, 100000);
  const BenchThreads threads(args);
  const std::optional<std::string> json_path = checked_json_path(args);
  std::vector<std::string> specs = args.positionals();
  if (specs.empty()) specs = {"builtin:skinned-grid"};
  std::vector<DeformConfig> configs(std::begin(kDeformConfigs), std::end(kDeformConfigs));
  if (const std::optional<std::string> list = args.value("backends")) {
    configs.clear();
    size_t at = 0;
    for (;;) {
      const size_t comma = list->find(',', at);
      const std::string name = list->substr(at, comma == std::string::npos ? comma : comma - at);
      bool known = false;
      for (const DeformConfig c : kDeformConfigs) {
        if (name == config_name(c)) {
          configs.push_back(c);
          known = true;
        }
      }
      if (!known) {
        throw UsageError("bench --deform: --backends: unknown configuration '" + name +
                         "' (host, cpu+cuda, embree, both-layouts)");
      }
      if (comma == std::string::npos) break;
      at = comma + 1;
    }
  }

  JsonValue report = bench_report("deform", threads.used());
  report.set("frames", uint64_t(frames));
  JsonValue list = JsonValue::array();
  std::printf("%-28s %-13s %10s %12s %12s %12s %14s %14s %18s\n", "scene", "backends", "vertices",
              "pose ms", "update ms", "total ms", "delta bytes", "upload bytes", "cpu ms pose/upd");
  for (const std::string& spec : specs) {
    // The scene's figures are those of the first configuration measured
    // (host by default: the Tandem BVH's update path); every configuration
    // is listed after them.
    JsonValue measured = JsonValue::array();
    JsonValue entry;
    for (const DeformConfig c : configs) {
      const DeformFigures d = run_config(spec, c, frames);
      std::printf("%-28s %-13s %10zu %12.3f %12.3f %12.3f %14.0f %14.0f %9.3f/%.3f\n", spec.c_str(),
                  config_name(c), d.vertices, d.pose, d.update, d.total, d.delta_bytes,
                  d.upload_bytes, d.pose_cpu, d.update_cpu);
      measured.push(figures_json(d).set("backends", std::string(config_name(c))));
      if (c == configs.front()) {
        entry = figures_json(d)
                    .set("scene", spec)
                    .set("deformed_vertices", uint64_t(d.vertices))
                    .set("backends", std::string(config_name(c)));
      }
    }
    list.push(entry.set("configurations", measured));
  }
  report.set("scenes", list);
  write_json_report(json_path, report);
  return 0;
}

}  // namespace tandem
