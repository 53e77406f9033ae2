// Internal: IO-View analysis (paper Section 4.1): regions of the labelled
// partition, principal primitives and secondary structures.
#pragma once

#include "bsp.hpp"
#include "planes.hpp"

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
  /// per primitive: the V_in/V_out interface lies on its plane (whole faces
  /// counted) over min_principal_area
  std::vector<char> on_surface;
  std::vector<Structure> structures;
  std::vector<int> primitive_structure;  ///< per primitive, -1 when none
};

/// Regions, principal primitives and secondary structures from the labelled
/// IO-View partition. `primitive_plane[i]` is the index of primitive i's plane
/// in bsp.planes().
IoView analyse_io_view(const Bsp& bsp, const std::vector<Primitive>& prims,
                       const std::vector<int>& primitive_plane,
                       const std::vector<char>& leaf_inside, const IoViewParams& p);

/// Index of each primitive's plane in the BSP's plane table (-1 when absent).
std::vector<int> match_planes(const Bsp& bsp, const std::vector<Primitive>& prims);

}  // namespace citylod::lod::detail
