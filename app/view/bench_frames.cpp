// The frame-loop benchmark: every frame advances the scene (arena bodies,
// glTF animations) by a fixed step and moves the camera along the scripted
// path, so every frame commits deltas and restarts accumulation, exactly as
// during motion in tandem-view. Reports frame-time percentiles, commit bytes
// per frame, and the backends' shares of the work.
#include "app/view/bench_frames.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>

#include "app/backend_list.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/scene_setup.h"
#include "app/view/input_waits.h"
#include "app/view/motion_quality.h"
#include "app/view/scripted_path.h"
#include "app/view/view_session.h"
#include "core/util/errors.h"

namespace tandem {

const std::vector<OptionSpec>& frame_bench_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      {
          {"scene", true, "scene to animate (or give it as SCENE)", "SCENE", "builtin:arena"},
          {"frames", true, "frames along the scripted path", "N", "300"},
      },
      image_size_options("640", "360"),
      {{"spp", true, "samples per pixel per frame", "N", "1"},
       {"motion-reference-spp", true,
        "also the relMSE of four frames as shown against references of N spp (their renders "
        "left out of the other figures)",
        "N"}},
      path_depth_options("4"),
      light_sampler_options(),
      backend_options(false),
      thread_options(),
      scene_options(),
      environment_options(),
      json_report_options(),
      help_options(),
  });
  return specs;
}

bool is_frame_bench(const std::vector<std::string>& args) {
  return std::any_of(args.begin(), args.end(), [](const std::string& a) {
    return a == "--frames" || a.rfind("--frames=", 0) == 0;
  });
}

