// The split's georeferencing: the scene's CRS (--crs, the files' own, sidecars) or
// local frame (--origin), heights (--geoid, --vertical), the scene frame and the inputs'
// common coordinate grid; and the memory plan (the cell size the budget allows).
#include <algorithm>
#include <cmath>
#include <exception>

#include "citylod/geo/units.hpp"
#include "citylod/geo/vertical.hpp"
#include "citylod/tiler/option_names.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

namespace {

std::string crs_spec_of(const io::FileInfo& i) {
  if (!i.crs_wkt.empty()) return i.crs_wkt;
  if (i.epsg)
    return "EPSG:" + std::to_string(i.epsg) +
           (i.vertical_epsg ? "+" + std::to_string(i.vertical_epsg) : "");
  return {};
}

/// --crs against the CRS record of a LAS/LAZ file: a unit mismatch (a feet --crs on a
/// file whose record says metres, or the reverse), as geo::declared_unit_conflict words
/// it; "" when they agree or the file says nothing.
std::string unit_conflict(const geo::Crs& declared, const io::FileInfo& info) {
  if (info.format != io::Format::las && info.format != io::Format::laz) return {};
  double unit_m = info.linear_unit_m;
  if (unit_m <= 0 && info.epsg) {
    try {
      const geo::Crs c = geo::Crs::parse("EPSG:" + std::to_string(info.epsg));
      if (c.is_projected()) unit_m = c.horizontal_unit().to_si;
    } catch (const std::exception&) {
    }
  }
  const std::string name = !info.crs_name.empty() ? info.crs_name
                           : info.epsg            ? "EPSG:" + std::to_string(info.epsg)
                                                  : std::string();
  return geo::declared_unit_conflict(declared, name, unit_m, info.vertical_unit_m);
}

}  // namespace

// ---------------------------------------------------------------------- georeferencing
/// The scene origin's x and y are multiples of this (CRS units).
constexpr double kOriginGrid = 100;

