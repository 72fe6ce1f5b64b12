#include "app/bench/bench_gpu_report.h"

#include <cstdio>

#include "app/bench/bench_report.h"

namespace tandem {

namespace {

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof(buf), fmt, args...);
  return buf;
}

double ratio(double a, double b) {
  return b > 0.0 ? a / b : 0.0;
}

}  // namespace

std::string format_gpu_bench_table(const GpuBenchFigures& f) {
  std::string out = format("GPU bench on %s: scene %s\n", f.device.c_str(), f.scene.c_str());
  out += format(
      "ray sets cast from %ux%u (Embree: %d threads; GPU figures include the ray and hit "
      "transfers)\n",
      f.ray_width, f.ray_height, f.embree_threads);
  out += format("path tracing: %ux%u, %u spp, max depth %u, median of %u frames after %u warm-up\n",
                f.frame_width, f.frame_height, f.spp, f.max_depth, f.timed_frames, f.warmup_frames);
  out += format("  %-28s %-7s %-10s %10s %9s %11s %9s\n", "measurement", "layout", "kernel",
                "Mrays/s", "x embree", "M samples/s", "ms/frame");
  for (const GpuRayFigures& r : f.rays) {
    const std::string what =
        format("%s rays%s (%llu)", r.kind.c_str(), r.any_hit ? ", any hit" : "",
               static_cast<unsigned long long>(r.rays));
    out += format("  %-28s %-7s %-10s %10.2f %9s %11s %9s\n", what.c_str(), "embree", "-",
                  r.embree_mrays, "1.00", "-", "-");
    out += format("  %-28s %-7s %-10s %10.2f %9.2f %11s %9s\n", what.c_str(), "binary", "-",
                  r.gpu_binary_mrays, ratio(r.gpu_binary_mrays, r.embree_mrays), "-", "-");
    out += format("  %-28s %-7s %-10s %10.2f %9.2f %11s %9s\n", what.c_str(), "wide", "-",
                  r.gpu_wide_mrays, ratio(r.gpu_wide_mrays, r.embree_mrays), "-", "-");
  }
  for (const GpuFrameFigures& p : f.frames) {
    out += format("  %-28s %-7s %-10s %10.2f %9s %11.2f %9.2f\n", "path tracing", p.layout.c_str(),
                  p.kernel.c_str(), p.mrays_per_second, "-", p.samples_per_second * 1e-6,
                  p.ms_per_frame_median);
  }
  return out;
}

void add_gpu_bench_json(JsonValue& report, const GpuBenchFigures& f) {
  report.set("device", f.device);
  set_render_facts(report, f.scene, f.frame_width, f.frame_height, f.spp, f.max_depth);
  report.set("embree_threads", f.embree_threads);
  report.set("ray_set_width", f.ray_width);
  report.set("ray_set_height", f.ray_height);
  report.set("timed_frames", f.timed_frames);
  report.set("warmup_frames", f.warmup_frames);
  report.set("gpu_ray_figures_include_transfers", true);
  JsonValue sets = JsonValue::array();
  for (const GpuRayFigures& r : f.rays) {
    sets.push(JsonValue::object()
                  .set("kind", r.kind)
                  .set("any_hit", r.any_hit)
                  .set("rays", r.rays)
                  .set("embree_mrays_per_second", r.embree_mrays)
                  .set("gpu_binary_mrays_per_second", r.gpu_binary_mrays)
                  .set("gpu_wide_mrays_per_second", r.gpu_wide_mrays)
                  .set("gpu_binary_vs_embree", ratio(r.gpu_binary_mrays, r.embree_mrays))
                  .set("gpu_wide_vs_embree", ratio(r.gpu_wide_mrays, r.embree_mrays)));
  }
  report.set("ray_sets", std::move(sets));
  JsonValue runs = JsonValue::array();
  for (const GpuFrameFigures& p : f.frames) {
    runs.push(JsonValue::object()
                  .set("kernel", p.kernel)
                  .set("layout", p.layout)
                  .set("ms_per_frame_median", p.ms_per_frame_median)
                  .set("samples_per_second", p.samples_per_second)
                  .set("mrays_per_second", p.mrays_per_second));
  }
  report.set("path_tracing", std::move(runs));
}

}  // namespace tandem
