#include "citylod/geo/units.hpp"

#include "citylod/geo/transformer.hpp"
#include "proj_util.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>

namespace citylod::geo {

namespace {

/// The horizontal Transformer of `crs`, kept per thread for the next call: a split asks
/// unit_swap_evidence and check_units about the same CRS, and each set-up costs 20-30 ms.
Transformer& horizontal_transformer(const Crs& crs) {
  thread_local std::map<std::string, std::unique_ptr<Transformer>> kept;
  auto it = kept.find(crs.definition());
  if (it == kept.end()) {
    if (kept.size() >= 8) kept.clear();
    it = kept.emplace(crs.definition(),
                      std::make_unique<Transformer>(crs, TransformOptions{HeightMode::Ellipsoidal}))
             .first;
  }
  return *it->second;
}

bool lands_in_area(const Crs& crs, const Eigen::AlignedBox3d& bbox, double margin_deg = 1.0) {
  try {
    horizontal_transformer(crs).check_in_area(bbox, margin_deg);
    return true;
  } catch (const GeoError&) {
    return false;
  }
}

bool is_metre(const Unit& u) {
  return std::abs(u.to_si - 1.0) < 1e-9;
}

std::string unit_label(double to_m) {
  if (std::abs(to_m - 1.0) < 1e-9) return "metre";
  if (std::abs(to_m - 0.3048) < 1e-6) return "foot";
  return detail::fmt(to_m, 10) + " m units";
}

}  // namespace

std::string unit_swap_evidence(const Crs& crs, const Eigen::AlignedBox3d& bbox) {
  if (bbox.isEmpty() || !crs.is_projected() || !crs.area_of_use()) return {};
  const Unit& unit = crs.horizontal_unit();
  const Unit other = is_metre(unit) ? Unit{"foot", 0.3048, false} : Unit{"metre", 1.0, false};
  if (lands_in_area(crs, bbox, 0.0)) return {};
  const Crs swapped = detail::with_horizontal_unit(crs, other);
  if (!lands_in_area(swapped, bbox, 0.0)) return {};
  return "the data lies outside the area of use of " + crs.label() + " read in " + unit.name +
         " but inside it read in " + other.name + ": are the coordinates in " + other.name +
         ", not " + unit.name + "? Give the CRS of the data's real unit (--crs)";
}

std::string unit_scale_evidence(const Crs& crs, const Eigen::AlignedBox3d& bbox) {
  if (bbox.isEmpty() || !crs.is_projected()) return {};
  const Unit& unit = crs.horizontal_unit();
  const Eigen::Vector3d size = bbox.sizes();
  const double across = std::max(size.x(), size.y());  // CRS units
  const double across_m = across * unit.to_si;
  std::string what;
  if (across >= 1.0 && across_m < kMinSceneAcross_m)
    what = "smaller than any building";
  else if (across_m > kMaxSceneAcross_m)
    what = "wider than a projected CRS reaches";
  if (what.empty()) return {};
  const std::string per = detail::fmt(unit.to_si, 10) + " m";
  const std::string name = unit.name.empty() || unit.name == "unknown"
                               ? "units of " + per
                               : unit.name + " (" + per + ")";
  return "the data spans " + detail::fmt(size.x() * unit.to_si, 3) + " x " +
         detail::fmt(size.y() * unit.to_si, 3) + " m read in " + name + ", " + what +
         ": are the coordinates really in " + name +
         "? Give the CRS of the data's real unit (--crs)";
}

std::string declared_unit_conflict(const Crs& declared, const std::string& file_crs_name,
                                   double file_unit_m, double file_vertical_unit_m) {
  const std::string file_crs =
      file_crs_name.empty()
          ? std::string("the file's CRS record")
          : "the file's CRS record (" +
                (file_crs_name.size() > 80 ? file_crs_name.substr(0, 77) + "..." : file_crs_name) +
                ")";
  const Unit& hu = declared.horizontal_unit();
  if (file_unit_m > 0 && !hu.angular && std::abs(file_unit_m - hu.to_si) > 1e-6)
    return file_crs + " is in " + unit_label(file_unit_m) + " but --crs " + declared.label() +
           " is in " + hu.name + ": x, y would be scaled by " +
           detail::fmt(hu.to_si / file_unit_m, 6) +
           "; give a --crs in the file's unit (or none: the file's CRS is used)";
  const Unit& vu = declared.vertical_unit();
  if (file_vertical_unit_m > 0 && std::abs(file_vertical_unit_m - vu.to_si) > 1e-6)
    return file_crs + " has heights in " + unit_label(file_vertical_unit_m) + " but --crs " +
           declared.label() + " has them in " + vu.name + ": z would be scaled by " +
           detail::fmt(vu.to_si / file_vertical_unit_m, 6) +
           "; give a --crs in the file's units (or none: the file's CRS is used)";
  return {};
}

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
