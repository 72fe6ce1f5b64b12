#include "app/bench/bench_hetero.h"

#include <algorithm>
#include <cstdio>

#include "app/backend_list.h"
#include "tracer/core_tracer.h"

namespace tandem {

namespace {

struct HeteroRun {
  double samples_per_second = 0.0;
  std::vector<BackendFrameMetrics> last;  // the final frame's per-backend figures
  std::vector<double> sample_share;       // over all measured frames
};

// Renders `frames` frames of 1 sample per pixel after one warm-up frame
// (scene build, first split) that is not counted.
HeteroRun run_frames(Scene& scene, const RenderSettings& settings, uint32_t frames,
                     const std::string& spec, const BackendOptions& options) {
  TracerSettings ts;
  ts.render = settings;
  ts.samples_per_frame = 1;
  CoreTracer tracer(make_backend_list(spec, options), ts);
  tracer.render_frame(scene);
  double seconds = 0.0;
  uint64_t samples = 0;
  std::vector<uint64_t> per_backend(tracer.backend_count(), 0);
  HeteroRun run;
  for (uint32_t f = 0; f < frames; ++f) {
    const FrameMetrics& m = tracer.render_frame(scene);
    seconds += m.render_seconds;
    samples += m.samples();
    for (size_t b = 0; b < m.backends.size(); ++b)
      per_backend[b] += m.backends[b].samples;
    run.last = m.backends;
  }
  run.samples_per_second = seconds > 0.0 ? double(samples) / seconds : 0.0;
  for (uint64_t s : per_backend)
    run.sample_share.push_back(samples ? double(s) / double(samples) : 0.0);
  return run;
}

}  // namespace

JsonValue run_hetero_bench(Scene& scene, const RenderSettings& settings, uint32_t frames,
                           const std::string& list, const BackendOptions& options) {
  make_backend_list(list, options, /*validate_only=*/true);
  const std::vector<std::string> names = split_backend_list(list);

  std::printf("\nhetero: %u frames of 1 spp at %ux%u through the core tracer\n", frames,
              settings.width, settings.height);
  JsonValue json = JsonValue::object();
  json.set("frames", frames).set("width", settings.width).set("height", settings.height);
  JsonValue alone_json = JsonValue::array();
  double sum = 0.0, best = 0.0;
  for (const std::string& n : names) {
    const HeteroRun alone = run_frames(scene, settings, frames, n, options);
    std::printf("  %-12s alone: %8.3f M samples/s\n", n.c_str(), alone.samples_per_second * 1e-6);
    alone_json.push(
        JsonValue::object().set("backend", n).set("samples_per_second", alone.samples_per_second));
    sum += alone.samples_per_second;
    best = std::max(best, alone.samples_per_second);
  }
  const HeteroRun together = run_frames(scene, settings, frames, list, options);
  std::printf("  %-12s      : %8.3f M samples/s  (%.2f x sum of alone, %.2f x best alone)\n",
              list.c_str(), together.samples_per_second * 1e-6, together.samples_per_second / sum,
              together.samples_per_second / best);
  JsonValue backends = JsonValue::array();
  for (size_t b = 0; b < together.last.size(); ++b) {
    const BackendFrameMetrics& m = together.last[b];
    std::printf(
        "    %-6s %5.1f%% of samples, last frame: planned share %.2f, %u tiles (%u stolen), busy "
        "%.1f ms, "
        "idle %.1f ms\n",
        m.name.c_str(), 100.0 * together.sample_share[b], m.planned_share, m.tiles, m.stolen,
        m.seconds * 1e3, m.idle_seconds * 1e3);
    backends.push(JsonValue::object()
                      .set("name", m.name)
                      .set("sample_share", together.sample_share[b])
                      .set("last_frame_planned_share", m.planned_share)
                      .set("last_frame_tiles", m.tiles)
                      .set("last_frame_stolen", m.stolen)
                      .set("last_frame_busy_ms", m.seconds * 1e3)
                      .set("last_frame_idle_ms", m.idle_seconds * 1e3));
  }
  json.set("alone", std::move(alone_json));
  json.set("together", JsonValue::object()
                           .set("list", list)
                           .set("samples_per_second", together.samples_per_second)
                           .set("vs_sum_of_alone", together.samples_per_second / sum)
                           .set("vs_best_alone", together.samples_per_second / best)
                           .set("backends", std::move(backends)));
  return json;
}

}  // namespace tandem
