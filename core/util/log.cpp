#include "core/util/log.h"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace tandem {
namespace {
std::atomic<int> g_level{int(LogLevel::kWarning)};
std::mutex g_mutex;

void emit(const char* prefix, const std::string& message) {
  std::lock_guard<std::mutex> lock(g_mutex);
  std::fprintf(stderr, "%s%s\n", prefix, message.c_str());
}
}  // namespace

void set_log_level(LogLevel level) {
  g_level = int(level);
}
LogLevel log_level() {
  return LogLevel(g_level.load());
}
void log_warning(const std::string& m) {
  if (g_level >= int(LogLevel::kWarning)) emit("tandem: warning: ", m);
}
void log_info(const std::string& m) {
  if (g_level >= int(LogLevel::kInfo)) emit("tandem: ", m);
}
void log_debug(const std::string& m) {
  if (g_level >= int(LogLevel::kDebug)) emit("tandem: debug: ", m);
}

}  // namespace tandem
