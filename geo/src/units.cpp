#include "citylod/geo/units.hpp"

#include "citylod/geo/transformer.hpp"
#include "proj_util.hpp"

#include <cmath>

namespace citylod::geo {

namespace {

bool lands_in_area(const Crs& crs, const Eigen::AlignedBox3d& bbox) {
  try {
    Transformer t(crs, {HeightMode::Ellipsoidal});
    t.check_in_area(bbox);
    return true;
  } catch (const GeoError&) {
    return false;
  }
}

}  // namespace

UnitReport check_units(const Crs& crs, const Eigen::AlignedBox3d& bbox) {
  UnitReport r;
  r.horizontal_to_metre = crs.horizontal_unit().angular ? 1.0 : crs.horizontal_unit().to_si;
  r.vertical_to_metre = crs.vertical_unit().to_si;
  if (bbox.isEmpty()) return r;

  if (crs.is_projected() && crs.area_of_use() && !lands_in_area(crs, bbox)) {
    const bool is_feet = std::abs(crs.horizontal_unit().to_si - 1.0) > 1e-9;
    const Unit other = is_feet ? Unit{"metre", 1.0, false} : Unit{"foot", 0.3048, false};
    if (lands_in_area(detail::with_horizontal_unit(crs, other), bbox))
      r.warnings.push_back("the data lies outside the area of use of " + crs.label() + " in " +
                           crs.horizontal_unit().name + " but inside it if read in " + other.name +
                           ": are the coordinates really in " + crs.horizontal_unit().name + "?");
  }
  const double zlo = bbox.min().z() * r.vertical_to_metre,
               zhi = bbox.max().z() * r.vertical_to_metre;
  if (zlo < -500.0 || zhi > 9000.0)
    r.warnings.push_back("heights " + detail::fmt(zlo, 6) + ".." + detail::fmt(zhi, 6) +
                         " m (z in " + crs.vertical_unit().name +
                         ") are outside -500..9000 m: wrong vertical unit?");
  return r;
}

}  // namespace citylod::geo
