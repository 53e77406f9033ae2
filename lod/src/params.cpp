// LodParams: validation, set-by-name, listing; to_string(ModelKind).
#include "citylod/lod/params.hpp"
#include "citylod/lod/lod.hpp"

#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>

namespace citylod::lod {

const char* to_string(ModelKind k) {
  switch (k) {
    case ModelKind::Anchor:
      return "anchor";
    case ModelKind::Interpolation:
      return "interpolation";
    case ModelKind::Fallback:
      return "fallback";
  }
  return "unknown";
}

namespace {

std::string fmt(double v) {
  std::ostringstream o;
  o.precision(17);
  o << v;
  return o.str();
}
std::string fmt(int v) {
  return std::to_string(v);
}
std::string fmt(bool v) {
  return v ? "true" : "false";
}
const std::string& fmt(const std::string& v) {
  return v;
}

[[noreturn]] void bad(const std::string& name, const std::string& why) {
  throw std::invalid_argument("parameter " + name + ": " + why);
}

void parse(const std::string& name, const std::string& s, double& out) {
  try {
    std::size_t pos = 0;
    double v = std::stod(s, &pos);
    if (pos != s.size() || !std::isfinite(v)) bad(name, "not a finite number: '" + s + "'");
    out = v;
  } catch (const std::invalid_argument&) {
    bad(name, "not a number: '" + s + "'");
  } catch (const std::out_of_range&) {
    bad(name, "out of range: '" + s + "'");
  }
}
void parse(const std::string& name, const std::string& s, int& out) {
  try {
    std::size_t pos = 0;
    long v = std::stol(s, &pos);
    if (pos != s.size() || v < INT32_MIN || v > INT32_MAX) bad(name, "not an integer: '" + s + "'");
    out = static_cast<int>(v);
  } catch (const std::invalid_argument&) {
    bad(name, "not an integer: '" + s + "'");
  } catch (const std::out_of_range&) {
    bad(name, "out of range: '" + s + "'");
  }
}
void parse(const std::string& name, const std::string& s, bool& out) {
  if (s == "1" || s == "true" || s == "on" || s == "yes")
    out = true;
  else if (s == "0" || s == "false" || s == "off" || s == "no")
    out = false;
  else
    bad(name, "not a boolean: '" + s + "'");
}

void parse(const std::string&, const std::string& s, std::string& out) {
  out = s;
}

/// Visits every parameter (fixed order) with its dotted name and a reference.
template <class P, class F>
void visit(P& p, F&& f) {
  f("normals.k_neighbors", p.normals.k_neighbors);
  f("planes.epsilon", p.planes.epsilon);
  f("planes.max_angle_deg", p.planes.max_angle_deg);
  f("planes.min_region_size", p.planes.min_region_size);
  f("planes.k_neighbors", p.planes.k_neighbors);
  f("planes.max_planes", p.planes.max_planes);
  f("alpha.alpha", p.alpha.alpha);
  f("bsp.bbox_enlarge", p.bsp.bbox_enlarge);
  f("bsp.max_cells", p.bsp.max_cells);
  f("bsp.baseline", p.bsp.baseline);
  f("labels.rays_per_cell", p.labels.rays_per_cell);
  f("labels.origins_per_cell", p.labels.origins_per_cell);
  f("ioview.separation_coverage", p.ioview.separation_coverage);
  f("ioview.min_principal_area", p.ioview.min_principal_area);
  f("ioview.covered_only", p.ioview.covered_only);
  f("ioview.uncovered", p.ioview.uncovered);
  f("cluster.area_bandwidth", p.cluster.area_bandwidth);
  f("cluster.volume_bandwidth", p.cluster.volume_bandwidth);
  f("cluster.volume_scale", p.cluster.volume_scale);
  f("regularization.enabled", p.regularization.enabled);
  f("regularization.principal_angle_deg", p.regularization.principal_angle_deg);
  f("regularization.principal_distance", p.regularization.principal_distance);
  f("regularization.secondary_angle_deg", p.regularization.secondary_angle_deg);
  f("regularization.secondary_distance", p.regularization.secondary_distance);
  f("regularization.vertical_host_deg", p.regularization.vertical_host_deg);
  f("regularization.min_cutouts_for_templates", p.regularization.min_cutouts_for_templates);
  f("tree.merge_k", p.tree.merge_k);
  f("tree.label_volume_ratio", p.tree.label_volume_ratio);
  f("tree.interpolation_ratio", p.tree.interpolation_ratio);
  f("tree.interpolation_floor", p.tree.interpolation_floor);
  f("budget.time_budget_s", p.budget.time_budget_s);
  f("closure.enabled", p.closure.enabled);
  f("closure.wall_fraction_min", p.closure.wall_fraction_min);
  f("closure.outline_alpha", p.closure.outline_alpha);
  f("closure.terrain", p.closure.terrain);
  f("closure.plinth_depth", p.closure.plinth_depth);
  f("closure.unknown_ground_depth", p.closure.unknown_ground_depth);
  f("closure.footprint_walls", p.closure.footprint_walls);
  f("closure.wall_profile", p.closure.wall_profile);
  f("closure.wall_snap", p.closure.wall_snap);
  f("airborne.mode", p.airborne.mode);
  f("airborne.wall_fraction_max", p.airborne.wall_fraction_max);
  f("airborne.cell", p.airborne.cell);
  f("airborne.fill_radius", p.airborne.fill_radius);
  f("airborne.step_min", p.airborne.step_min);
  f("airborne.step_probe", p.airborne.step_probe);
  f("airborne.step_alpha", p.airborne.step_alpha);
  f("airborne.step_min_edge", p.airborne.step_min_edge);
  f("airborne.origins_per_cell", p.airborne.origins_per_cell);
  f("airborne.block", p.airborne.block);
  f("airborne.min_region_size", p.airborne.min_region_size);
  f("airborne.roof_refit", p.airborne.roof_refit);
  f("airborne.roof_edge_margin", p.airborne.roof_edge_margin);
  f("airborne.detail_level", p.airborne.detail_level);
  f("orient.enabled", p.orient.enabled);
  f("orient.points_per_plane", p.orient.points_per_plane);
  f("orient.rays", p.orient.rays);
  f("orient.offset", p.orient.offset);
  f("orient.margin", p.orient.margin);
  f("metrics.samples", p.metrics.samples);
  f("colour.enabled", p.colour.enabled);
  f("colour.distance", p.colour.distance);
  f("colour.min_points", p.colour.min_points);
  f("colour.max_angle_deg", p.colour.max_angle_deg);
  f("threads", p.threads);
}

void check(bool ok, const char* name, const std::string& why) {
  if (!ok) bad(name, why);
}

}  // namespace

void LodParams::validate() const {
  check(labels.origins_per_cell >= 1 && labels.origins_per_cell <= labels.rays_per_cell,
        "labels.origins_per_cell", "must be in [1, labels.rays_per_cell]");
  auto pos = [](double v) { return std::isfinite(v) && v > 0; };
  auto ratio = [](double v) { return std::isfinite(v) && v > 0 && v <= 1; };
  auto angle = [](double v) { return std::isfinite(v) && v > 0 && v <= 90; };
  check(normals.k_neighbors >= 3, "normals.k_neighbors", "must be >= 3");
  check(pos(planes.epsilon), "planes.epsilon", "must be > 0");
  check(angle(planes.max_angle_deg), "planes.max_angle_deg", "must be in (0, 90]");
  check(planes.min_region_size >= 3, "planes.min_region_size", "must be >= 3");
  check(planes.k_neighbors >= 3, "planes.k_neighbors", "must be >= 3");
  check(planes.max_planes >= 1, "planes.max_planes", "must be >= 1");
  check(pos(alpha.alpha), "alpha.alpha", "must be > 0");
  check(std::isfinite(bsp.bbox_enlarge) && bsp.bbox_enlarge >= 0 && bsp.bbox_enlarge <= 1,
        "bsp.bbox_enlarge", "must be in [0, 1]");
  check(bsp.max_cells >= 1, "bsp.max_cells", "must be >= 1");
  check(labels.rays_per_cell >= 1, "labels.rays_per_cell", "must be >= 1");
  check(ratio(ioview.separation_coverage), "ioview.separation_coverage", "must be in (0, 1]");
  check(std::isfinite(ioview.min_principal_area) && ioview.min_principal_area >= 0,
        "ioview.min_principal_area", "must be >= 0");
  check(pos(cluster.area_bandwidth), "cluster.area_bandwidth", "must be > 0");
  check(pos(cluster.volume_bandwidth), "cluster.volume_bandwidth", "must be > 0");
  check(ioview.uncovered == "noise" || ioview.uncovered == "s0" || ioview.uncovered == "last",
        "ioview.uncovered", "must be noise, s0 or last");
  check(cluster.volume_scale == "ratio" || cluster.volume_scale == "m3", "cluster.volume_scale",
        "must be ratio or m3");
  check(cluster.volume_scale == "m3" || cluster.volume_bandwidth > 1.0, "cluster.volume_bandwidth",
        "must be > 1 (a factor) with cluster.volume_scale = ratio");
  check(angle(regularization.principal_angle_deg), "regularization.principal_angle_deg",
        "must be in (0, 90]");
  check(std::isfinite(regularization.principal_distance) && regularization.principal_distance >= 0,
        "regularization.principal_distance", "must be >= 0");
  check(angle(regularization.secondary_angle_deg), "regularization.secondary_angle_deg",
        "must be in (0, 90]");
  check(std::isfinite(regularization.secondary_distance) && regularization.secondary_distance >= 0,
        "regularization.secondary_distance", "must be >= 0");
  check(angle(regularization.vertical_host_deg), "regularization.vertical_host_deg",
        "must be in (0, 90]");
  check(regularization.min_cutouts_for_templates >= 1, "regularization.min_cutouts_for_templates",
        "must be >= 1");
  check(tree.merge_k >= 1, "tree.merge_k", "must be >= 1");
  check(ratio(tree.label_volume_ratio), "tree.label_volume_ratio", "must be in (0, 1]");
  check(ratio(tree.interpolation_ratio), "tree.interpolation_ratio", "must be in (0, 1]");
  check(std::isfinite(tree.interpolation_floor) && tree.interpolation_floor >= 0 &&
            tree.interpolation_floor < 1,
        "tree.interpolation_floor", "must be in [0, 1)");
  check(std::isfinite(budget.time_budget_s) && budget.time_budget_s >= 0, "budget.time_budget_s",
        "must be >= 0");
  check(ratio(closure.wall_fraction_min), "closure.wall_fraction_min", "must be in (0, 1]");
  check(pos(closure.outline_alpha), "closure.outline_alpha", "must be > 0");
  check(closure.terrain == "plinth" || closure.terrain == "cut", "closure.terrain",
        "must be 'plinth' or 'cut'");
  check(pos(closure.plinth_depth), "closure.plinth_depth", "must be > 0");
  check(closure.unknown_ground_depth >= 0, "closure.unknown_ground_depth", "must be >= 0");
  check(closure.wall_snap >= 0 && std::isfinite(closure.wall_snap), "closure.wall_snap",
        "must be >= 0");
  check(airborne.mode == "auto" || airborne.mode == "on" || airborne.mode == "off", "airborne.mode",
        "must be 'auto', 'on' or 'off'");
  check(ratio(airborne.wall_fraction_max), "airborne.wall_fraction_max", "must be in (0, 1]");
  check(pos(airborne.cell), "airborne.cell", "must be > 0");
  check(airborne.fill_radius >= 0, "airborne.fill_radius", "must be >= 0");
  check(pos(airborne.step_min), "airborne.step_min", "must be > 0");
  check(pos(airborne.step_probe), "airborne.step_probe", "must be > 0");
  check(pos(airborne.step_alpha), "airborne.step_alpha", "must be > 0");
  check(pos(airborne.step_min_edge), "airborne.step_min_edge", "must be > 0");
  check(airborne.origins_per_cell >= 1, "airborne.origins_per_cell", "must be >= 1");
  check(airborne.min_region_size >= 3, "airborne.min_region_size", "must be >= 3");
  check(airborne.roof_edge_margin >= 0, "airborne.roof_edge_margin", "must be >= 0");
  check(orient.points_per_plane >= 1, "orient.points_per_plane", "must be >= 1");
  check(orient.rays >= 2, "orient.rays", "must be >= 2");
  check(pos(orient.offset), "orient.offset", "must be > 0");
  check(orient.margin >= 0 && orient.margin < 1, "orient.margin", "must be in [0, 1)");
  check(metrics.samples >= 1, "metrics.samples", "must be >= 1");
  check(colour.distance >= 0, "colour.distance", "must be >= 0");
  check(colour.min_points >= 1, "colour.min_points", "must be >= 1");
  check(colour.max_angle_deg >= 0 && colour.max_angle_deg <= 90, "colour.max_angle_deg",
        "must be in [0, 90]");
  check(threads >= 0, "threads", "must be >= 0 (0 = all cores)");
}

void LodParams::set(const std::string& name, const std::string& value) {
  bool found = false;
  visit(*this, [&](const char* n, auto& field) {
    if (found || name != n) return;
    found = true;
    parse(name, value, field);
  });
  if (!found) throw std::invalid_argument("unknown parameter: " + name);
}

std::vector<std::pair<std::string, std::string>> LodParams::items() const {
  std::vector<std::pair<std::string, std::string>> out;
  visit(*this, [&](const char* n, const auto& field) { out.emplace_back(n, fmt(field)); });
  return out;
}

}  // namespace citylod::lod
