#include "progress_bar.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli.hpp"

namespace citylod::app {

namespace detail {
// Set while a TTY bar occupies the last stderr line (log lines clear it first).
bool g_bar_on_screen = false;
}  // namespace detail

std::string human_count(double v) {
  char b[32];
  const char* suffix[] = {"", "k", "M", "G", "T"};
  int i = 0;
  while (std::abs(v) >= 1000.0 && i < 4) {
    v /= 1000.0;
    ++i;
  }
  if (i == 0)
    std::snprintf(b, sizeof b, "%.0f", v);
  else
    std::snprintf(b, sizeof b, v < 10 ? "%.2f%s" : (v < 100 ? "%.1f%s" : "%.0f%s"), v, suffix[i]);
  return b;
}

namespace {
std::string duration(double s) {
  if (!(s >= 0) || s > 1e7) return "--";
  char b[32];
  long t = std::lround(s);
  if (t >= 3600)
    std::snprintf(b, sizeof b, "%ldh%02ldm", t / 3600, (t / 60) % 60);
  else if (t >= 60)
    std::snprintf(b, sizeof b, "%ldm%02lds", t / 60, t % 60);
  else
    std::snprintf(b, sizeof b, "%lds", t);
  return b;
}
}  // namespace

Progress::Progress(std::string label, std::uint64_t total, std::string unit)
    : label_(std::move(label)), unit_(std::move(unit)), total_(total) {
  enabled_ = !quiet() && log_level() >= LogLevel::info;
  tty_ = ::isatty(STDERR_FILENO) != 0;
  start_ = last_ = std::chrono::steady_clock::now();
}

Progress::~Progress() {
  if (tty_ && detail::g_bar_on_screen && !finished_) {
    std::fputs("\r\033[K", stderr);
    detail::g_bar_on_screen = false;
  }
}

void Progress::advance(std::uint64_t n) {
  set_done(done_ + n);
}

void Progress::set_done(std::uint64_t done) {
  done_ = done;
  if (total_ > 0)
    fraction_ = std::min(1.0, static_cast<double>(done_) / static_cast<double>(total_));
  draw(false);
}

void Progress::update(double fraction, const char* stage) {
  fraction_ = std::clamp(fraction, 0.0, 1.0);
  if (stage) stage_ = stage;
  if (total_ > 0) done_ = static_cast<std::uint64_t>(fraction_ * static_cast<double>(total_));
  draw(false);
}

void Progress::finish() {
  if (finished_) return;
  fraction_ = 1.0;
  if (total_ > 0) done_ = std::max(done_, total_);
  draw(true);
  finished_ = true;
}

bool Progress::callback(double fraction, const char* stage, void* self) {
  static_cast<Progress*>(self)->update(fraction, stage);
  return true;
}

void Progress::draw(bool final) {
  if (!enabled_ || finished_) return;
  auto now = std::chrono::steady_clock::now();
  const double since_last = std::chrono::duration<double>(now - last_).count();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double min_interval = tty_ ? 0.1 : 2.0;
  if (!final && since_last < min_interval) return;
  if (!tty_ && final && elapsed < 2.0) return;  // short stages: no log noise
  last_ = now;

  std::string rate;
  if (elapsed > 0 && !unit_.empty() && done_ > 0)
    rate = human_count(static_cast<double>(done_) / elapsed) + " " + unit_ + "/s";
  std::string eta =
      final ? duration(elapsed)
            : (fraction_ > 0.001 ? duration(elapsed * (1 - fraction_) / fraction_) : "--");
  std::string what = label_ + (stage_.empty() ? "" : " (" + stage_ + ")");
  char pct[16];
  std::snprintf(pct, sizeof pct, "%5.1f%%", 100.0 * fraction_);

  if (tty_) {
    const int width = 28;
    int fill = static_cast<int>(fraction_ * width + 0.5);
    std::string bar(static_cast<std::size_t>(fill), '#');
    bar.resize(width, '.');
    std::fprintf(stderr, "\r\033[K%s [%s] %s  %s  %s %s", what.c_str(), bar.c_str(), pct,
                 rate.c_str(), final ? "in" : "ETA", eta.c_str());
    if (final) {
      std::fputc('\n', stderr);
      detail::g_bar_on_screen = false;
    } else {
      detail::g_bar_on_screen = true;
    }
    std::fflush(stderr);
  } else {
    std::string line = what + ": " + pct;
    if (!rate.empty()) line += ", " + rate;
    line += final ? ", done in " + eta : ", ETA " + eta;
    log_info(line);
  }
}

// ------------------------------------------------------------ ProgressDisplay
void clear_progress_bar() {
  if (detail::g_bar_on_screen) {
    std::fputs("\r\033[K", stderr);
    detail::g_bar_on_screen = false;
  }
}

ProgressDisplay::~ProgressDisplay() {
  finish();
}

tiler::ProgressFn ProgressDisplay::fn() {
  return [this](const tiler::ProgressEvent& e) {
    on(e);
    return true;
  };
}

void ProgressDisplay::finish() {
  if (bar_) bar_->finish();
  bar_.reset();
  task_.clear();
}

void ProgressDisplay::on(const tiler::ProgressEvent& e) {
  const std::string task = e.task ? e.task : "";
  if (!bar_ || task != task_) {
    finish();
    if (e.finished) return;  // a task that never reported: nothing to show
    task_ = task;
    bar_ = std::make_unique<Progress>(task, e.total, e.unit ? e.unit : "");
  }
  if (e.finished) {
    finish();
  } else if (e.total > 0) {
    bar_->set_done(e.done);
  } else {
    bar_->update(e.fraction, e.detail);
  }
}

}  // namespace citylod::app