void Splitter::georeference() {
  const std::string label = inputs_label(inputs_);
  try {
    std::string origin = opt_.origin;
    if (origin.empty() && opt_.crs.empty()) {  // metadata.xml <SRS>ENU:lat,lon for every input
      for (const auto& in : inputs_)
        if (in.sidecar_origin.empty() || in.sidecar_origin != inputs_.front().sidecar_origin ||
            !crs_spec_of(in.info).empty()) {
          origin.clear();
          break;
        } else {
          origin = in.sidecar_origin;
        }
    }
    if (!origin.empty()) {
      georef_.emplace(geo::Georef::local(geo::parse_origin(origin)));
      rep_.notes.push_back(
          std::string("data in a local ENU frame at ") +
          (opt_.origin.empty() ? std::string("metadata.xml ENU:") : option_name("origin") + " ") +
          origin + " (no CRS)");
      return;
    }
    if (!opt_.crs.empty()) {
      crs_spec_ = opt_.crs;
    } else {
      for (const auto& in : inputs_) {
        std::string s = crs_spec_of(in.info);
        if (s.empty()) s = in.sidecar_crs;
        if (s.empty())
          throw IoError(in.path,
                        "no CRS in the file (nor in a .prj or metadata.xml beside it); pass " +
                            option_name("crs") + " EPSG:nnnn (or " + option_name("origin") +
                            " LAT,LON,H for local data)");
        if (!crs_spec_.empty() && s != crs_spec_)
          throw IoError(in.path, "its CRS differs from that of " + inputs_.front().path +
                                     "; pass " + option_name("crs"));
        crs_spec_ = s;
      }
    }
    crs_.emplace(geo::Crs::parse(crs_spec_));
    crs_->require_projected("to split a scene");
    if (!opt_.crs.empty())
      for (const auto& in : inputs_) {
        const std::string conflict = unit_conflict(*crs_, in.info);
        if (!conflict.empty()) throw IoError(in.path, conflict);
      }
    if (opt_.geoid ==
        SplitOptions::Geoid::egm96) {  // the explicit model wins over the CRS's (implied) datum
      geo::TransformOptions to;
      to.height = geo::HeightMode::Egm96;
      georef_.emplace(geo::Georef::from_crs_bbox(*crs_, to_eigen(bbox_crs_), to));
      rep_.vertical =
          "heights orthometric (" + option_name("geoid") + " egm96) -> ellipsoidal via EGM96";
    } else {
      geo::VerticalChoice vc = geo::choose_vertical(*crs_, opt_.vertical);
      georef_.emplace(
          vc.transformer
              ? geo::Georef::from_transformer_bbox(std::move(vc.transformer), to_eigen(bbox_crs_))
              : geo::Georef::from_crs_bbox(vc.crs, to_eigen(bbox_crs_), vc.options));
      rep_.vertical = vc.assumption;
      for (const auto& w : vc.warnings) rep_.notes.push_back(w);
    }
    // The scene frame: the CRS's axes in metres from an origin on a 100-unit grid
    // (geo::SceneFrame::projected): a building's points get the same coordinates
    // wherever it lies (the same model), and grids anchored at the scene origin (the
    // cells) fall alike on copies shifted by whole 100 units.
    {
      const Eigen::Vector3d c = to_eigen(bbox_crs_).center();
      georef_->use_projected_frame(Eigen::Vector3d(std::round(c[0] / kOriginGrid) * kOriginGrid,
                                                   std::round(c[1] / kOriginGrid) * kOriginGrid,
                                                   std::round(c[2])));
    }
    if (crs_->horizontal_unit().to_si == 1.0 && crs_->vertical_unit().to_si == 1.0)
      for (int k = 0; k < 3; ++k) {
        const double step = inputs_.front().info.scale[std::size_t(k)];
        bool ok = step > 0 && std::isfinite(step);
        const double per_unit = ok ? std::round(1.0 / step) : 0;  // steps per metre
        ok = ok && per_unit >= 1 && std::fabs(per_unit * step - 1.0) < 1e-9;
        for (const auto& in : inputs_) {
          const double o = in.info.offset[std::size_t(k)] + in.offset[std::size_t(k)];
          ok = ok && in.info.scale[std::size_t(k)] == step &&
               std::fabs(o * per_unit - std::round(o * per_unit)) < 1e-6;
        }
        grid_[std::size_t(k)] = ok ? step : 0;
      }
    rep_.notes.push_back(rep_.vertical);
    rep_.crs = crs_->label();
    const auto& hu = crs_->horizontal_unit();
    if (std::abs(hu.to_si - 1.0) > 1e-12)
      rep_.notes.push_back("coordinates in " + hu.name + " (" + fmt("%.10g", hu.to_si) +
                           " m) converted to metres");
    const auto& vu = crs_->vertical_unit();
    if (std::abs(vu.to_si - 1.0) > 1e-12)
      rep_.notes.push_back("heights in " + vu.name + " (" + fmt("%.10g", vu.to_si) +
                           " m) converted to metres");
    for (const auto& w : georef_->warnings())
      if (std::find(rep_.notes.begin(), rep_.notes.end(), w) == rep_.notes.end())
        rep_.notes.push_back(w);
    for (const auto& w : geo::check_units(*crs_, to_eigen(bbox_crs_)).warnings)
      rep_.notes.push_back(w);
  } catch (const geo::GeoError& e) {
    throw IoError(label, e.what());
  }
}

// ---------------------------------------------------------------------- memory plan
// Processing a region costs about kRegionBytesPerPoint (points + attributes +
// PCL clouds + kd-trees + labels); spilling buffers take a quarter of the budget.
constexpr double kRegionBytesPerPoint = 400;

void Splitter::choose_cell_size() {
  region_budget_points_ =
      static_cast<std::size_t>(0.45 * double(opt_.memory_limit) / kRegionBytesPerPoint);
  cell_ = opt_.cell_size;
  // Density from the header counts over the (CRS) box, in points per m^2 (units converted).
  double to_m = 1;
  if (crs_) to_m = crs_->horizontal_unit().to_si;
  const double area = std::max(1.0, (bbox_crs_.max[0] - bbox_crs_.min[0]) *
                                        (bbox_crs_.max[1] - bbox_crs_.min[1]) * to_m * to_m);
  const double density = double(total_points_) / area;
  while (cell_ > kMinSplitCell && (cell_ + 2 * opt_.halo) * (cell_ + 2 * opt_.halo) * density >
                                      0.5 * double(region_budget_points_))
    cell_ *= 0.5;
  if (cell_ != opt_.cell_size)
    rep_.notes.push_back("cell size reduced to " + fmt("%.1f", cell_) + " m to fit " +
                         option_name("memory_limit"));
  rep_.cell_size = cell_;
  claim_cell_ = cell_;
  while (claim_cell_ > kMinSplitCell) claim_cell_ *= 0.5;
}

}  // namespace citylod::tiler::split_detail
