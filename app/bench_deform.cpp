// The deformation benchmark. Every frame poses the scene at t = frame / 30 s
// through its SceneAnimator (for a skinned glTF file: node animations, joint
// palettes, skinning; for the built-ins: their procedural rigs), then runs
// the per-frame update path on the result. The first frame is untimed (it
// builds everything); the figures are medians over the timed frames.
#include "app/bench_deform.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <optional>

#include "accstruc/accel_structure.h"
#include "app/bench_mode.h"
#include "app/bench_report.h"
#include "app/cli_args.h"
#include "core/util/errors.h"
#include "core/world/kernel_scene.h"
#include "scenes/gltf_animation.h"
#include "scenes/scene_animator.h"
#include "scenes/scene_loader.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& deform_options() {
  static const std::vector<OptionSpec> specs = {
      {"deform", false,
       "measure per-frame skinning/morphing, SyncScene + UpdateAccStruc and delta bytes of "
       "deforming meshes (default scene: builtin:skinned-grid, 1 M skinned vertices)"},
      {"frames", true, "timed frames per scene (default 30)", "N"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
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
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

// Vertices of the meshes the last pose marked as moved.
size_t deformed_vertices(const Scene& scene) {
  size_t n = 0;
  for (uint32_t m : scene.dirty_meshes()) {
    if (scene.mesh_dirty()[m] & kDirtyVertices) n += scene.meshes()[m].positions.size();
  }
  return n;
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

  JsonValue report = bench_report("deform", threads.used());
  report.set("frames", uint64_t(frames));
  JsonValue list = JsonValue::array();
  RenderSettings settings;
  std::printf("%-28s %10s %12s %12s %12s %14s %18s\n", "scene", "vertices", "skinning ms",
              "update ms", "total ms", "delta bytes", "cpu ms skin/upd");
  for (const std::string& spec : specs) {
    GltfAnimations animations;
    SceneLoadOptions load;
    load.animations = &animations;
    Scene scene = load_scene(spec, load);
    if (!scene.has_camera()) scene.set_camera(frame_bounds_camera(scene.bounds(), 0.69f, 1.0f));
    std::unique_ptr<SceneAnimator> animator = make_scene_animator(scene, std::move(animations));
    if (!animator->animated()) throw InputError(spec + ": nothing in the scene moves");
    KernelScene ks;
    SceneCompiler compiler;
    AccelStructure accel;
    std::vector<double> skin_ms, update_ms, total_ms, bytes, skin_cpu, update_cpu, sync_ms,
        accstruc_ms, sync_cpu, accstruc_cpu;
    size_t vertices = 0;
    for (uint32_t f = 0; f <= frames; ++f) {
      const double c0 = cpu_ms_now();
      const auto t0 = Clock::now();
      animator->pose(double(f) / 30.0, scene);
      const double pose = ms_since(t0);
      const double c1 = cpu_ms_now();
      vertices = std::max(vertices, deformed_vertices(scene));
      const auto t1 = Clock::now();
      const SceneDelta delta = compiler.compile(scene, settings, ks);
      const double compile = ms_since(t1);
      const double c_compiled = cpu_ms_now();
      const auto t2 = Clock::now();
      const AccelUpdate update = accel.update(ks, delta);
      const double refit = ms_since(t2);
      const double sync = compile + refit;
      const double c2 = cpu_ms_now();
      const size_t frame_bytes = (delta | update.delta).bytes(ks);
      if (f == 0) continue;  // the first frame builds everything
      skin_ms.push_back(pose);
      update_ms.push_back(sync);
      sync_ms.push_back(compile);
      accstruc_ms.push_back(refit);
      total_ms.push_back(pose + sync);
      bytes.push_back(double(frame_bytes));
      skin_cpu.push_back(c1 - c0);
      update_cpu.push_back(c2 - c1);
      sync_cpu.push_back(c_compiled - c1);
      accstruc_cpu.push_back(c2 - c_compiled);
    }
    const double skin = median(skin_ms), upd = median(update_ms), total = median(total_ms);
    const double delta_bytes = median(bytes);
    std::printf("%-28s %10zu %12.3f %12.3f %12.3f %14.0f %9.3f/%.3f\n", spec.c_str(), vertices,
                skin, upd, total, delta_bytes, median(skin_cpu), median(update_cpu));
    list.push(JsonValue::object()
                  .set("scene", spec)
                  .set("deformed_vertices", uint64_t(vertices))
                  .set("skinning_ms", skin)
                  .set("update_ms", upd)
                  .set("sync_scene_ms", median(sync_ms))
                  .set("update_accstruc_ms", median(accstruc_ms))
                  .set("total_ms", total)
                  .set("delta_bytes", delta_bytes)
                  .set("skinning_cpu_ms", median(skin_cpu))
                  .set("update_cpu_ms", median(update_cpu))
                  .set("sync_scene_cpu_ms", median(sync_cpu))
                  .set("update_accstruc_cpu_ms", median(accstruc_cpu)));
  }
  report.set("scenes", list);
  write_json_report(json_path, report);
  return 0;
}

}  // namespace tandem
