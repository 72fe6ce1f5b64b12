// The start that every `tandem bench ... --MODE` shares: whether its flag
// was given, its help, the --threads cap and the --json path checked before
// anything is measured. One place, so that the modes cannot drift apart.
#pragma once

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "app/bench/bench_report.h"
#include "app/cli_args.h"

namespace tandem {

inline bool has_bench_flag(const std::vector<std::string>& args, const char* flag) {
  return std::find(args.begin(), args.end(), flag) != args.end();
}

// Prints "usage: USAGE" and the option table when -h/--help was given; the
// caller then returns 0.
inline bool print_bench_help(const ParsedArgs& args, const std::string& usage,
                             const std::vector<OptionSpec>& table) {
  if (!args.has("help")) return false;
  std::printf("usage: %s\n\n%s", usage.c_str(), format_options_help(table).c_str());
  return true;
}

// --threads N caps TBB (and Embree, which runs on it) for as long as this
// lives; without it every core is used.
class BenchThreads {
 public:
  explicit BenchThreads(const ParsedArgs& args) : count_(args.get_u32("threads", 0, 1, 4096)) {
    if (count_) limit_.emplace(tbb::global_control::max_allowed_parallelism, count_);
  }
  uint32_t requested() const { return count_; }  // 0: not given
  int used() const { return count_ ? int(count_) : tbb::info::default_concurrency(); }

 private:
  uint32_t count_;
  std::optional<tbb::global_control> limit_;
};

// --json FILE with its directory checked now, so that a bad path fails
// before the benchmark measures anything rather than after.
inline std::optional<std::string> checked_json_path(const ParsedArgs& args) {
  std::optional<std::string> path = args.value("json");
  if (path) check_json_output_path(*path);
  return path;
}

}  // namespace tandem
