// Minimal leveled logging to stderr. Warnings are for things a user should
// know about but that do not stop the job (a missing texture, a fallback).
#pragma once

#include <string>

namespace tandem {

enum class LogLevel { kQuiet = 0, kWarning = 1, kInfo = 2, kDebug = 3 };

void set_log_level(LogLevel level);
LogLevel log_level();
void log_warning(const std::string& message);
void log_info(const std::string& message);
void log_debug(const std::string& message);

}  // namespace tandem
