// citylod::geo::LocalFrame — a local East-North-Up frame at an origin on the WGS84 ellipsoid.
#pragma once

#include "citylod/geo/types.hpp"

#include <Eigen/Geometry>

#include <array>
#include <string>

namespace citylod::geo {

/// A 3D Tiles bounding region: angles in radians, heights in metres above the WGS84 ellipsoid.
struct BoundingRegion {
  double west = 0, south = 0, east = 0, north = 0;  ///< radians
  double min_height = 0, max_height = 0;            ///< metres (ellipsoidal)
  /// [west, south, east, north, minimum height, maximum height], the tileset.json "region".
  std::array<double, 6> to_array() const {
    return {west, south, east, north, min_height, max_height};
  }
};

/// ENU frame at an origin (GeographicLib LocalCartesian on WGS84). Stateless after
/// construction: all member functions are const and thread-safe.
class LocalFrame {
 public:
  /// Origin as (lon deg, lat deg, ellipsoidal h m).
  explicit LocalFrame(const LonLatH& origin);

  const LonLatH& origin() const { return origin_; }
  Eigen::Vector3d origin_ecef() const { return origin_ecef_; }  ///< metres, ECEF (EPSG:4978)

  Eigen::Vector3d geodetic_to_enu(const LonLatH& geodetic) const;  ///< -> ENU metres
  LonLatH enu_to_geodetic(const Eigen::Vector3d& enu) const;       ///< ENU metres -> LonLatH
  Eigen::Vector3d enu_to_ecef(const Eigen::Vector3d& enu) const;   ///< metres -> metres
  Eigen::Vector3d ecef_to_enu(const Eigen::Vector3d& ecef) const;  ///< metres -> metres

  /// 4x4 ENU -> ECEF matrix, column-major (3D Tiles root `transform`): columns are the east,
  /// north and up unit vectors and the origin's ECEF position.
  std::array<double, 16> enu_to_ecef_matrix() const;

  /// Region enclosing an ENU box (metres): corners, edge points and the point nearest the
  /// origin's vertical are sampled and the result padded by ~1 cm. Assumes the box does not
  /// cross the antimeridian or a pole.
  BoundingRegion bounding_region(const Eigen::AlignedBox3d& enu_box) const;

 private:
  LonLatH origin_;
  Eigen::Vector3d origin_ecef_;
  Eigen::Matrix3d enu_to_ecef_rot_;  // columns: east, north, up
};

/// Parses the CLI form "LAT,LON,H" (degrees, degrees, ellipsoidal metres) into a LonLatH.
/// Throws GeoError on malformed input or out-of-range latitude/longitude.
LonLatH parse_origin(const std::string& lat_lon_h);

}  // namespace citylod::geo
