// The one log sink of the city pipeline. Library code reports what a user
// should know (notes, warnings, per-building problems) through log_*(); the
// program decides where it goes by setting a sink (app/ prints it on stderr,
// filtered by --log-level / --quiet). Without a sink nothing is written.
#pragma once

#include <functional>
#include <string>

namespace citylod::tiler {

enum class LogLevel { error = 0, warn = 1, info = 2, debug = 3 };

/// Receives every message; must be thread-safe (the LOD stage logs from OpenMP threads).
using LogSink = std::function<void(LogLevel, const std::string&)>;

/// Replaces the sink (an empty function discards messages). Not thread-safe:
/// set it once at start-up.
void set_log_sink(LogSink sink);

void log_message(LogLevel level, const std::string& msg);
inline void log_error(const std::string& msg) {
  log_message(LogLevel::error, msg);
}
inline void log_warn(const std::string& msg) {
  log_message(LogLevel::warn, msg);
}
inline void log_info(const std::string& msg) {
  log_message(LogLevel::info, msg);
}
inline void log_debug(const std::string& msg) {
  log_message(LogLevel::debug, msg);
}

}  // namespace citylod::tiler
