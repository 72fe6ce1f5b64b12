// Minimal leveled logging. Warnings are for things a user should know about
// but that do not stop the job (a missing texture, a fallback). They go to
// stderr unless a sink takes them: the embedding API hands them to its
// host's callback, or to nobody (api/tandem/tandem.h).
#pragma once

#include <functional>
#include <string>

namespace tandem {

enum class LogLevel { kQuiet = 0, kWarning = 1, kInfo = 2, kDebug = 3 };

void set_log_level(LogLevel level);
LogLevel log_level();
void log_warning(const std::string& message);
void log_info(const std::string& message);
void log_debug(const std::string& message);

// Where messages at or under the level go instead of stderr (called under a
// lock, one message at a time, from any thread); empty: stderr, prefixed
// "tandem: warning: " and so on.
using LogSink = std::function<void(LogLevel level, const std::string& message)>;
void set_log_sink(LogSink sink);

}  // namespace tandem
