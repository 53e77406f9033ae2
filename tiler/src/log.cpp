// The log sink and the progress helpers (log.hpp, progress.hpp).
#include "citylod/tiler/log.hpp"

#include "citylod/tiler/progress.hpp"

namespace citylod::tiler {

namespace {
LogSink& sink() {
  static LogSink s;
  return s;
}
}  // namespace

void set_log_sink(LogSink s) {
  sink() = std::move(s);
}

void log_message(LogLevel level, const std::string& msg) {
  const LogSink& s = sink();
  if (!s) return;
  try {
    s(level, msg);
  } catch (...) {  // logging never throws
  }
}

namespace {
ProgressEvent fraction_event(const char* task, double fraction, const char* detail) {
  ProgressEvent e;
  e.task = task;
  e.fraction = fraction;
  e.detail = detail;
  return e;
}
ProgressEvent count_event(const char* task, std::size_t done, std::size_t total, const char* unit) {
  ProgressEvent e;
  e.task = task;
  e.fraction = total ? double(done) / double(total) : 1.0;
  e.done = done;
  e.total = total;
  e.unit = unit;
  return e;
}
}  // namespace

void report_progress(const ProgressFn& fn, const char* task, double fraction, const char* detail) {
  if (fn && !fn(fraction_event(task, fraction, detail))) throw Cancelled();
}
void report_count(const ProgressFn& fn, const char* task, std::size_t done, std::size_t total,
                  const char* unit) {
  if (fn && !fn(count_event(task, done, total, unit))) throw Cancelled();
}
void notify_progress(const ProgressFn& fn, const char* task, double fraction, const char* detail) {
  if (fn) fn(fraction_event(task, fraction, detail));
}
void notify_count(const ProgressFn& fn, const char* task, std::size_t done, std::size_t total,
                  const char* unit) {
  if (fn) fn(count_event(task, done, total, unit));
}
void notify_finished(const ProgressFn& fn, const char* task) {
  if (!fn) return;
  ProgressEvent e = fraction_event(task, 1.0, nullptr);
  e.finished = true;
  fn(e);
}

}  // namespace citylod::tiler
