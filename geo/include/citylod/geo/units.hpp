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

/// The decisive form of the first check above, for a projected CRS with an area of use: the
/// data's box (CRS units; corners, edge midpoints and centre) is not entirely inside the area
/// of use read in the CRS's horizontal unit, but entirely inside it read in the other unit
/// (metre <-> foot), both without any margin. Returns the one-line reason ("the data lies ...
/// are the coordinates in metre, not US survey foot?"), or "" when the data is consistent
/// with the unit or the test cannot tell (no area of use, inside or outside both ways).
/// Catches a metre data set given a state-plane feet CRS, which shrinks towards the false
/// origin and can stay within the usual 1-degree tolerance of the area test.
std::string unit_swap_evidence(const Crs& crs, const Eigen::AlignedBox3d& bbox);

/// A scene narrower than this (metres, the wider of x and y) is no scene of buildings.
inline constexpr double kMinSceneAcross_m = 1.0;
/// ... and one wider than this is beyond what any projected CRS maps (half the equator).
inline constexpr double kMaxSceneAcross_m = 2.0e7;

/// The scale check of the horizontal unit, for a projected CRS whatever its area of use: the
/// data's box (CRS units) read in the CRS's unit spans less than kMinSceneAcross_m while
/// spanning at least one unit (a WKT in nanometres over metre data: 72 m read as 72 micrometres),
/// or more than kMaxSceneAcross_m. Returns the one-line reason, or "" when the size is plausible.
std::string unit_scale_evidence(const Crs& crs, const Eigen::AlignedBox3d& bbox);

/// Compares a CRS given by the user (--crs) with the units of the CRS a file declares
/// (`file_unit_m`: metres per horizontal unit, 0 = unknown; `file_vertical_unit_m`: metres per
/// vertical unit, 0 = unknown). Returns "" when they agree (within 1e-6, so foot and US survey
/// foot are one unit here) or are unknown, else the one-line reason: "the file's CRS record
/// (...) is in metre but --crs EPSG:2992 is in foot: ...".
std::string declared_unit_conflict(const Crs& declared, const std::string& file_crs_name,
                                   double file_unit_m, double file_vertical_unit_m);

}  // namespace citylod::geo
