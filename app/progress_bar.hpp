// The terminal side of progress: a bar per task, fed by the library's
// ProgressEvents (citylod/tiler/progress.hpp) through ProgressDisplay.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "citylod/tiler/progress.hpp"

namespace citylod::app {

/// A progress display for long stages. On a TTY stderr: a redrawn bar with
/// percentage, rate and ETA; otherwise a plain log line at most every ~2 s.
/// Silent with --quiet or --log-level below info.
///
///   Progress p("reading", total_points, "pts");
///   p.advance(n);  ...  p.finish();
/// or pass it to an io reader taking bool(*)(double, const char*, void*):
///   io::scan_file(path, &Progress::callback, &p);
class Progress {
 public:
  /// `total` in `unit`s (0 = unknown; then only fractions given to update() count).
  explicit Progress(std::string label, std::uint64_t total = 0, std::string unit = "");
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void advance(std::uint64_t n);                              ///< n more units done
  void set_done(std::uint64_t done);                          ///< absolute units done
  void update(double fraction, const char* stage = nullptr);  ///< fraction in [0,1]
  void finish();                                              ///< final line (idempotent)

  /// Adapter for library callbacks; `self` is a Progress*. Always returns true.
  static bool callback(double fraction, const char* stage, void* self);

 private:
  void draw(bool final);

  std::string label_, unit_, stage_;
  std::uint64_t total_ = 0, done_ = 0;
  double fraction_ = 0;
  bool enabled_ = false, tty_ = false, finished_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

/// Draws the events of a library call: one bar per task (a new task finishes
/// the bar of the previous one; a `finished` event finishes its bar).
///
///   ProgressDisplay bars;
///   tiler::run_city(options, bars.fn());
class ProgressDisplay {
 public:
  ProgressDisplay() = default;
  ~ProgressDisplay();
  ProgressDisplay(const ProgressDisplay&) = delete;
  ProgressDisplay& operator=(const ProgressDisplay&) = delete;

  /// The callback to hand to the library; valid while this object lives. Never cancels.
  tiler::ProgressFn fn();
  void finish();  ///< finishes the current bar

 private:
  void on(const tiler::ProgressEvent& e);
  std::string task_;
  std::unique_ptr<Progress> bar_;
};

/// Clears a bar from the last stderr line (before a log line is written).
void clear_progress_bar();

/// "12.3k", "4.56M": compact counts for messages.
std::string human_count(double v);

}  // namespace citylod::app
