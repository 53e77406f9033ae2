// Internal: 1D mean-shift clustering (flat kernel), used by the two-stage
// clustering of IO-View (projected areas, then cluster volumes).
#pragma once

#include <vector>

namespace citylod::lod::detail {

/// Mean shift with a flat kernel of radius `bandwidth` on 1D values.
/// Returns a cluster id per value; clusters are numbered by increasing mode.
/// Deterministic (no randomness, stable for equal inputs).
std::vector<int> mean_shift_1d(const std::vector<double>& values, double bandwidth);

}  // namespace citylod::lod::detail
