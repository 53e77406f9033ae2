// The one progress type of the city pipeline. Every long library call of
// citylod::tiler (split, the LOD stage, assemble, eval, run_city, rebuild)
// takes a ProgressFn and reports through it; the library never draws
// anything itself (the command line's bar lives in app/progress_bar.*).
#pragma once

#include <cstddef>
#include <exception>
#include <functional>

namespace citylod::tiler {

/// One report of a long task.
struct ProgressEvent {
  const char* task = "";            ///< "split", "lod", "assemble", "eval", "reading tiles"
  double fraction = 0;              ///< of the task, in [0, 1]
  const char* detail = nullptr;     ///< sub-step ("ingest", "writing tiles", ...) or nullptr
  std::size_t done = 0, total = 0;  ///< items done / in the task when it counts items (else 0)
  const char* unit = nullptr;       ///< what the items are ("buildings", "tiles") or nullptr
  bool finished = false;            ///< the task is over (the last event of a task)
};

/// Called from one thread at a time. Return false to cancel: the task then
/// throws tiler::Cancelled (not every task can stop at once; the LOD stage
/// finishes the buildings it is running).
using ProgressFn = std::function<bool(const ProgressEvent&)>;

/// Thrown when a ProgressFn returned false.
struct Cancelled : std::exception {
  const char* what() const noexcept override { return "cancelled"; }
};

/// Calls `fn` (if set) with a fraction-only event; throws Cancelled when it returns false.
void report_progress(const ProgressFn& fn, const char* task, double fraction,
                     const char* detail = nullptr);
/// Calls `fn` (if set) with an item count; throws Cancelled when it returns false.
void report_count(const ProgressFn& fn, const char* task, std::size_t done, std::size_t total,
                  const char* unit);
/// The same without cancellation (inside OpenMP regions): the return value of `fn` is ignored.
void notify_progress(const ProgressFn& fn, const char* task, double fraction,
                     const char* detail = nullptr);
void notify_count(const ProgressFn& fn, const char* task, std::size_t done, std::size_t total,
                  const char* unit);
/// The last event of a task (fraction 1, finished).
void notify_finished(const ProgressFn& fn, const char* task);

}  // namespace citylod::tiler
