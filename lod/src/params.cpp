// LodParams: validation, set-by-name, listing.
#include "citylod/lod/params.hpp"
#include "citylod/lod/lod.hpp"

#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <vector>

namespace citylod::lod {

namespace {

/// The words of an enum's values, in the order of its values.
constexpr const char* kUncovered[] = {"noise", "s0", "last"};
constexpr const char* kVolumeScale[] = {"ratio", "m3"};
constexpr const char* kTerrain[] = {"plinth", "cut"};
constexpr const char* kAirborneMode[] = {"auto", "on", "off"};

template <class E, std::size_t N>
const char* word(E v, const char* const (&words)[N]) {
  const auto i = std::size_t(v);
  return i < N ? words[i] : "unknown";
}

}  // namespace

const char* to_string(Uncovered v) {
  return word(v, kUncovered);
}
const char* to_string(VolumeScale v) {
  return word(v, kVolumeScale);
}
const char* to_string(Terrain v) {
  return word(v, kTerrain);
}
const char* to_string(AirborneMode v) {
  return word(v, kAirborneMode);
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
template <class E, std::enable_if_t<std::is_enum_v<E>, int> = 0>
std::string fmt(E v) {
  return to_string(v);
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

/// "'a', 'b' or 'c'".
template <std::size_t N>
std::string one_of(const char* const (&words)[N]) {
  std::string out;
  for (std::size_t i = 0; i < N; ++i)
    out += std::string(i == 0 ? "'" : i + 1 == N ? " or '" : ", '") + words[i] + "'";
  return out;
}

/// The values a switch or a mode takes ("" for numbers, whose rule says it).
template <class T>
std::string choices(const T&) {
  return "";
}
std::string choices(const bool&) {
  return "true or false";
}
std::string choices(const Uncovered&) {
  return one_of(kUncovered);
}
std::string choices(const VolumeScale&) {
  return one_of(kVolumeScale);
}
std::string choices(const Terrain&) {
  return one_of(kTerrain);
}
std::string choices(const AirborneMode&) {
  return one_of(kAirborneMode);
}

/// One of the words of `words`; else the error names them.
template <class E, std::size_t N>
void parse_word(const std::string& name, const std::string& s, E& out,
                const char* const (&words)[N]) {
  for (std::size_t i = 0; i < N; ++i)
    if (s == words[i]) {
      out = E(i);
      return;
    }
  bad(name, "must be " + one_of(words) + ", got '" + s + "'");
}
void parse(const std::string& name, const std::string& s, Uncovered& out) {
  parse_word(name, s, out, kUncovered);
}
void parse(const std::string& name, const std::string& s, VolumeScale& out) {
  parse_word(name, s, out, kVolumeScale);
}
void parse(const std::string& name, const std::string& s, Terrain& out) {
  parse_word(name, s, out, kTerrain);
}
void parse(const std::string& name, const std::string& s, AirborneMode& out) {
  parse_word(name, s, out, kAirborneMode);
}

/// Validation rules of the parameters (visit): ok(value, all parameters) and
/// the message when it fails.
struct Any {
  template <class T>
  bool ok(const T&, const LodParams&) const {
    return true;
  }
  std::string why() const { return ""; }
};
/// A finite number in an interval; `lo_open` / `hi_open` exclude the ends.
struct Range {
  double lo, hi;
  bool lo_open, hi_open;
  bool ok(double v, const LodParams&) const {
    return std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string why() const {
    if (std::isinf(hi)) return std::string("must be ") + (lo_open ? "> " : ">= ") + fmt_short(lo);
    return "must be in " + std::string(lo_open ? "(" : "[") + fmt_short(lo) + ", " + fmt_short(hi) +
           (hi_open ? ")" : "]");
  }
  static std::string fmt_short(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  }
};
constexpr double kInf = std::numeric_limits<double>::infinity();
const Range kPositive{0, kInf, true, false};
const Range kNonNegative{0, kInf, false, false};
const Range kRatio{0, 1, true, false};        // (0, 1]
const Range kUnitOpen{0, 1, false, true};     // [0, 1)
const Range kAngle{0, 90, true, false};       // (0, 90] degrees
const Range kAngleZero{0, 90, false, false};  // [0, 90] degrees
/// An integer >= min.
struct AtLeast {
  int min;
  bool ok(int v, const LodParams&) const { return v >= min; }
  std::string why() const { return "must be >= " + std::to_string(min); }
};
/// A rule that reads other parameters.
template <class T>
struct Relation {
  bool (*test)(const T&, const LodParams&);
  const char* message;
  bool ok(const T& v, const LodParams& p) const { return test(v, p); }
  std::string why() const { return message; }
};

/// Visits every parameter (fixed order) with its dotted name, a reference, its
/// validation rule, its unit ("" for switches and modes) and a one-line doc of
/// what it does (no unit: `citylod lod --help` shows it beside): the one place
/// a parameter's name, unit, rule and doc are written (its default is the
/// field's initialiser in params.hpp).
template <class P, class F>
void visit(P& p, F&& f) {
  f("normals.k_neighbors", p.normals.k_neighbors, AtLeast{3}, "points",
    "neighbours of a point's PCA normal when the input has none");
  f("planes.epsilon", p.planes.epsilon, kPositive, "m",
    "max point-to-plane distance of a plane's inliers");
  f("planes.max_angle_deg", p.planes.max_angle_deg, kAngle, "deg",
    "max deviation of an inlier's normal from the plane's");
  f("planes.min_region_size", p.planes.min_region_size, AtLeast{3}, "points",
    "smallest plane: its points (or mesh faces)");
  f("planes.k_neighbors", p.planes.k_neighbors, AtLeast{3}, "points",
    "neighbourhood of region growing on point clouds");
  f("planes.max_planes", p.planes.max_planes, AtLeast{1}, "planes",
    "cap: the largest planes are kept, the rest dropped (recorded)");
  f("alpha.alpha", p.alpha.alpha, kPositive, "m",
    "alpha radius of the primitives' alpha-shapes (CGAL's is its square)");
  f("bsp.bbox_enlarge", p.bsp.bbox_enlarge, Range{0, 1, false, false}, "ratio",
    "share of the bbox diagonal added to the BSP's box on every side");
  f("bsp.max_cells", p.bsp.max_cells, AtLeast{1}, "cells",
    "cap on leaf cells per BSP (fallback when hit)");
  f("bsp.baseline", p.bsp.baseline, Any{}, "",
    "also build the plain BSP-Tree (area order, binary) for comparison");
  f("labels.rays_per_cell", p.labels.rays_per_cell, AtLeast{1}, "rays",
    "rays cast from a cell to label it in or out");
  f("labels.origins_per_cell", p.labels.origins_per_cell,
    Relation<int>{
        [](const int& v, const LodParams& q) { return v >= 1 && v <= q.labels.rays_per_cell; },
        "must be in [1, labels.rays_per_cell]"},
    "points", "ray origins per cell: 1 = its centre (the paper), more spread them");
  f("ioview.separation_coverage", p.ioview.separation_coverage, kRatio, "ratio",
    "share of a shared face an alpha-shape covers to separate its cells");
  f("ioview.min_principal_area", p.ioview.min_principal_area, kNonNegative, "m^2",
    "V_in/V_out interface on its plane that makes a primitive principal");
  f("ioview.covered_only", p.ioview.covered_only, Any{}, "",
    "a face counts for a plane only where its alpha-shape covers it (paper)");
  f("ioview.uncovered", p.ioview.uncovered, Any{}, "",
    "with covered_only: the uncovered interface primitives' place in S");
  f("cluster.area_bandwidth", p.cluster.area_bandwidth, kPositive, "m^2",
    "stage 1 mean shift: bandwidth of the area projected on the host");
  f("cluster.volume_bandwidth", p.cluster.volume_bandwidth,
    Relation<double>{[](const double& v, const LodParams& q) {
                       return std::isfinite(v) && v > 0 &&
                              (q.cluster.volume_scale == VolumeScale::M3 || v > 1.0);
                     },
                     "must be > 0, and > 1 (a factor) with "
                     "cluster.volume_scale = ratio"},
    "factor | m^3", "stage 2 mean shift: bandwidth of the clusters' mean volumes");
  f("cluster.volume_scale", p.cluster.volume_scale, Any{}, "",
    "stage 2 on ln V (ratio: the bandwidth is a factor) or on V (m3)");
  f("regularization.enabled", p.regularization.enabled, Any{}, "",
    "adaptive regularization of the primitives");
  f("regularization.principal_angle_deg", p.regularization.principal_angle_deg, kAngle, "deg",
    "parallelism/orthogonality tolerance of principal primitives");
  f("regularization.principal_distance", p.regularization.principal_distance, kNonNegative, "m",
    "coplanarity tolerance of principal primitives");
  f("regularization.secondary_angle_deg", p.regularization.secondary_angle_deg, kAngle, "deg",
    "angle tolerance of secondary primitives, to their host");
  f("regularization.secondary_distance", p.regularization.secondary_distance, kNonNegative, "m",
    "coplanarity tolerance of secondary primitives");
  f("regularization.vertical_host_deg", p.regularization.vertical_host_deg, kAngle, "deg",
    "a host counts as a wall within this angle of vertical");
  f("regularization.min_cutouts_for_templates", p.regularization.min_cutouts_for_templates,
    AtLeast{1}, "cut-outs",
    "cut-outs of a cluster on a wall host that give cuboid window templates");
  f("tree.merge_k", p.tree.merge_k, AtLeast{1}, "primitives",
    "K: a cluster with < K primitives per structure is one multi-branch node");
  f("tree.label_volume_ratio", p.tree.label_volume_ratio, kRatio, "ratio",
    "a node is in when this share of its leaf volume is in");
  f("tree.interpolation_ratio", p.tree.interpolation_ratio, kRatio, "ratio",
    "new interpolation model when the diff sum < this x the last one's");
  f("tree.interpolation_floor", p.tree.interpolation_floor, kUnitOpen, "ratio",
    "no interpolation below this share of the level's first diff sum");
  f("budget.time_budget_s", p.budget.time_budget_s, kNonNegative, "s",
    "wall-clock time per building, then a fallback (0 = none)");
  f("closure.enabled", p.closure.enabled, Any{}, "",
    "add ground + outline walls when walls are missing");
  f("closure.wall_fraction_min", p.closure.wall_fraction_min, kRatio, "ratio",
    "walls are inferred when vertical-normal samples are under this share");
  f("closure.outline_alpha", p.closure.outline_alpha, kPositive, "m",
    "2D alpha radius of the outline of the points");
  f("closure.terrain", p.closure.terrain, Any{}, "",
    "terrain sheet around the building: kept as a plinth, or cut away");
  f("closure.plinth_depth", p.closure.plinth_depth, kPositive, "m",
    "plinth bottom below the lowest sample");
  f("closure.unknown_ground_depth", p.closure.unknown_ground_depth, kNonNegative, "m",
    "no ground given and roof-only: ground this far below the lowest");
  f("closure.footprint_walls", p.closure.footprint_walls, Any{}, "",
    "walls along a given footprint even where some walls were scanned");
  f("closure.wall_profile", p.closure.wall_profile, Any{}, "",
    "meshes on a footprint: inferred walls follow the roof's profile");
  f("closure.wall_snap", p.closure.wall_snap, kNonNegative, "m",
    "meshes on a footprint: an inferred wall this near a seen one takes it");
  f("airborne.mode", p.airborne.mode, Any{}, "",
    "2.5D labelling by a roof height field: auto, every input or none");
  f("airborne.wall_fraction_max", p.airborne.wall_fraction_max, kRatio, "ratio",
    "auto: a point cloud under this share of wall samples is airborne");
  f("airborne.cell", p.airborne.cell, kPositive, "m", "height-field cell size");
  f("airborne.fill_radius", p.airborne.fill_radius, kNonNegative, "m",
    "height-field gaps filled from neighbours up to this far");
  f("airborne.step_min", p.airborne.step_min, kPositive, "m",
    "roof drop to the lower side extrapolated to the edge that makes a step wall");
  f("airborne.step_min_raw", p.airborne.step_min_raw, kPositive, "m",
    "roof drop step_probe beyond a roof plane's edge that makes a step wall");
  f("airborne.step_probe", p.airborne.step_probe, kPositive, "m",
    "how far beyond the edge the lower roof is probed");
  f("airborne.step_alpha", p.airborne.step_alpha, kPositive, "m",
    "2D alpha radius of a roof plane's outline");
  f("airborne.step_min_edge", p.airborne.step_min_edge, kPositive, "m",
    "shortest edge that gets a step wall");
  f("airborne.origins_per_cell", p.airborne.origins_per_cell, AtLeast{1}, "points",
    "height-test points per cell (centre + halfway to vertices)");
  f("airborne.block", p.airborne.block, Any{}, "", "the LoD1.2 block as the coarsest model");
  f("airborne.min_region_size", p.airborne.min_region_size, AtLeast{3}, "points",
    "smallest plane on airborne input");
  f("airborne.roof_refit", p.airborne.roof_refit, Any{}, "",
    "roof planes refitted robustly (Tukey, outline points weighted down)");
  f("airborne.roof_edge_margin", p.airborne.roof_edge_margin, kNonNegative, "m",
    "returns farther inside the outline are the roof; nearer weigh less in a refit");
  f("airborne.detail_level", p.airborne.detail_level, Any{}, "",
    "roof planes outside every structure form a last level set");
  f("airborne.plane_merge_distance", p.airborne.plane_merge_distance, kNonNegative, "m",
    "BSP planes whose polygons lie this near each other's planes are one (0: off)");
  f("airborne.plane_merge_angle_deg", p.airborne.plane_merge_angle_deg, kAngle, "deg",
    "... and whose normals are this near (either orientation)");
  f("orient.enabled", p.orient.enabled, Any{}, "",
    "turn round planes whose normals point into the building");
  f("orient.points_per_plane", p.orient.points_per_plane, AtLeast{1}, "points",
    "inlier positions probed per plane");
  f("orient.rays", p.orient.rays, AtLeast{2}, "rays",
    "ray directions per probe (half of them per side)");
  f("orient.offset", p.orient.offset, kPositive, "m",
    "probe distance in front of / behind the plane");
  f("orient.margin", p.orient.margin, kUnitOpen, "ratio",
    "a plane's front in-fraction must exceed its back's by this much");
  f("metrics.samples", p.metrics.samples, AtLeast{1}, "samples",
    "samples on each model for e1; at most this many input samples for e2");
  f("colour.enabled", p.colour.enabled, Any{}, "",
    "input colours onto the models' faces (inputs with colours only)");
  f("colour.distance", p.colour.distance, kNonNegative, "m",
    "a point colours the nearest face within this distance");
  f("colour.min_points", p.colour.min_points, AtLeast{1}, "points",
    "points a plane region needs to take their median colour");
  f("colour.max_angle_deg", p.colour.max_angle_deg, kAngleZero, "deg",
    "max angle of a point's normal to the face's outward normal");
}

}  // namespace

void LodParams::validate() const {
  visit(*this,
        [&](const char* name, const auto& value, const auto& rule, const char*, const char*) {
          if (!rule.ok(value, *this)) bad(name, rule.why());
        });
}

void LodParams::set(const std::string& name, const std::string& value) {
  bool found = false;
  visit(*this, [&](const char* n, auto& field, const auto&, const char*, const char*) {
    if (found || name != n) return;
    found = true;
    parse(name, value, field);
  });
  if (!found) throw std::invalid_argument("unknown parameter: " + name);
}

std::vector<ParamInfo> LodParams::describe() const {
  std::vector<ParamInfo> out;
  visit(*this,
        [&](const char* n, const auto& field, const auto& rule, const char* unit, const char* doc) {
          std::string r = rule.why();
          if (r.empty()) r = choices(field);
          out.push_back({n, fmt(field), unit, r, doc});
        });
  return out;
}

std::vector<std::pair<std::string, std::string>> LodParams::items() const {
  std::vector<std::pair<std::string, std::string>> out;
  visit(*this, [&](const char* n, const auto& field, const auto&, const char*, const char*) {
    out.emplace_back(n, fmt(field));
  });
  return out;
}

}  // namespace citylod::lod
