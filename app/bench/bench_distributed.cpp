// `tandem bench --distributed`: the same render on rank 0 alone and on
// every rank of the MPI run, frame for frame, so the speed-up and the cost
// of the network are ratios measured in one run. Offline (spp samples of a
// still scene, split into frames as `tandem render` does) or, with
// --frames N, the frame loop with the scene moving every frame (the arena's
// bodies and the scripted camera of `bench --frames`). Both runs must give
// the same image bit for bit, which the bench checks: a difference is an
// error (exit status 1).

#include <chrono>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <optional>

#include "app/backend_list.h"
#include "app/bench/bench_mode.h"
#include "app/bench/bench_report.h"
#include "app/cli_args.h"
#include "app/distributed.h"
#include "app/render_frames.h"
#include "app/view/scripted_path.h"
#include "backends/mpi/mpi_cluster.h"
#include "core/util/cpu_time.h"
#include "core/util/errors.h"
#include "scenes/arena_scene.h"
#include "scenes/scene_loader.h"
#include "tracer/core_tracer.h"

namespace tandem {

namespace {

const std::vector<OptionSpec>& distributed_bench_options() {
  static const std::vector<OptionSpec> specs = {
      {"distributed", false, "run under mpirun -np N (this mode)"},
      {"frames", true,
       "measure the frame loop instead: N frames with the scene moving every frame (default "
       "scene builtin:arena, 640x360, 1 spp, max depth 4)",
       "N"},
      {"width", true, "image width (default 320; 640 with --frames)", "W"},
      {"height", true, "image height (default 180; 360 with --frames)", "H"},
      {"spp", true, "samples per pixel (default 64; per frame with --frames: 1)", "N"},
      {"max-depth", true, "maximum scattering events (default 8; 4 with --frames)", "D"},
      {"backend", true, "the local backends of every rank (default auto)", "B"},
      {"kernel", true, "megakernel | wavefront for the cuda and host backends", "K"},
      {"threads", true, "CPU worker threads on every rank (default: all cores)", "N"},
      {"tile-size", true, "tile edge in pixels (default 32)", "N"},
      {"json", true, "also write every figure, with the machine and run facts, to FILE as JSON",
       "FILE"},
      {"help", false, "show this help"},
  };
  return specs;
}

using Clock = std::chrono::steady_clock;

bool same_pixels(const ImageRGB& a, const ImageRGB& b) {
  return a.width == b.width && a.height == b.height &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

// Remembers which tiles a backend took from its source.
class RecordingTiles final : public TileSource {
 public:
  explicit RecordingTiles(TileSource& inner) : inner_(inner) {}
  bool next(Tile* tile) override {
    if (!inner_.next(tile)) return false;
    std::lock_guard<std::mutex> lock(mutex_);
    taken_.push_back(tile->index);
    return true;
  }
  const std::vector<uint32_t>& taken() const { return taken_; }

 private:
  TileSource& inner_;
  std::mutex mutex_;
  std::vector<uint32_t> taken_;
};

// A backend as the tracer sees it, plus what the bench wants to know of its
// last render(): the seconds of each tile it rendered (from the tracer's
// tile_seconds, which every backend fills, the peers with their worker's
// figures) and the CPU time of the thread that ran render(), which with
// --threads 1 is the whole renderer (TBB runs the tile loop on the caller).
class TimedBackend final : public Backend {
 public:
  explicit TimedBackend(std::unique_ptr<Backend> inner) : inner_(std::move(inner)) {}
  std::string name() const override { return inner_->name(); }
  BackendTraits traits() const override { return inner_->traits(); }
  void sync(const KernelScene& scene, const SceneDelta& delta) override {
    inner_->sync(scene, delta);
  }
  BackendStats render(const RenderPass& pass, TileSource& tiles, Film& film) override {
    RecordingTiles recording(tiles);
    const double cpu_start = tandem::thread_cpu_seconds();
    const BackendStats stats = inner_->render(pass, recording, film);
    thread_cpu_s_ = tandem::thread_cpu_seconds() - cpu_start;
    tiles_.clear();
    for (uint32_t i : recording.taken())
      tiles_.emplace_back(i, pass.tile_seconds ? pass.tile_seconds[i] : -1.0);
    return stats;
  }
  bool render_features(const FeaturePass& pass, PixelFeatures* out, const PassStop& stop) override {
    return inner_->render_features(pass, out, stop);
  }
  // (tile index, seconds) of the last render().
  const std::vector<std::pair<uint32_t, double>>& tiles() const { return tiles_; }
  double thread_cpu_seconds() const { return thread_cpu_s_; }

 private:
  std::unique_ptr<Backend> inner_;
  std::vector<std::pair<uint32_t, double>> tiles_;
  double thread_cpu_s_ = 0.0;
};

// One rank's share of the distributed run, summed over the measured frames.
struct RankTotals {
  std::string name;
  double tiles = 0, busy_s = 0, idle_s = 0;
  double bytes_to = 0, bytes_from = 0, scene_bytes = 0, sync_s = 0;
  // CPU: the whole rank's (rank 0's process for its local backends), the
  // part spent rendering, and for a worker rank 0's thread driving it.
  double cpu_s = 0, render_cpu_s = 0, driver_cpu_s = 0;
  // Seconds of the tiles this backend rendered, and of the same tiles when
  // rank 0 rendered them alone in the same frame: their ratio is the
  // backend's slowdown per tile, whatever the tiles' costs.
  double tile_s = 0, same_tiles_alone_s = 0;
};

// The scene and its motion: the same for both runs, posed from time alone.
struct MovingScene {
  Scene scene;
  std::unique_ptr<ArenaSimulation> arena;
  Camera base;
  MovingScene(const std::string& spec, uint32_t width, uint32_t height, bool moving) {
    scene = load_scene(spec);
    if (!scene.has_camera()) {
      scene.set_camera(
          frame_bounds_camera(scene.bounds(), 0.6911112f, float(width) / float(height)));
    }
    if (spec.rfind("builtin:", 0) != 0 && scene.lights().empty())
      scene.edit_environment().color = glm::vec3(1.0f);
    base = scene.camera();
    if (moving && spec == "builtin:arena") arena = std::make_unique<ArenaSimulation>(scene);
    if (moving) pose(0.0);
  }
  void pose(double t) {
    if (arena) arena->advance_to(t, scene);
    scene.edit_camera() = scripted_camera(base, t);
  }
};

struct Run {
  std::unique_ptr<CoreTracer> tracer;
  std::vector<TimedBackend*> timed;  // every backend, in the tracer's order
  std::vector<mpi::MpiPeerBackend*> peers;
  std::vector<RankTotals> ranks;  // rank 0's backends, then one per peer
  std::vector<double> frame_s;
  // Per frame: the frame time beyond the busiest rank's rendering, i.e.
  // what the network and an uneven finish add to the frame.
  std::vector<double> overhead_s;
  double total_s = 0;
  double process_cpu_s = 0;  // rank 0's, over the frames
};

Run make_run(const std::string& spec, const BackendOptions& options, const TracerSettings& ts,
             bool with_peers) {
  Run run;
  std::vector<std::unique_ptr<Backend>> backends = make_backend_list(spec, options);
  if (with_peers) {
    for (auto& p : mpi::connect_peers()) {
      run.peers.push_back(p.get());
      backends.push_back(std::move(p));
    }
  }
  for (auto& b : backends) {
    auto timed = std::make_unique<TimedBackend>(std::move(b));
    run.timed.push_back(timed.get());
    b = std::move(timed);
  }
  run.tracer = std::make_unique<CoreTracer>(std::move(backends), ts);
  return run;
}

// Adds a frame's figures to the run's totals (peers: the worker's own time).
// `alone_tile_s`: the seconds of every tile in the same frame rendered by
// rank 0 alone (empty for that run itself); `process_cpu_s`: rank 0's CPU
// time during the frame.
void account(Run& run, const FrameMetrics& m, const std::vector<double>& alone_tile_s,
             double process_cpu_s) {
  run.process_cpu_s += process_cpu_s;
  run.frame_s.push_back(m.total_seconds);
  run.ranks.resize(m.backends.size());
  const size_t local = m.backends.size() - run.peers.size();
  double busiest = 0.0;
  for (size_t b = 0; b < m.backends.size(); ++b) {
    RankTotals& r = run.ranks[b];
    r.name = m.backends[b].name;
    r.tiles += m.backends[b].tiles;
    double busy = m.backends[b].seconds;
    if (b >= local) {
      const mpi::PeerFrameStats& p = run.peers[b - local]->last_frame();
      busy = p.worker_busy_seconds;
      r.bytes_to += double(p.bytes_to_worker);
      r.bytes_from += double(p.bytes_from_worker);
      r.scene_bytes += double(p.scene_bytes);
      r.sync_s += p.sync_seconds;
      r.cpu_s += p.worker_cpu_seconds;
      r.render_cpu_s += p.worker_render_cpu_seconds;
      r.driver_cpu_s += p.driver_cpu_seconds;
    } else {
      r.cpu_s += process_cpu_s;
      r.render_cpu_s += run.timed[b]->thread_cpu_seconds();
    }
    for (const auto& [index, seconds] : run.timed[b]->tiles()) {
      if (index < alone_tile_s.size() && seconds > 0.0 && alone_tile_s[index] > 0.0) {
        r.tile_s += seconds;
        r.same_tiles_alone_s += alone_tile_s[index];
      }
    }
    r.busy_s += busy;
    r.idle_s += std::max(0.0, m.render_seconds - busy);
    busiest = std::max(busiest, busy);
  }
  run.overhead_s.push_back(std::max(0.0, m.total_seconds - busiest));
}

double mean(const std::vector<double>& v, size_t skip) {
  double s = 0;
  size_t n = 0;
  for (size_t i = skip; i < v.size(); ++i, ++n)
    s += v[i];
  return n ? s / double(n) : 0.0;
}

}  // namespace

int run_distributed_bench(const std::vector<std::string>& argv) {
  const ParsedArgs args("bench", distributed_bench_options(), argv);
  if (args.has("help")) {
    std::printf(
        "usage: mpirun -np N tandem bench --distributed [SCENE] [--frames F] [options]\n\n"
        "Renders SCENE on rank 0 alone, then on all N ranks, and reports the speed-up, each "
        "rank's\ntiles and busy/idle time and the bytes sent per frame; the two images must be "
        "identical.\n\n%s",
        format_options_help(distributed_bench_options()).c_str());
    return 0;
  }
  if (args.positionals().size() > 1) throw UsageError("bench: expected at most one SCENE argument");
  const bool loop = args.has("frames");
  const uint32_t frames = args.get_u32("frames", 0, 1, 1u << 20);
  const std::string scene_spec = args.positionals().empty()
                                     ? (loop ? "builtin:arena" : "builtin:cornell")
                                     : args.positionals()[0];
  const std::string backend_spec = args.get_string("backend", "auto");
  const BackendOptions options =
      parse_kernel_option(args.value("kernel"), parse_backend_list(backend_spec));
  const BenchThreads threads(args);
  TracerSettings ts;
  ts.render.width = args.get_u32("width", loop ? 640 : 320, 1, 16384);
  ts.render.height = args.get_u32("height", loop ? 360 : 180, 1, 16384);
  ts.render.max_depth = args.get_u32("max-depth", loop ? 4 : 8, 0, 1024);
  const uint32_t spp = args.get_u32("spp", loop ? 1 : 64, 1, 1u << 16);
  ts.tile_size = args.get_u32("tile-size", 32, 1, 4096);
  const std::optional<std::string> json_path = args.value("json");

  const int worker_status = start_distributed("bench", backend_spec, options);
  if (worker_status >= 0) return worker_status;
  if (json_path) check_json_output_path(*json_path);

  // The offline render takes its samples as frames of the core tracer, as
  // `tandem render` does; the frame loop renders spp per frame.
  const uint32_t frame_count = loop ? frames : offline_frame_count(spp);
  ts.samples_per_frame = loop ? spp : (spp + frame_count - 1) / frame_count;
  MovingScene ref_scene(scene_spec, ts.render.width, ts.render.height, loop);
  MovingScene dist_scene(scene_spec, ts.render.width, ts.render.height, loop);
  Run ref = make_run(backend_spec, options, ts, false);
  Run dist = make_run(backend_spec, options, ts, true);

  // Lockstep: frame f on rank 0 alone, then on all ranks, then compare.
  // The workers wait (asleep) while rank 0 renders alone.
  uint32_t identical = 0, first_difference = 0;
  uint32_t done_spp = 0;
  std::vector<double> alone_tile_s;  // this frame's, rank 0 alone
  double alone_tiles_total_s = 0;    // all frames'
  for (uint32_t f = 0; f < frame_count; ++f) {
    TracerSettings now = ts;
    if (!loop) now.samples_per_frame = std::min(ts.samples_per_frame, spp - done_spp);
    if (now.samples_per_frame == 0) break;
    done_spp += now.samples_per_frame;
    for (Run* run : {&ref, &dist}) {
      MovingScene& ms = run == &ref ? ref_scene : dist_scene;
      run->tracer->set_settings(now);
      const auto t = Clock::now();
      const double cpu_start = process_cpu_seconds();
      // Brigade's overlap, as in `bench --frames`: the scene moves on to the
      // next frame while this one renders.
      run->tracer->begin_frame(ms.scene);
      if (loop) ms.pose(double(f + 1) * kScriptedFrameStep);
      const FrameMetrics& m = run->tracer->end_frame();
      run->total_s += seconds_since(t);
      const double cpu_s = process_cpu_seconds() - cpu_start;
      if (run == &ref) {
        alone_tile_s.clear();
        for (const TimedBackend* b : ref.timed) {
          for (const auto& [index, seconds] : b->tiles()) {
            if (index >= alone_tile_s.size()) alone_tile_s.resize(index + 1, -1.0);
            alone_tile_s[index] = seconds;
            if (seconds > 0.0) alone_tiles_total_s += seconds;
          }
        }
        account(ref, m, {}, cpu_s);
      } else {
        account(dist, m, alone_tile_s, cpu_s);
      }
    }
    if (loop || done_spp == spp) {
      if (same_pixels(ref.tracer->image(), dist.tracer->image())) {
        ++identical;
      } else if (first_difference == 0) {
        first_difference = f + 1;
      }
    }
  }
  const uint32_t compared = loop ? frame_count : 1;
  const int ranks = mpi::rank_count();
  // The frame loop's first frame sends the whole scene: reported apart.
  const size_t skip = loop && frame_count > 1 ? 1 : 0;
  const double ref_s = loop ? mean(ref.frame_s, skip) : ref.total_s;
  const double dist_s = loop ? mean(dist.frame_s, skip) : dist.total_s;
  const double speedup = dist_s > 0 ? ref_s / dist_s : 0.0;

  std::printf("scene %s: %ux%u, %u spp%s, max depth %u, %d ranks, backend %s, %s threads/rank\n",
              scene_spec.c_str(), ts.render.width, ts.render.height, spp, loop ? "/frame" : "",
              ts.render.max_depth, ranks, backend_spec.c_str(),
              threads.requested() ? std::to_string(threads.requested()).c_str() : "all");
  if (loop) {
    std::printf(
        "frame loop:  %u frames, scene moving every frame (first frame, full scene, "
        "reported apart)\n",
        frame_count);
    std::printf("rank 0 alone:      %8.2f ms/frame\n", ref_s * 1e3);
    std::printf("all %d ranks:       %8.2f ms/frame (first frame %.2f ms)\n", ranks, dist_s * 1e3,
                dist.frame_s.empty() ? 0.0 : dist.frame_s[0] * 1e3);
  } else {
    std::printf("offline:     %u spp as %u frames\n", spp, frame_count);
    std::printf("rank 0 alone:      %8.3f s\n", ref_s);
    std::printf("all %d ranks:       %8.3f s\n", ranks, dist_s);
  }
  std::printf("speed-up:          %8.2fx\n", speedup);
  const double frames_d = double(std::max<size_t>(dist.frame_s.size(), 1));
  const double overhead_ms = mean(dist.overhead_s, skip) * 1e3;
  std::printf(
      "overhead:          %8.2f ms/frame (frame time beyond the busiest rank's "
      "rendering)\n",
      overhead_ms);
  double tile_sum = 0;
  for (const RankTotals& r : dist.ranks)
    tile_sum += r.tiles;
  // Per tile against rank 0 alone on the same tiles of the same frames:
  // wall time (load from elsewhere on the machine inflates both runs
  // alike only on average), and rendering CPU time (immune to that load),
  // the rank 0 alone share of the same tiles taken from their wall times.
  auto tile_time_ratio = [](const RankTotals& r) {
    return r.same_tiles_alone_s > 0 ? r.tile_s / r.same_tiles_alone_s : 0.0;
  };
  double alone_render_cpu_s = 0;
  for (const RankTotals& r : ref.ranks)
    alone_render_cpu_s += r.render_cpu_s;
  auto tile_cpu_ratio = [&](const RankTotals& r) {
    const double expected = alone_tiles_total_s > 0
                                ? alone_render_cpu_s * r.same_tiles_alone_s / alone_tiles_total_s
                                : 0.0;
    return expected > 0 ? r.render_cpu_s / expected : 0.0;
  };
  for (const RankTotals& r : dist.ranks) {
    std::printf(
        "  %-16s tiles %5.1f%%  busy %8.2f ms/frame  idle %8.2f ms/frame  sent %9.1f KiB/frame "
        "(scene %.1f KiB)  received %9.1f KiB/frame\n",
        r.name.c_str(), tile_sum > 0 ? r.tiles / tile_sum * 100.0 : 0.0, r.busy_s / frames_d * 1e3,
        r.idle_s / frames_d * 1e3, r.bytes_to / frames_d / 1024.0,
        r.scene_bytes / frames_d / 1024.0, r.bytes_from / frames_d / 1024.0);
    // CPU time beyond the rendering is what waiting, packing and MPI cost
    // the rank; a tile time above 1 is the slowdown per tile next to rank 0
    // rendering alone (the same tiles of the same frame).
    const bool peer = r.driver_cpu_s > 0.0 || r.bytes_from > 0.0;
    std::printf(
        "  %-16s cpu %8.2f ms/frame (%s)  rendering %8.2f ms/frame  per tile vs rank 0 alone: "
        "time %5.3fx, cpu %5.3fx",
        "", r.cpu_s / frames_d * 1e3, peer ? "the worker's process" : "rank 0's process",
        r.render_cpu_s / frames_d * 1e3, tile_time_ratio(r), tile_cpu_ratio(r));
    if (peer) std::printf("  driving it on rank 0 %6.2f ms/frame", r.driver_cpu_s / frames_d * 1e3);
    std::printf("\n");
  }
  const double ref_frames_d = double(std::max<size_t>(ref.frame_s.size(), 1));
  std::printf("rank 0 alone:      cpu %8.2f ms/frame (its process)  rendering %8.2f ms/frame\n",
              ref.process_cpu_s / ref_frames_d * 1e3, alone_render_cpu_s / ref_frames_d * 1e3);
  std::printf("identical images:  %u of %u %s\n", identical, compared, loop ? "frames" : "renders");
  if (json_path) {
    JsonValue report = bench_report("distributed", threads.used());
    set_render_facts(report, scene_spec, ts.render.width, ts.render.height, spp,
                     ts.render.max_depth);
    JsonValue per_rank = JsonValue::array();
    for (const RankTotals& r : dist.ranks) {
      per_rank.push(JsonValue::object()
                        .set("name", r.name)
                        .set("tile_share", tile_sum > 0 ? r.tiles / tile_sum : 0.0)
                        .set("busy_ms_per_frame", r.busy_s / frames_d * 1e3)
                        .set("idle_ms_per_frame", r.idle_s / frames_d * 1e3)
                        .set("bytes_sent_per_frame", r.bytes_to / frames_d)
                        .set("scene_bytes_per_frame", r.scene_bytes / frames_d)
                        .set("bytes_received_per_frame", r.bytes_from / frames_d)
                        .set("sync_ms_per_frame", r.sync_s / frames_d * 1e3)
                        .set("cpu_ms_per_frame", r.cpu_s / frames_d * 1e3)
                        .set("render_cpu_ms_per_frame", r.render_cpu_s / frames_d * 1e3)
                        .set("driver_cpu_ms_per_frame", r.driver_cpu_s / frames_d * 1e3)
                        .set("tile_time_vs_rank0_alone", tile_time_ratio(r))
                        .set("tile_cpu_vs_rank0_alone", tile_cpu_ratio(r)));
    }
    report.set("loop", loop ? "frames" : "offline")
        .set("ranks", ranks)
        .set("backend", backend_spec)
        .set("frames", uint64_t(frame_count))
        .set(loop ? "rank0_ms_per_frame" : "rank0_seconds", loop ? ref_s * 1e3 : ref_s)
        .set(loop ? "distributed_ms_per_frame" : "distributed_seconds",
             loop ? dist_s * 1e3 : dist_s)
        .set("speedup", speedup)
        .set("overhead_ms_per_frame", overhead_ms)
        .set("rank0_alone_cpu_ms_per_frame", ref.process_cpu_s / ref_frames_d * 1e3)
        .set("identical_images", uint64_t(identical))
        .set("compared_images", uint64_t(compared))
        .set("ranks_detail", std::move(per_rank));
    write_json_report(json_path, report);
  }
  finish_distributed();
  if (identical != compared) {
    std::fprintf(stderr,
                 "tandem: error: bench --distributed: the image of %u ranks differs from rank 0's "
                 "alone (first at frame %u)\n",
                 ranks, first_difference);
    return 1;
  }
  return 0;
}

}  // namespace tandem
