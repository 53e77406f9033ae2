// citylod::geo units sanity — catch the feet-vs-metres mistake before it ruins a tileset.
#pragma once

#include "citylod/geo/crs.hpp"

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace citylod::geo {

struct UnitReport {
  double horizontal_to_metre = 1.0;   ///< factor applied to x, y (1 for geographic CRSes)
  double vertical_to_metre = 1.0;     ///< factor applied to z
  std::vector<std::string> warnings;  ///< empty when nothing looks wrong
};

/// Reports the unit factors the transform applies for `crs` and looks for signs that the data
/// is not in the units the CRS claims. `bbox` is the data's box in CRS units. Checks:
///   * the box lies outside the area of use as declared, but inside if metres and feet are
///     swapped (the classic LAS mistake: a metre EPSG code on feet data, or the reverse);
///   * heights (z times the vertical factor) outside -500..9000 m.
/// Never throws for suspicious data (only for an untransformable CRS); callers decide.
UnitReport check_units(const Crs& crs, const Eigen::AlignedBox3d& bbox);

}  // namespace citylod::geo
