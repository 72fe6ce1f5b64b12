#include "core/util/log.h"

#include <atomic>
#include <cstdio>
#include <mutex>
#include <utility>

namespace tandem {
namespace {
std::atomic<int> g_level{int(LogLevel::kWarning)};
std::mutex g_mutex;
LogSink g_sink;  // under g_mutex

void emit(LogLevel level, const char* prefix, const std::string& message) {
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_sink) {
    g_sink(level, message);
    return;
  }
  std::fprintf(stderr, "%s%s\n", prefix, message.c_str());
}
}  // namespace

void set_log_sink(LogSink sink) {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_sink = std::move(sink);
}

void set_log_level(LogLevel level) {
  g_level = int(level);
}
LogLevel log_level() {
  return LogLevel(g_level.load());
}
void log_warning(const std::string& m) {
  if (g_level >= int(LogLevel::kWarning)) emit(LogLevel::kWarning, "tandem: warning: ", m);
}
void log_info(const std::string& m) {
  if (g_level >= int(LogLevel::kInfo)) emit(LogLevel::kInfo, "tandem: ", m);
}
void log_debug(const std::string& m) {
  if (g_level >= int(LogLevel::kDebug)) emit(LogLevel::kDebug, "tandem: debug: ", m);
}

}  // namespace tandem
