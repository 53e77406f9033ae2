// What every `threads` of citylod means: the number of threads to use, 0 =
// all cores. Results never depend on it.
#pragma once

#include <thread>

namespace citylod::tiler {

/// `requested` when > 0, else the number of cores (at least 1). Does not
/// touch OpenMP (safe before supervise() forks).
inline int resolve_threads(int requested) {
  if (requested > 0) return requested;
  const unsigned n = std::thread::hardware_concurrency();
  return n > 0 ? int(n) : 1;
}

}  // namespace citylod::tiler
