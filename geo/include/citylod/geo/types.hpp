// citylod::geo — shared value types and the error type of the georeferencing library.
//
// Conventions used throughout citylod::geo:
//   * Geodetic coordinates are WGS84 (EPSG:4979) and stored as `LonLatH`:
//     x = longitude [degrees, east positive], y = latitude [degrees], z = ellipsoidal height [m].
//   * "CRS units" are the units of the source CRS's own axes (e.g. international feet for
//     EPSG:2994); the library converts them, callers never pre-scale.
//   * Local coordinates are ENU (east, north, up) metres, float64, at a scene origin.
#pragma once

#include <Eigen/Core>

#include <stdexcept>
#include <string>

namespace citylod::geo {

/// (longitude deg, latitude deg, ellipsoidal height m) on WGS84.
using LonLatH = Eigen::Vector3d;

/// The one exception type of citylod::geo; what() is a single line saying what went wrong.
class GeoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace citylod::geo
