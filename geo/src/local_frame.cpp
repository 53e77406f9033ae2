#include "citylod/geo/local_frame.hpp"

#include "proj_util.hpp"

#include <GeographicLib/Geocentric.hpp>
#include <algorithm>

#include <cmath>
#include <locale>
#include <sstream>

namespace citylod::geo {

namespace {
const GeographicLib::Geocentric& earth() {
  return GeographicLib::Geocentric::WGS84();
}
constexpr double kDeg = M_PI / 180.0;
}  // namespace

LocalFrame::LocalFrame(const LonLatH& origin) : origin_(origin) {
  if (!origin.allFinite() || std::abs(origin.y()) > 90.0)
    throw GeoError("invalid local frame origin (lon " + detail::fmt(origin.x()) + ", lat " +
                   detail::fmt(origin.y()) + ", h " + detail::fmt(origin.z()) + ")");
  earth().Forward(origin.y(), origin.x(), origin.z(), origin_ecef_.x(), origin_ecef_.y(),
                  origin_ecef_.z());
  const double sp = std::sin(origin.y() * kDeg), cp = std::cos(origin.y() * kDeg);
  const double sl = std::sin(origin.x() * kDeg), cl = std::cos(origin.x() * kDeg);
  enu_to_ecef_rot_.col(0) << -sl, cl, 0;
  enu_to_ecef_rot_.col(1) << -sp * cl, -sp * sl, cp;
  enu_to_ecef_rot_.col(2) << cp * cl, cp * sl, sp;
}

Eigen::Vector3d LocalFrame::geodetic_to_enu(const LonLatH& g) const {
  Eigen::Vector3d ecef;
  earth().Forward(g.y(), g.x(), g.z(), ecef.x(), ecef.y(), ecef.z());
  return ecef_to_enu(ecef);
}

LonLatH LocalFrame::enu_to_geodetic(const Eigen::Vector3d& enu) const {
  const Eigen::Vector3d ecef = enu_to_ecef(enu);
  LonLatH g;
  earth().Reverse(ecef.x(), ecef.y(), ecef.z(), g.y(), g.x(), g.z());
  return g;
}

Eigen::Vector3d LocalFrame::enu_to_ecef(const Eigen::Vector3d& enu) const {
  return origin_ecef_ + enu_to_ecef_rot_ * enu;
}

Eigen::Vector3d LocalFrame::ecef_to_enu(const Eigen::Vector3d& ecef) const {
  return enu_to_ecef_rot_.transpose() * (ecef - origin_ecef_);
}

std::array<double, 16> LocalFrame::enu_to_ecef_matrix() const {
  std::array<double, 16> m{};
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) m[4 * c + r] = enu_to_ecef_rot_(r, c);
  for (int r = 0; r < 3; ++r) m[12 + r] = origin_ecef_[r];
  m[15] = 1.0;
  return m;
}

BoundingRegion LocalFrame::bounding_region(const Eigen::AlignedBox3d& box) const {
  if (box.isEmpty()) throw GeoError("bounding_region: empty box");
  // Sample a 5 x 5 grid on the bottom and top faces, plus the points of both faces nearest the
  // origin's vertical (lowest ellipsoidal height of a flat face is there).
  constexpr int kSteps = 4;
  BoundingRegion r{1e9, 1e9, -1e9, -1e9, 1e300, -1e300};
  auto add = [&](const Eigen::Vector3d& enu) {
    const LonLatH g = enu_to_geodetic(enu);
    r.west = std::min(r.west, g.x() * kDeg);
    r.east = std::max(r.east, g.x() * kDeg);
    r.south = std::min(r.south, g.y() * kDeg);
    r.north = std::max(r.north, g.y() * kDeg);
    r.min_height = std::min(r.min_height, g.z());
    r.max_height = std::max(r.max_height, g.z());
  };
  const Eigen::Vector3d lo = box.min(), hi = box.max();
  for (double z : {lo.z(), hi.z()}) {
    for (int i = 0; i <= kSteps; ++i)
      for (int j = 0; j <= kSteps; ++j)
        add({lo.x() + (hi.x() - lo.x()) * i / kSteps, lo.y() + (hi.y() - lo.y()) * j / kSteps, z});
    add({std::clamp(0.0, lo.x(), hi.x()), std::clamp(0.0, lo.y(), hi.y()), z});
  }
  // Pad: ~1 cm in angle (1.6e-9 rad) and height, against sampling between grid points.
  constexpr double kPadRad = 1.6e-9, kPadM = 0.01;
  r.west -= kPadRad;
  r.south -= kPadRad;
  r.east += kPadRad;
  r.north += kPadRad;
  r.min_height -= kPadM;
  r.max_height += kPadM;
  return r;
}

LonLatH parse_origin(const std::string& text) {
  std::istringstream is(text);
  is.imbue(std::locale::classic());
  double lat, lon, h;
  char c1 = 0, c2 = 0;
  if (!(is >> lat >> c1 >> lon >> c2 >> h) || c1 != ',' || c2 != ',' || !(is >> std::ws).eof())
    throw GeoError("invalid origin '" + text + "': expected LAT,LON,H (degrees, degrees, metres)");
  if (std::abs(lat) > 90.0 || std::abs(lon) > 180.0)
    throw GeoError("invalid origin '" + text +
                   "': latitude must be in [-90, 90], longitude in "
                   "[-180, 180] (order is LAT,LON,H)");
  return {lon, lat, h};
}

}  // namespace citylod::geo
