// The scene-update benchmark. Every case repeats one kind of edit and times
// SceneSync::update (compile + BVH update) for it; the edit itself
// (writing a transform, a colour) is outside the timed region. Moves
// alternate between two poses so the TLAS refit never drifts far from the
// built tree, as in a game where bodies move a little per frame.
#include "app/bench/bench_scene_update.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <optional>

#include <glm/gtc/matrix_transform.hpp>

#include "app/bench/bench_mode.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "core/util/errors.h"
#include "core/world/kernel_scene.h"
#include "scenes/scene_loader.h"
#include "sync/scene_sync.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& scene_update_options() {
  static const std::vector<OptionSpec> specs = {
      {"scene-update", false,
       "measure SyncScene + UpdateAccStruc for one instance, 100 instances, one and 100 emissive "
       "instances (lights), one material and one light changed (default scenes: "
       "builtin:procedural builtin:arena builtin:many-lights)"},
      {"repeats", true, "timed updates per case (default 31)", "N"},
      {"threads", true, "CPU worker threads (default: all cores)", "N"},
      {"json", true, "also write a list of {scene, case, median_ms} to FILE as JSON", "FILE"},
      {"help", false, "show this help"},
  };
  return specs;
}

using Clock = std::chrono::steady_clock;

struct UpdateCase {
  const char* name;
  std::function<void(Scene&, uint32_t repeat)> edit;
};

// `count` of `among` spread evenly over it (all of them when fewer).
std::vector<uint32_t> spread_instances(const std::vector<uint32_t>& among, uint32_t count) {
  const uint32_t n = uint32_t(among.size());
  std::vector<uint32_t> picked;
  if (n == 0) return picked;
  count = std::min(count, n);
  for (uint32_t i = 0; i < count; ++i)
    picked.push_back(among[uint64_t(i) * n / count]);
  return picked;
}

bool material_glows(const Material& m) {
  return m.emissive_strength > 0.0f && glm::length(m.emissive) > 0.0f;
}

std::vector<UpdateCase> update_cases(const Scene& scene) {
  // Every instance, and those of a mesh that emits (a light each).
  std::vector<uint32_t> all, emissive;
  for (uint32_t i = 0; i < scene.instances().size(); ++i) {
    all.push_back(i);
    const Mesh& mesh = scene.mesh(scene.instances()[i].mesh);
    if (std::any_of(mesh.triangle_materials.begin(), mesh.triangle_materials.end(),
                    [&](uint32_t m) {
                      return m < scene.materials().size() && material_glows(scene.materials()[m]);
                    })) {
      emissive.push_back(i);
    }
  }
  auto mover = [&scene](const std::vector<uint32_t>& among, uint32_t count) {
    const std::vector<uint32_t> picked = spread_instances(among, count);
    std::vector<glm::mat4> rest;
    for (uint32_t i : picked)
      rest.push_back(scene.instances()[i].transform);
    return [picked, rest](Scene& s, uint32_t repeat) {
      const float step = (repeat % 2) ? 0.01f : 0.0f;
      for (size_t k = 0; k < picked.size(); ++k)
        s.set_instance_transform(picked[k],
                                 glm::translate(glm::mat4(1.0f), glm::vec3(step, 0, 0)) * rest[k]);
    };
  };
  // A material no emitter uses, so the case measures the material path and
  // not a light-table rebuild.
  uint32_t material = 0;
  for (uint32_t i = 0; i < scene.materials().size(); ++i) {
    if (!material_glows(scene.materials()[i])) {
      material = i;
      break;
    }
  }
  std::vector<UpdateCase> cases = {
      {"move_1", mover(all, 1)},
      {"move_100", mover(all, 100)},
      {"material_1",
       [material](Scene& s, uint32_t repeat) {
         s.edit_material(material).roughness = (repeat % 2) ? 0.5f : 0.6f;
       }},
      {"light_1",
       [](Scene& s, uint32_t repeat) { s.edit_light(0).intensity *= (repeat % 2) ? 1.25f : 0.8f; }},
  };
  // Moving lights: each moved instance's light and the light tree's path
  // to it follow (only where the scene has some).
  if (!emissive.empty()) {
    cases.push_back({"move_light_1", mover(emissive, 1)});
    cases.push_back({"move_light_100", mover(emissive, 100)});
  }
  return cases;
}

}  // namespace

bool is_scene_update_bench(const std::vector<std::string>& args) {
  return has_bench_flag(args, "--scene-update");
}

int run_scene_update_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", scene_update_options(), argv);
  if (print_bench_help(args, "tandem bench [SCENE...] --scene-update [options]",
                       scene_update_options()))
    return 0;
  const uint32_t repeats = args.get_u32("repeats", 31, 1, 100000);
  const BenchThreads threads(args);
  const std::optional<std::string> json_path = checked_json_path(args);
  std::vector<std::string> specs = args.positionals();
  if (specs.empty()) specs = {"builtin:procedural", "builtin:arena", "builtin:many-lights"};

  JsonValue report = JsonValue::array();
  RenderSettings settings;
  std::printf("%-24s %-16s %12s\n", "scene", "case", "median ms");
  for (const std::string& spec : specs) {
    Scene scene = load_scene(spec);
    // light_1 needs a light to change.
    if (scene.lights().empty()) scene.add_light(Light{});
    if (!scene.has_camera()) scene.set_camera(frame_bounds_camera(scene.bounds(), 0.69f, 1.0f));
    SceneSync scene_sync;
    scene_sync.update(scene, settings);
    for (const UpdateCase& c : update_cases(scene)) {
      std::vector<double> ms;
      // One untimed round first: caches and the refit path warm up.
      for (uint32_t r = 0; r <= repeats; ++r) {
        c.edit(scene, r);
        const auto t0 = Clock::now();
        scene_sync.update(scene, settings);
        const double t = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        if (r > 0) ms.push_back(t);
      }
      const double m = median(ms);
      std::printf("%-24s %-16s %12.3f\n", spec.c_str(), c.name, m);
      report.push(JsonValue::object().set("scene", spec).set("case", c.name).set("median_ms", m));
    }
  }
  write_json_report(json_path, report);
  return 0;
}

}  // namespace tandem
