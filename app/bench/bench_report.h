// What every `tandem bench` mode writes with --json FILE: the machine and
// run facts, then the mode's figures (each mode adds its own sections).
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "app/json_writer.h"

namespace tandem {

// Throws InputError naming `path` when the report could not be written
// there (a directory, a missing or unwritable directory), so that the
// benchmark fails before it measures anything rather than after.
void check_json_output_path(const std::string& path);

// An object with the facts of this run: "tool", "mode", "date_utc" (ISO
// 8601), "threads" (the worker threads the run may use), "hardware_threads",
// "cpu" (model name, where the system says), "host".
JsonValue bench_report(const std::string& mode, int threads);

// The run facts every mode repeats for its scene: "scene", "width",
// "height", "spp", "max_depth".
void set_render_facts(JsonValue& report, const std::string& scene, uint32_t width, uint32_t height,
                      uint32_t spp, uint32_t max_depth);

// The median of timings or rates (the mean of the middle two for an even
// count; 0 for none): what the modes that repeat a measurement report.
double median(std::vector<double> v);
// The value at fraction p in [0, 1] of the sorted values (the nearest
// rank; 0 for none): frame-time p50 and p99.
double percentile(std::vector<double> v, double p);

// Seconds on the steady clock since `start`: what every mode times with.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The values as a JSON array: the individual runs beside their median.
JsonValue json_number_list(const std::vector<double>& v);

// Writes report.dump() to `path` atomically; no-op without a path.
void write_json_report(const std::optional<std::string>& path, const JsonValue& report);

}  // namespace tandem