int run_frame_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", frame_bench_options(), argv);
  if (args.has("help")) {
    std::printf("usage: tandem bench [SCENE] --frames N [options]\n\n%s",
                format_options_help(frame_bench_options()).c_str());
    return 0;
  }
  if (args.positionals().size() > 1 || (!args.positionals().empty() && args.has("scene")))
    throw UsageError("bench --frames: give one scene, as SCENE or with --scene");
  const uint32_t threads = args.get_u32("threads", 0, 1, 4096);
  std::optional<tbb::global_control> limit;
  if (threads) limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  ViewOptions o;
  o.scene = args.positionals().empty() ? args.get_string("scene") : args.positionals()[0];
  const SceneRequest request = parse_scene_request(args, o.scene);
  o.scene_load = request.load;
  o.environment = request.environment;
  o.width = args.get_u32("width", 8, 16384);
  o.height = args.get_u32("height", 8, 16384);
  o.fixed_scale = 1.0f;  // measure the loop itself, not the adaptation
  o.max_depth = args.get_u32("max-depth", 1, 1024);
  o.light_sampler = parse_light_sampler(args);
  o.backend = parse_backend_kind(args.get_string("backend"));
  o.backend_options = parse_kernel_option(args.value("kernel"), {o.backend});
  o.denoise = false;
  const uint32_t spp = args.get_u32("spp", 1, 4096);
  o.fixed_samples_per_frame = spp;
  const uint32_t frames = args.get_u32("frames", 1, 1u << 24);
  const uint32_t reference_spp = args.get_u32("motion-reference-spp", 0, 1, 1u << 20);
  if (reference_spp > 0 && frames < 5)
    throw UsageError("bench --frames: --motion-reference-spp needs --frames 5 or more");
  const std::optional<std::string> json_path = args.value("json");
  if (json_path) check_json_output_path(*json_path);  // before measuring

  ViewSession session(o);
  const Camera base = session.camera();
  std::vector<double> frame_s;
  // The scene's own work per frame: posing it (skinning, morphing; while
  // the previous frame renders), SyncScene, UpdateAccStruc and SyncAccStruc
  // (the backends' commits: Embree's refit, a device upload).
  std::vector<double> pose_s, sync_s, accstruc_s, commit_s;
  uint64_t delta_bytes = 0, rays = 0;
  std::vector<std::string> names;
  std::vector<double> seconds, tiles, share;
  std::vector<uint64_t> commit;
  std::vector<double> copy_s, hidden_s;
  uint32_t overlapped_commits = 0;
  double first_frame = 0.0;
  // Where the viewer reads its input: before each frame and every input
  // slice while it renders (the first frame's full build not counted).
  InputWaits waits;
  std::vector<double> relmse;  // of the frames motion_quality_frame() picks
  const auto start = std::chrono::steady_clock::now();
  auto poll = [&] {
    waits.polled(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    return false;
  };
  session.advance_scene(0.0);
  for (uint32_t f = 0; f < frames; ++f) {
    if (f > 0) poll();
    // The viewer's frame loop (Brigade's overlap): while the backends
    // render frame f, the simulation advances the Scene to frame f + 1 (the
    // renderers only read the compiled KernelScene) and, GPU-only, the next
    // frame is compiled and its BVH updated.
    session.set_camera(scripted_camera(base, double(f) * kScriptedFrameStep));
    // The Scene as this frame renders it, for its reference (a copy, like
    // the reference render, is no part of the loop: the input waits skip
    // both).
    std::optional<Scene> frame_scene;
    if (reference_spp > 0 && motion_quality_frame(f, frames)) {
      frame_scene = session.scene();
      waits.pause();
    }
    std::optional<double> next_t;
    if (f + 1 < frames) next_t = double(f + 1) * kScriptedFrameStep;
    const FrameMetrics& m =
        f == 0 ? session.render_frame(true, next_t) : session.render_frame(true, next_t, poll);
    if (f == 0) {
      first_frame = m.total_seconds;  // full compile + build: reported apart
      names.clear();
      for (const BackendFrameMetrics& b : m.backends)
        names.push_back(b.name);
      seconds.assign(names.size(), 0.0), tiles.assign(names.size(), 0.0);
      share.assign(names.size(), 0.0), commit.assign(names.size(), 0);
      copy_s.assign(names.size(), 0.0), hidden_s.assign(names.size(), 0.0);
      continue;
    }
    frame_s.push_back(m.total_seconds);
    pose_s.push_back(session.last_pose_seconds());
    sync_s.push_back(m.sync_scene_seconds);
    accstruc_s.push_back(m.update_accstruc_seconds);
    commit_s.push_back(m.sync_accstruc_seconds);
    delta_bytes += m.delta_bytes;
    overlapped_commits += m.overlapped_commit;
    rays += m.rays();
    for (size_t i = 0; i < m.backends.size() && i < names.size(); ++i) {
      seconds[i] += m.backends[i].seconds;
      tiles[i] += m.backends[i].tiles;
      share[i] += m.backends[i].planned_share;
      commit[i] += m.backends[i].commit_bytes;
      copy_s[i] += m.backends[i].commit_copy_seconds;
      hidden_s[i] += m.backends[i].commit_hidden_seconds;
    }
    if (frame_scene) {
      relmse.push_back(motion_relmse(*frame_scene, session, reference_spp));
      waits.pause();
    }
  }
  const double n = double(std::max<size_t>(frame_s.size(), 1));
  double total = 0.0, tile_sum = 0.0;
  for (double s : frame_s)
    total += s;
  for (double t : tiles)
    tile_sum += t;
  std::printf("scene %s: %zu triangles, %zu instances, %ux%u, %u spp/frame, max depth %u\n",
              o.scene.c_str(), session.scene().triangle_count_instanced(),
              session.scene().instances().size(), o.width, o.height, spp, o.max_depth);
  std::printf("first frame (full build):  %8.2f ms\n", first_frame * 1e3);
  std::printf("frames measured:           %8zu (scripted path, scene moving every frame)\n",
              frame_s.size());
  std::printf("frame time p50 / p99:      %8.2f / %.2f ms  (mean %.2f ms, %.1f fps)\n",
              percentile(frame_s, 0.5) * 1e3, percentile(frame_s, 0.99) * 1e3, total / n * 1e3,
              n / std::max(total, 1e-9));
  std::printf("input read every:          %8.2f ms at most (p99 %.2f ms)\n", waits.max_ms(),
              waits.p99_ms());
  std::printf("scene delta per frame:     %8.1f KiB\n", double(delta_bytes) / n / 1024.0);
  double mean_relmse = 0.0;
  for (double e : relmse)
    mean_relmse += e / double(relmse.size());
  if (!relmse.empty()) {
    std::printf("motion relMSE:             %8.4f (four frames against %u-spp references)\n",
                mean_relmse, reference_spp);
  }
  std::printf(
      "scene work per frame p50:  pose %.2f ms (beside the render), SyncScene %.2f, "
      "UpdateAccStruc %.2f, SyncAccStruc %.2f\n",
      percentile(pose_s, 0.5) * 1e3, percentile(sync_s, 0.5) * 1e3,
      percentile(accstruc_s, 0.5) * 1e3, percentile(commit_s, 0.5) * 1e3);
  std::printf("throughput:                %8.2f Mrays/s\n",
              double(rays) / std::max(total, 1e-9) * 1e-6);
  std::printf(
      "commits during the render:  %8u of %zu frames (uploaded while the previous frame "
      "rendered)\n",
      overlapped_commits, frame_s.size());
  for (size_t i = 0; i < names.size(); ++i) {
    std::printf(
        "backend %-8s tiles %5.1f%%  planned share %5.1f%%  %7.2f ms/frame  commit %8.1f "
        "KiB/frame, copy %.3f ms/frame (%.3f ms hidden behind rendering)\n",
        names[i].c_str(), tile_sum > 0 ? tiles[i] / tile_sum * 100.0 : 0.0, share[i] / n * 100.0,
        seconds[i] / n * 1e3, double(commit[i]) / n / 1024.0, copy_s[i] / n * 1e3,
        hidden_s[i] / n * 1e3);
  }
  if (json_path) {
    JsonValue report =
        bench_report("frames", threads ? int(threads) : tbb::info::default_concurrency());
    set_render_facts(report, o.scene, o.width, o.height, spp, o.max_depth);
    JsonValue backends = JsonValue::array();
    for (size_t i = 0; i < names.size(); ++i) {
      backends.push(JsonValue::object()
                        .set("name", names[i])
                        .set("tile_share", tile_sum > 0 ? tiles[i] / tile_sum : 0.0)
                        .set("planned_share", share[i] / n)
                        .set("ms_per_frame", seconds[i] / n * 1e3)
                        .set("commit_kib_per_frame", double(commit[i]) / n / 1024.0)
                        .set("commit_copy_ms_per_frame", copy_s[i] / n * 1e3)
                        .set("commit_hidden_ms_per_frame", hidden_s[i] / n * 1e3));
    }
    report.set("backend", args.get_string("backend", "auto"))
        .set("kernel", kernel_variant_name(o.backend_options.kernel))
        .set("triangles", uint64_t(session.scene().triangle_count_instanced()))
        .set("instances", uint64_t(session.scene().instances().size()))
        .set("first_frame_ms", first_frame * 1e3)
        .set("frames_measured", uint64_t(frame_s.size()))
        .set("overlapped_commits", uint64_t(overlapped_commits))
        .set("frame_ms_p50", percentile(frame_s, 0.5) * 1e3)
        .set("frame_ms_p99", percentile(frame_s, 0.99) * 1e3)
        .set("frame_ms_mean", total / n * 1e3)
        .set("fps", n / std::max(total, 1e-9))
        .set("max_input_wait_ms", waits.max_ms())
        .set("p99_input_wait_ms", waits.p99_ms())
        .set("shown_width", uint64_t(session.tracer().settings().render.width))
        .set("shown_height", uint64_t(session.tracer().settings().render.height))
        .set("spp_per_frame", uint64_t(spp))
        .set("denoise", o.denoise)
        .set("scene_delta_kib_per_frame", double(delta_bytes) / n / 1024.0)
        .set("pose_ms_p50", percentile(pose_s, 0.5) * 1e3)
        .set("sync_scene_ms_p50", percentile(sync_s, 0.5) * 1e3)
        .set("update_accstruc_ms_p50", percentile(accstruc_s, 0.5) * 1e3)
        .set("sync_accstruc_ms_p50", percentile(commit_s, 0.5) * 1e3)
        .set("mrays_per_second", double(rays) / std::max(total, 1e-9) * 1e-6)
        .set("backends", std::move(backends));
    if (!relmse.empty()) {
      report.set("motion_relmse", mean_relmse)
          .set("motion_relmse_frames", json_number_list(relmse))
          .set("motion_reference_spp", uint64_t(reference_spp));
    }
    write_json_report(json_path, report);
  }
  return 0;
}

}  // namespace tandem
