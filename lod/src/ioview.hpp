// Internal: IO-View analysis (paper Section 4.1): regions of the labelled
// partition, principal and secondary structures, two-stage clustering into
// level sets, adaptive regularization of secondary structures (with cuboid
// templates for windows), and the scale-sorted primitive order S.
#pragma once

#include "bsp.hpp"
#include "primitives.hpp"

#include <vector>

namespace citylod::lod::detail {

enum class RegionKind { CoreInterior, CoreExterior, AddOn, CutOut };

struct Region {
  RegionKind kind = RegionKind::AddOn;
  bool inside = false;
  double volume = 0.0;
  std::vector<int> leaves;  ///< BSP leaf ids
};

/// A secondary structure (an add-on or cut-out region) and its primitives.
struct Structure {
  int region = -1;
  bool addon = false;
  double volume = 0.0;                        ///< m^3
  int host = -1;                              ///< principal primitive it is attached to (-1: none)
  double projected_area = 0.0;                ///< m^2, contact area on the host primitive
  std::vector<int> primitives;                ///< secondary primitives bounding it
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  ///< bbox of its cells
};

struct IoView {
  std::vector<int> leaves;        ///< IO-View partition (BSP leaves)
  std::vector<char> leaf_inside;  ///< per entry of `leaves`
  std::vector<int> leaf_region;   ///< per entry of `leaves`
  std::vector<Region> regions;
  int core_in = -1, core_out = -1;
  std::vector<char> principal;  ///< per primitive
  std::vector<Structure> structures;
  std::vector<int> primitive_structure;  ///< per primitive, -1 when none
};

/// Regions, principal primitives and secondary structures from the labelled
/// IO-View partition. `primitive_plane[i]` is the index of primitive i's plane
/// in bsp.planes().
IoView analyse_io_view(const Bsp& bsp, const std::vector<Primitive>& prims,
                       const std::vector<int>& primitive_plane,
                       const std::vector<char>& leaf_inside, const IoViewParams& p);

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

/// Adaptive regularization of the secondary structures relative to their host
/// (angle/distance of p), and cuboid templates for clusters of more than three
/// cut-outs on a near-vertical host. New template primitives are appended to
/// `prims` and replace the structure's primitives in its cluster. Returns the
/// number of templates made.
int regularize_secondary(std::vector<Primitive>& prims, Grouping& grouping, const IoView& view,
                         const Bsp& bsp, const Samples& samples, const RegularizationParams& p,
                         const AlphaParams& a);

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

/// Index of each primitive's plane in the BSP's plane table (-1 when absent).
std::vector<int> match_planes(const Bsp& bsp, const std::vector<Primitive>& prims);

}  // namespace citylod::lod::detail
