// Internal: two-stage clustering of IO-View's secondary structures into level
// sets (paper Section 4.1), and the scale-sorted primitive order S.
#pragma once

#include "ioview.hpp"

#include <string>
#include <vector>

namespace citylod::lod::detail {

/// Mean shift with a flat kernel of radius `bandwidth` on 1D values.
/// Returns a cluster id per value; clusters are numbered by increasing mode.
/// Deterministic (no randomness, stable for equal inputs).
std::vector<int> mean_shift_1d(const std::vector<double>& values, double bandwidth);

/// Grouping of structures: clusters (stage 1, per host) and level sets (stage 2).
struct Grouping {
  struct Cluster {
    int host = -1;
    std::vector<int> structures;
    std::vector<int> primitives;  ///< sorted by area, descending
    double mean_volume = 0.0;
    int level = 0;  ///< 1..N_l
    int cutouts = 0;
  };
  std::vector<Cluster> clusters;  ///< sorted: by level, then mean volume descending
  int num_level_sets = 0;         ///< N_l
};
Grouping group_structures(const IoView& view, const std::vector<Primitive>& prims,
                          const ClusterParams& p);

/// The scale-sorted order S = S0 (principal by area) then each level set's
/// clusters and primitives. level_of[i] / cluster_of[i] per primitive (-1 when
/// not in S).
struct SortedPrimitives {
  std::vector<int> order;
  std::vector<int> level_of;
  std::vector<int> cluster_of;
  int num_levels = 1;  ///< N_l + 1 (S0..S_Nl)
};
SortedPrimitives sort_primitives(const std::vector<Primitive>& prims, const IoView& view,
                                 const Grouping& grouping);
/// With ioview.covered_only: the primitives the V_in/V_out interface lies on
/// (view.on_surface) whose alpha-shapes cover too little of it to be principal
/// and that are in no level set, placed by `rule`: Noise leaves them out of
/// S, S0 puts them in S0 after the principal primitives, Last makes them
/// one more, last level set (largest alpha-shape first). Returns how many.
int place_uncovered(const std::vector<Primitive>& prims, const IoView& view, Uncovered rule,
                    SortedPrimitives& sorted);

}  // namespace citylod::lod::detail
