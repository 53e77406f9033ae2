// What every `threads` of citylod means: the number of threads to use, 0 =
// all cores. Results never depend on it.
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace citylod::tiler {

/// `requested` when > 0, else the number of cores (at least 1). Does not
/// touch OpenMP (safe before supervise() forks).
inline int resolve_threads(int requested) {
  if (requested > 0) return requested;
  const unsigned n = std::thread::hardware_concurrency();
  return n > 0 ? int(n) : 1;
}

/// Runs `worker()` on min(resolve_threads(requested), jobs) std::threads (on this
/// thread when that is 1) and joins them: each worker takes jobs from a shared
/// counter. std::thread, not OpenMP: `citylod tile` forks its LOD stage after the
/// split, and a child forked after the parent used OpenMP cannot start a team.
template <class Worker>
void run_workers(int requested, std::size_t jobs, Worker&& worker) {
  const std::size_t k =
      std::min<std::size_t>(std::size_t(std::max(1, resolve_threads(requested))), jobs);
  if (k <= 1) {
    worker();
    return;
  }
  std::vector<std::thread> pool;
  for (std::size_t t = 0; t < k; ++t) pool.emplace_back([&worker] { worker(); });
  for (auto& t : pool) t.join();
}

}  // namespace citylod::tiler
