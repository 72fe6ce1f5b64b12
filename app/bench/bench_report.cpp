#include "app/bench/bench_report.h"

#include <unistd.h>

#include <algorithm>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <thread>

#include "core/image/image.h"
#include "core/util/errors.h"

namespace tandem {

namespace fs = std::filesystem;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, size_t(p * double(v.size() - 1) + 0.5));
  return v[i];
}

JsonValue json_number_list(const std::vector<double>& v) {
  JsonValue a = JsonValue::array();
  for (double d : v)
    a.push(d);
  return a;
}

void check_json_output_path(const std::string& path) {
  const std::string what = "--json " + path + ": ";
  if (path.empty()) throw InputError("--json: empty file name");
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(what + "is a directory");
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) {
    throw InputError(what + "cannot write: directory '" + dir.string() + "' does not exist");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw InputError(what + "cannot write: directory '" + dir.string() + "' is not writable");
  }
}

namespace {

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos && colon + 2 <= line.size()) return line.substr(colon + 2);
    }
  }
  return "";
}

std::string host_name() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof(buf) - 1) != 0) return "";
  return buf;
}

}  // namespace

JsonValue bench_report(const std::string& mode, int threads) {
  JsonValue r = JsonValue::object();
  r.set("tool", "tandem bench");
  r.set("mode", mode);
  r.set("date_utc", utc_now_iso8601());
  r.set("threads", threads);
  r.set("hardware_threads", int(std::thread::hardware_concurrency()));
  r.set("cpu", cpu_model());
  r.set("host", host_name());
  return r;
}

void set_render_facts(JsonValue& report, const std::string& scene, uint32_t width, uint32_t height,
                      uint32_t spp, uint32_t max_depth) {
  report.set("scene", scene);
  report.set("width", width);
  report.set("height", height);
  report.set("spp", spp);
  report.set("max_depth", max_depth);
}

void write_json_report(const std::optional<std::string>& path, const JsonValue& report) {
  if (!path) return;
  const std::string text = report.dump();
  write_file_atomically(*path, std::vector<uint8_t>(text.begin(), text.end()));
}

}  // namespace tandem
