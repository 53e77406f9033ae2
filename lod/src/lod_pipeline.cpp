// The LOD-Tree method for one building, top to bottom (paper Section 4):
//
//   samples -> planes (+ closure for roof-only LiDAR) -> IO-View BSP + ray
//   labels -> regions, principal/secondary structures -> two-stage clustering
//   -> adaptive regularization (+ window templates) -> scale-sorted S ->
//   LOD-Tree BSP + per-level labels -> LOD-nodes -> traversal -> mesh per
//   candidate -> fidelity metrics -> input colours on the faces.
//
// Any failure inside gives the fallback model with the reason recorded.
#include "airborne.hpp"
#include "bsp.hpp"
#include "citylod/lod/lod.hpp"
#include "closure.hpp"
#include "colour.hpp"
#include "fallback.hpp"
#include "fidelity.hpp"
#include "grouping.hpp"
#include "ioview.hpp"
#include "labelling.hpp"
#include "orient.hpp"
#include "planes.hpp"
#include "regularization.hpp"
#include "samples.hpp"
#include "tree.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <set>
#include <sstream>

namespace citylod::lod {
namespace {

using Clock = std::chrono::steady_clock;
using namespace detail;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void check_input(const BuildingInput& in) {
  if (in.points.empty()) throw LodError("input", "no points");
  for (size_t i = 0; i < in.points.size(); ++i)
    if (!in.points[i].allFinite())
      throw LodError("input", "non-finite coordinate at point #" + std::to_string(i));
  if (!in.normals.empty() && in.normals.size() != in.points.size())
    throw LodError("input", "normals count differs from points count");
  for (const auto& t : in.triangles)
    for (int v : t)
      if (v < 0 || size_t(v) >= in.points.size())
        throw LodError("input", "triangle index out of range");
}

struct Budget {
  Clock::time_point deadline;
  void check(const char* stage) const {
    if (Clock::now() > deadline) throw LodBudgetExceeded(stage);
  }
};

class Progress {
 public:
  Progress(ProgressFn fn, void* user) : fn_(fn), user_(user) {}
  void operator()(double f, const char* stage) const {
    if (fn_ && !fn_(f, stage, user_)) throw LodCancelled(stage);
  }

 private:
  ProgressFn fn_;
  void* user_;
};

/// The BSP's box and its first cuts. The paper partitions "the bounding box
/// of the model"; (ours) the box is padded (bsp.bbox_enlarge) only to keep its
/// faces off the outermost primitives. (ours) The six planes of the data's bounding box,
/// kDataBoxMargin outside it, are the first cuts, so that no cell straddles
/// the data's bounds, and the leaves beyond them are out at every level
/// (clear_pad_leaves): nothing is there to model. With cells straddling the
/// bounds, thin in-cells reached the box (cgal_building's finest model had a
/// 4 x 10 cm rod 3 m long in the pad, AHN3_13856's coarse models overhung the
/// data by 7.7 m).
struct SceneBox {
  Vec3 lo, hi;          ///< the enlarged box the BSP partitions
  Vec3 cut_lo, cut_hi;  ///< the data box cuts
};
constexpr double kDataBoxMargin = 0.25;  ///< m; the pad is >= 0.5 m, so the cuts stay inside it
constexpr double kMinShellFraction =
    0.01;  ///< shells under 1 % of the largest one's volume are slivers
constexpr double kMinCavityVolume =
    1e-6;  ///< m^3; cavities are kept (the input shows them) unless of no volume

/// Bounding box of the samples and primitive shapes, enlarged by `enlarge` of
/// its diagonal (at least 0.5 m) per side.
SceneBox scene_box(const Samples& s, const std::vector<Primitive>& prims, double enlarge) {
  Vec3 lo = s.points.front(), hi = lo;
  for (const auto& p : s.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  for (const auto& pr : prims)
    for (const auto& v : pr.hull) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  const Vec3 pad = Vec3::Constant(std::max(0.5, enlarge * (hi - lo).norm()));
  const Vec3 margin = Vec3::Constant(kDataBoxMargin);
  return {lo - pad, hi + pad, lo - margin, hi + margin};
}

void clear_pad_leaves(const Bsp& bsp, const SceneBox& box, std::vector<std::vector<char>>& labels) {
  const auto leaves = bsp.leaves();
  for (size_t i = 0; i < leaves.size() && i < labels.size(); ++i) {
    const Vec3& c = bsp.nodes()[size_t(leaves[i])].center;
    if ((c.array() < box.cut_lo.array()).any() || (c.array() > box.cut_hi.array()).any())
      std::fill(labels[i].begin(), labels[i].end(), 0);
  }
}

/// Polygons of a BSP: the six data-box cuts (kBoxCut), then the hulls of the
/// primitives in `order`.
std::vector<BspPolygon> hull_polygons(const std::vector<Primitive>& prims,
                                      const std::vector<int>& order, const SceneBox& box) {
  std::vector<BspPolygon> polys;
  polys.reserve(order.size() + 6);
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      const double at = side ? box.cut_hi[axis] : box.cut_lo[axis];
      std::array<double, 4> plane{0, 0, 0, -at};
      plane[size_t(axis)] = 1.0;
      std::vector<Vec3> rect(4);  // spans the BSP's box (clipped to it)
      for (int k = 0; k < 4; ++k) {
        rect[size_t(k)][axis] = at;
        rect[size_t(k)][u] = (k == 1 || k == 2) ? box.hi[u] + 1.0 : box.lo[u] - 1.0;
        rect[size_t(k)][w] = (k >= 2) ? box.hi[w] + 1.0 : box.lo[w] - 1.0;
      }
      polys.push_back(BspPolygon{plane, std::move(rect), kBoxCut});
    }
  for (int i : order) {
    const auto& p = prims[size_t(i)];
    polys.push_back(BspPolygon{{p.normal.x(), p.normal.y(), p.normal.z(), p.d}, p.hull, i});
  }
  return polys;
}

LevelTriangles alpha_triangles(const std::vector<Primitive>& prims,
                               const std::vector<int>& level_of) {
  LevelTriangles t;
  for (size_t i = 0; i < prims.size(); ++i) {
    if (level_of[i] < 0) continue;
    for (const auto& tri : prims[i].alpha_tris) {
      t.triangles.push_back(tri);
      t.level.push_back(level_of[i]);
    }
  }
  return t;
}

/// Ray origins of each leaf: its centre and points halfway to some of its
/// vertices (max_origins in all), so elongated cells are judged along their extent.
std::vector<std::vector<Vec3>> leaf_ray_origins(const Bsp& bsp, int max_origins) {
  std::vector<std::vector<Vec3>> out;
  for (int l : bsp.leaves()) {
    const Vec3 c = bsp.nodes()[size_t(l)].center;
    std::vector<Vec3> o{c};
    const auto verts = bsp.cell_vertices(l);
    const size_t extra = size_t(std::max(0, max_origins - 1));
    if (extra > 0) {
      const size_t step = std::max<size_t>(1, (verts.size() + extra - 1) / extra);
      for (size_t i = 0; i < verts.size() && o.size() <= extra; i += step)
        o.push_back(c + 0.5 * (verts[i] - c));
    }
    out.push_back(std::move(o));
  }
  return out;
}

PlaneReport report_plane(const Primitive& p, const Samples& s, int level, int cluster) {
  PlaneReport r;
  r.normal = p.normal;
  r.d = p.d;
  r.level = level;
  r.cluster = cluster;
  r.area = p.alpha_area;
  r.from_template = p.from_template;
  r.inferred = p.inferred;
  for (int i : p.inliers) r.inlier_points.push_back(s.points[size_t(i)]);
  if (p.inliers.empty())
    for (const auto& t : p.alpha_tris)
      r.inlier_points.insert(r.inlier_points.end(), t.begin(), t.end());
  return r;
}

/// (ours) One solid per model: shells (edge-connected pieces) with less than
/// `min_fraction` of the largest one's volume are removed (slivers left by a
/// cut), and cavities (shells of negative volume: rooms seen through windows)
/// of no volume. Cavities are kept: filling cgal_building's 11 (0.02-6.7 m^3)
/// raised its finest e2 from 0.497 to 0.521 %. Returns the number of outer
/// shells kept.
int drop_small_shells(LodModel& m, double min_fraction) {
  const auto& T = m.mesh.triangles;
  std::vector<int> parent(m.mesh.vertices.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
  auto find = [&](int x) {
    while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
    return x;
  };
  for (const auto& t : T) {
    parent[size_t(find(t[1]))] = find(t[0]);
    parent[size_t(find(t[2]))] = find(t[0]);
  }
  std::map<int, double> volume;  // root -> volume
  for (const auto& t : T) {
    const Vec3 &a = m.mesh.vertices[size_t(t[0])], &b = m.mesh.vertices[size_t(t[1])],
               &c = m.mesh.vertices[size_t(t[2])];
    const Vec3& o = m.mesh.vertices[0];
    volume[find(t[0])] += (a - o).dot((b - o).cross(c - o)) / 6.0;
  }
  if (volume.size() <= 1) return int(volume.size());
  double vmax = 0;
  for (const auto& [r, v] : volume) vmax = std::max(vmax, v);
  std::set<int> keep;
  int outer = 0;
  for (const auto& [r, v] : volume)
    if (vmax > 0 && (v > 0 ? v >= min_fraction * vmax : -v >= kMinCavityVolume)) {
      keep.insert(r);
      outer += v > 0;
    }
  if (keep.size() == volume.size()) return outer;
  std::vector<std::array<int, 3>> tris;
  for (const auto& t : T)
    if (keep.count(find(t[0]))) tris.push_back(t);
  m.mesh.triangles = std::move(tris);
  std::vector<std::vector<int>> faces;
  for (auto& f : m.polygons.faces)
    if (!f.empty() && keep.count(find(f[0]))) faces.push_back(std::move(f));
  m.polygons.faces = std::move(faces);
  return outer;
}

/// (ours) Airborne LiDAR: a point cloud that sees few walls (less than
/// airborne.wall_fraction_max of its samples), or a city chunk with a
/// footprint whose walls are inferred along it.
bool airborne_input(const BuildingInput& in, const Samples& s, const LodParams& P) {
  if (P.airborne.mode != AirborneMode::Auto) return P.airborne.mode == AirborneMode::On;
  if (in.is_mesh() || !P.closure.enabled || s.points.empty()) return false;
  if (P.closure.footprint_walls && in.footprint.size() >= 3) return true;
  double wall = 0, total = 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const double w = s.weights.empty() ? 1.0 : s.weights[i];
    total += w;
    if (std::abs(s.normals[i].z()) < 0.3) wall += w;
  }
  return total > 0 && wall / total < P.airborne.wall_fraction_max;
}

/// (ours) Airborne LiDAR: the roof planes (normal.z >= 0.3) and inferred
/// walls that IO-View leaves out of S (the paper's noise: secondary
/// primitives bounding no structure) become one more level set, the last.
/// On dense MVS input such planes are noise; on airborne LiDAR a small roof
/// plane is roof detail (a ridge piece, a cross gable, a dormer cheek), and
/// the height field labels its cells whatever the plane. Returns the number
/// of primitives added.
int append_detail_level(const std::vector<Primitive>& prims, SortedPrimitives& sorted) {
  int added = 0;
  for (size_t i = 0; i < prims.size(); ++i)
    if (sorted.level_of[i] < 0 && (prims[i].inferred || prims[i].normal.z() >= 0.3)) {
      sorted.order.push_back(int(i));
      sorted.level_of[i] = sorted.num_levels;
      ++added;
    }
  if (added > 0) ++sorted.num_levels;
  return added;
}

/// Step 1's result: the planar primitives and, for airborne LiDAR, the roof
/// height field that labels the cells.
struct Planes {
  std::vector<Primitive> prims;
  std::optional<HeightField> heights;
  /// Inferred walls take the equation of a plane they nearly coincide with
  /// (meshes: scanned walls along a footprint edge), again after regularization.
  bool snap_walls = false;
};

/// 1. Planar primitives (region growing on the oriented samples); airborne
/// LiDAR is sparser than the paper's MVS input: smaller regions count.
/// Closure planes for roof-only LiDAR, the airborne height field, refitted
/// roofs and step walls; planes with inward normals turned round.
Planes planar_primitives(const BuildingInput& in, const Samples& samples, const LodParams& P,
                         int threads, LodStats& st) {
  Planes out;
  std::vector<Primitive>& prims = out.prims;
  const bool airborne = airborne_input(in, samples, P);
  PlaneParams plane_params = P.planes;
  if (airborne)
    plane_params.min_region_size =
        std::min(plane_params.min_region_size, P.airborne.min_region_size);
  prims = detect_planes(in, samples, plane_params, P.alpha, threads, &st.planes_found);
  st.planes_detected = int(prims.size());
  if (st.planes_found > st.planes_detected)  // a cap, recorded (counts.planes_found)
    st.notes.push_back("planes.max_planes = " + std::to_string(P.planes.max_planes) +
                       " reached: " + std::to_string(st.planes_found) + " planes found, the " +
                       std::to_string(st.planes_found - st.planes_detected) +
                       " smallest left out (raise planes.max_planes to keep them)");
  if (prims.empty()) throw LodError("planes", "no plane found");
  // Roof-only LiDAR: ground + walls through the outline so the building closes.
  Closure c;
  if (P.closure.enabled) {
    c = close_building(in, samples, P.closure, prims, airborne);
    st.walls_inferred = c.what == Closure::Walls || c.what == Closure::FootprintWalls;
    const std::string n = std::to_string(c.added);
    if (c.what == Closure::Base) st.notes.push_back("open bottom: a base plane was inferred");
    if (c.what == Closure::Walls)
      st.notes.push_back("walls missing: " + n + " closure planes inferred (ground + walls)");
    if (c.what == Closure::FootprintWalls)
      st.notes.push_back(std::string(in.footprint.size() >= 3 ? "walls along the footprint: "
                                                              : "walls along the outline: ") +
                         n + " closure planes inferred (ground + walls; scanned walls kept)");
    out.snap_walls = c.snap_walls;
    if (c.snapped > 0)
      st.notes.push_back(std::to_string(c.snapped) +
                         " inferred walls on the plane of a wall they nearly coincide with");
    if (c.what == Closure::Plinth)
      st.notes.push_back(
          "terrain sheet kept as a plinth: " + n +
          " closure planes inferred (base + walls; closure.terrain=cut models the building alone)");
  }
  // (ours) Airborne LiDAR is 2.5D: a roof height field labels the cells, and
  // walls are inferred where the roof steps down.
  std::optional<HeightField>& heights = out.heights;
  const bool walls_inferred = c.what == Closure::Walls || c.what == Closure::FootprintWalls;
  if (P.airborne.mode == AirborneMode::On || (airborne && walls_inferred)) {
    if (c.outline.size() < 3) throw LodError("airborne", "no outline to model the building on");
    heights.emplace(samples, c.outline, c.ground_z, P.airborne);
    if (heights->top() <= 0) {
      char what[96];
      std::snprintf(what, sizeof what,
                    "no point above the ground (98th percentile %.2f m under it)", -heights->top());
      throw LodError("airborne", what);
    }
    const int refitted = refit_roof_planes(samples, c.outline, P.airborne, P.alpha, prims);
    const int steps = infer_step_walls(samples, *heights, P.airborne, prims);
    st.notes.push_back("airborne LiDAR: cells labelled by the roof height field; " +
                       std::to_string(refitted) + " roof planes refitted robustly; " +
                       std::to_string(steps) + " step walls inferred");
  }
  prims.erase(
      std::remove_if(prims.begin(), prims.end(),
                     [](const Primitive& p) { return p.hull.size() < 3 || p.alpha_tris.empty(); }),
      prims.end());
  // (ours) Planes whose input normals point into the building are turned round
  // (the ray labelling needs it; the height field does not).
  if (!heights) {
    st.planes_turned = orient_primitives(prims, samples, P.orient, threads);
    if (st.planes_turned > 0)
      st.notes.push_back(std::to_string(st.planes_turned) +
                         " planes turned round (normals pointed inside)");
  }
  if (prims.size() < 4)
    throw LodError("planes", "fewer than 4 usable planes (" + std::to_string(prims.size()) + ")");
  return out;
}

/// An IO-View failure with what the scan saw, which names the common cases:
/// a patch at the ground's level, a roof the scan hardly reached.
std::string io_view_failure(const std::string& why, const HeightField& hf) {
  char height[128];
  std::snprintf(height, sizeof height,
                " (the returns reach %.2f m above the ground, 98th percentile; roof returns "
                "over %.0f %% of the outline)",
                hf.top(), 100.0 * hf.roof_coverage());
  return why + height;
}

/// Step 2's result: the BSP's box, the IO-View BSP and its analysis.
struct IoViewStep {
  SceneBox box;
  Bsp bsp;
  IoView view;
};

/// 2. IO-View: BSP by the hulls, largest first; ray labels (or the height
/// field's); regions, principal primitives, secondary structures.
IoViewStep io_view_step(const Samples& samples, const Planes& planes, const LodParams& P,
                        int threads, const Budget& budget, LodStats& st) {
  const std::vector<Primitive>& prims = planes.prims;
  const std::optional<HeightField>& heights = planes.heights;
  const SceneBox box = scene_box(samples, prims, P.bsp.bbox_enlarge);
  std::vector<int> by_area(prims.size());
  for (size_t i = 0; i < prims.size(); ++i) by_area[i] = int(i);
  std::stable_sort(by_area.begin(), by_area.end(), [&](int a, int b) {
    return prims[size_t(a)].hull_area > prims[size_t(b)].hull_area;
  });
  Bsp io_bsp(box.lo, box.hi, hull_polygons(prims, by_area, box), P.bsp.max_cells);
  if (io_bsp.cap_hit()) {
    st.bsp_cap_hit = true;
    st.notes.push_back("bsp.max_cells = " + std::to_string(P.bsp.max_cells) +
                       " reached in the IO-View BSP: the primitives after that point do not cut "
                       "(raise bsp.max_cells to partition fully)");
  }
  st.ioview_cells = int(io_bsp.leaves().size());
  budget.check("io-view");
  const std::vector<int> all_level0(prims.size(), 0);
  std::vector<char> io_labels;
  std::vector<std::vector<char>> io_leaf_labels;
  if (heights) {
    for (char l : label_by_height(leaf_ray_origins(io_bsp, P.airborne.origins_per_cell), *heights))
      io_leaf_labels.push_back({l});
  } else {
    const RayLabeller io_labeller(alpha_triangles(prims, all_level0), P.labels.rays_per_cell);
    io_leaf_labels =
        io_labeller.label(leaf_ray_origins(io_bsp, P.labels.origins_per_cell), 1, threads);
  }
  clear_pad_leaves(io_bsp, box, io_leaf_labels);
  for (const auto& l : io_leaf_labels) io_labels.push_back(l[0]);
  budget.check("io-view");
  const auto matches = match_planes(io_bsp, prims);
  IoView view;
  const auto analyse = [&](const IoViewParams& ip) {
    view = analyse_io_view(io_bsp, prims, matches, io_labels, ip);
    st.principal = int(
        std::count_if(view.principal.begin(), view.principal.end(), [](char p) { return p != 0; }));
  };
  analyse(P.ioview);
  if (view.core_in < 0) throw LodError("io-view", "no cell labelled inside");
  const LodError too_few("io-view", "fewer than 4 principal primitives");
  // (ours) A roof height field labels stepped roofs as inside regions cut
  // apart by their roof planes: the core is then one step, and few planes
  // separate it from the core exterior. Seen again with no plane separating
  // inside from inside, the core is the whole connected building.
  IoViewParams joined = P.ioview;
  joined.separation_coverage = 2;  // above any coverage (<= 1): nothing separates
  if (st.principal < 4 && heights) {
    analyse(joined);
    st.notes.push_back("io-view: the inside regions taken as one core (" +
                       std::to_string(st.principal) + " principal primitives)");
  }
  if (st.principal < 4 && heights) {
    // (ours) A low object (a slab 0.2-1 m high, a flat annex) has walls
    // smaller than min_principal_area: a 0.3 m wall must run 1.7 m to count,
    // and a footprint's outline splits a side into shorter walls. Any plane
    // that separates the core from the core exterior then counts. Its chain
    // is kept only where it fits better than the block (returns at the
    // ground's level make a roof plane through the ground, a wedge):
    // drop_low_object_worse_than_block after the metrics.
    IoViewParams low = joined;
    low.min_principal_area = 1e-6;
    analyse(low);
    st.low_object = io_view_failure(too_few.what(), *heights);
    st.notes.push_back("io-view: a low object, every plane bounding its core principal (" +
                       std::to_string(st.principal) + " principal primitives)");
  }
  if (st.principal < 4) throw too_few;
  for (const auto& s : view.structures)
    (s.addon ? st.add_ons : st.cut_outs) += s.primitives.empty() ? 0 : 1;
  return {box, std::move(io_bsp), std::move(view)};
}

/// Step 3's result: the level sets and the scale-sorted order S.
struct SortStep {
  Grouping grouping;
  SortedPrimitives sorted;
};

/// 3. Two-stage clustering, adaptive regularization, scale-sorted S (plus,
/// for airborne LiDAR, the last level set of roof detail).
SortStep sort_step(const Samples& samples, Planes& planes, IoViewStep& io, const LodParams& P,
                   LodResult& R) {
  auto& st = R.stats;
  std::vector<Primitive>& prims = planes.prims;
  IoView& view = io.view;
  Grouping grouping = group_structures(view, prims, P.cluster);
  if (P.regularization.enabled) {
    std::vector<int> principal;
    for (size_t i = 0; i < prims.size(); ++i)
      if (view.principal[i] && !prims[i].inferred) principal.push_back(int(i));
    regularize_principal(prims, principal, samples, P.regularization, P.alpha);
    const int templates =
        regularize_secondary(prims, grouping, view, io.bsp, samples, P.regularization, P.alpha);
    if (planes.snap_walls)  // onto the regularized planes
      snap_inferred_walls(prims, P.closure.wall_snap);
    if (templates > 0)
      st.notes.push_back(std::to_string(templates) +
                         " window cut-outs replaced by cuboid templates");
  }
  view.principal.resize(prims.size(), 0);  // template primitives are secondary
  SortedPrimitives sorted = sort_primitives(prims, view, grouping);
  const int uncovered = place_uncovered(prims, view, P.ioview.uncovered, sorted);
  if (uncovered > 0)
    st.notes.push_back(std::to_string(uncovered) + " uncovered surface primitives placed (" +
                       to_string(P.ioview.uncovered) + ")");
  if (planes.heights && P.airborne.detail_level) {
    const int added = append_detail_level(prims, sorted);
    if (added > 0)
      st.notes.push_back("airborne LiDAR: " + std::to_string(added) +
                         " roof planes and walls outside every IO-View structure form the last "
                         "level set");
  }
  st.clusters = int(grouping.clusters.size());
  st.level_sets = sorted.num_levels - 1;
  st.planes_sorted = int(sorted.order.size());
  for (size_t i = 0; i < prims.size(); ++i)
    R.planes.push_back(report_plane(prims[i], samples, sorted.level_of[i], sorted.cluster_of[i]));
  return {std::move(grouping), std::move(sorted)};
}

/// Step 4's result: the LOD-Tree's BSP and its LOD-nodes.
struct TreeStep {
  Bsp bsp;
  LodTree tree;
};

/// (ours) Airborne LiDAR: the LOD-Tree BSP's supports a hair's breadth apart
/// are one plane (airborne.plane_merge_*); none on other inputs.
PlaneMerge plane_merge(const LodParams& P, bool airborne) {
  if (!airborne) return {};
  return {P.airborne.plane_merge_distance, P.airborne.plane_merge_angle_deg * M_PI / 180.0};
}

/// 4. LOD-Tree: BSP in the order S, per-level leaf labels, LOD-nodes.
TreeStep tree_step(const Planes& planes, const SceneBox& box, const SortStep& S, const LodParams& P,
                   int threads, const Budget& budget, LodStats& st) {
  const std::vector<Primitive>& prims = planes.prims;
  const std::optional<HeightField>& heights = planes.heights;
  const SortedPrimitives& sorted = S.sorted;
  Bsp bsp(box.lo, box.hi, hull_polygons(prims, sorted.order, box), P.bsp.max_cells,
          plane_merge(P, heights.has_value()));
  if (bsp.cap_hit()) {
    st.bsp_cap_hit = true;
    st.notes.push_back("bsp.max_cells = " + std::to_string(P.bsp.max_cells) +
                       " reached in the LOD-Tree BSP: the primitives after that point do not cut "
                       "(raise bsp.max_cells to partition fully)");
  }
  budget.check("lod-tree");
  std::vector<std::vector<char>> leaf_labels;
  if (heights) {  // the height field knows no levels: every level sees the same cells
    for (char l : label_by_height(leaf_ray_origins(bsp, P.airborne.origins_per_cell), *heights))
      leaf_labels.emplace_back(size_t(sorted.num_levels), l);
  } else {
    const RayLabeller labeller(alpha_triangles(prims, sorted.level_of), P.labels.rays_per_cell);
    leaf_labels = labeller.label(leaf_ray_origins(bsp, P.labels.origins_per_cell),
                                 sorted.num_levels, threads);
  }
  clear_pad_leaves(bsp, box, leaf_labels);
  LodTree tree = build_tree(bsp, sorted, S.grouping, leaf_labels, P.tree);
  st.bsp_nodes = int(bsp.nodes().size());
  st.lod_nodes = int(tree.nodes.size());
  return {std::move(bsp), std::move(tree)};
}

/// 5. Traversal (Algorithm 1) and a watertight mesh per candidate; for
/// airborne LiDAR the LoD1.2 block first.
void models_step(const Samples& samples, const Planes& planes, const TreeStep& T,
                 const LodParams& P, int threads, const Progress& progress, const Budget& budget,
                 LodResult& R) {
  auto& st = R.stats;
  const std::optional<HeightField>& heights = planes.heights;
  const Bsp& bsp = T.bsp;
  const auto candidates = traverse(T.tree, bsp, P.tree, budget.deadline);
  // Cells relabelled in by the non-manifold repair of one candidate are
  // relabelled in the next ones too while they remain in the cut: consecutive
  // candidates share most of their cells, and each repair round is a full
  // extraction pass.
  std::set<int> repaired;
  int split_interpolations = 0;
  ExtractCache extract_cache;  // planes whose faces did not change are not recomputed
  extract_cache.threads = threads;
  for (size_t i = 0; i < candidates.size(); ++i) {
    progress(0.6 + 0.3 * double(i) / double(candidates.size()), "extraction");
    budget.check("extraction");
    const auto& c = candidates[i];
    std::vector<char> inside = c.inside;
    for (size_t k = 0; k < inside.size(); ++k)
      if (!inside[k] && repaired.count(c.partition[k])) inside[k] = 1;
    BspSurface surf = bsp.extract(c.partition, inside, &extract_cache);
    for (size_t k = 0; k < surf.inside.size(); ++k)
      if (surf.inside[k] && !c.inside[k]) repaired.insert(c.partition[k]);
    if (surf.triangles.triangles.empty()) continue;  // empty model (nothing inside yet)
    LodModel m;
    m.kind = c.kind;
    m.level = c.level;
    m.cuts = c.cuts;
    m.diff_sum = c.diff_sum;
    m.polygons = std::move(surf.polygons);
    m.mesh = std::move(surf.triangles);
    const int shells = drop_small_shells(m, kMinShellFraction);
    if (shells > 1 && c.kind == ModelKind::interpolation) {
      ++split_interpolations;  // (ours) a building in pieces is not worth streaming
      continue;
    }
    if (shells > 1)
      st.notes.push_back("model " + std::to_string(R.models.size()) + ": " +
                         std::to_string(shells) + " solids (a multi-solid)");
    m.volume = mesh_volume(m.mesh);
    if (surf.labels_flipped > 0)
      st.notes.push_back("model " + std::to_string(R.models.size()) + ": " +
                         std::to_string(surf.labels_flipped) +
                         " cells relabelled to remove non-manifold edges");
    R.models.push_back(std::move(m));
  }
  // (ours) The LoD1.2 block first: the outline at the height that fits the
  // points best, as coarse as a building gets.
  if (heights && P.airborne.block) {
    const OutlineDistances od = outline_distances(samples, *heights);
    try {
      R.models.insert(R.models.begin(), block_model(samples, *heights, od));
      st.block_first = true;
      st.notes.push_back(
          "model 0 is the outline extruded to its best-fitting height (LoD1.2 block)");
    } catch (const LodError& e) {
      st.notes.push_back(std::string("no LoD1.2 block: ") + e.what());
    }
    if (st.block_first) {  // the roof as the scanner saw it, to judge the chain against the block
      const std::vector<Vec3> returns = roof_returns(samples, od, P.airborne.roof_edge_margin);
      for (auto& m : R.models) {
        const double fit = roof_rmse(m.mesh, returns, heights->ground());
        m.roof_rmse = std::isnan(fit) ? -1.0 : fit;
      }
    }
  }
  if (split_interpolations > 0)
    st.notes.push_back(std::to_string(split_interpolations) +
                       " interpolation models in more than one solid left out");
  for (size_t i = 0; i < R.models.size(); ++i) R.models[i].step = int(i);
  if (R.models.empty()) throw LodError("traversal", "no non-empty model");
  for (const auto& c : candidates)
    if (c.kind == ModelKind::anchor) st.lod_tree_cuts_to_finest = c.cuts;
}

/// Plain BSP-Tree baseline: same primitives, area order, binary nodes.
void baseline_step(const std::vector<Primitive>& prims, bool airborne, const SceneBox& box,
                   const SortedPrimitives& sorted, const LodParams& P, LodStats& st) {
  std::vector<int> order = sorted.order;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return prims[size_t(a)].hull_area > prims[size_t(b)].hull_area;
  });
  const Bsp base(box.lo, box.hi, hull_polygons(prims, order, box), P.bsp.max_cells,
                 plane_merge(P, airborne));
  st.baseline_bsp_nodes = int(base.nodes().size());
  int internal = 0;
  for (const auto& n : base.nodes()) internal += n.is_leaf() ? 0 : 1;
  st.baseline_cuts_to_finest = internal;
}

/// (ours) Airborne LiDAR whose IO-View labels no cell inside or finds too few
/// principal primitives still has its roof height field: its model is then the
/// outline extruded to the height that fits the points best (the LoD1.2 block),
/// a fallback with the IO-View's reason, the height the returns reach and the
/// share of the outline with roof returns, rather than a prism to the points'
/// 95th percentile. False when no block can be made (no roof point).
bool block_fallback(const Samples& samples, const HeightField& hf, const std::string& why,
                    LodResult& R) {
  try {
    R.models.assign(1, block_model(samples, hf, outline_distances(samples, hf)));
    R.models.front().kind = ModelKind::fallback;
  } catch (const LodError&) {
    return false;
  }
  R.status = Status::fallback;
  R.reason = io_view_failure(why, hf);
  R.stats.notes.push_back(
      "fallback model: the outline extruded to its best-fitting height (LoD1.2 block)");
  return true;
}

/// The whole method; throws on any failure (caught by build_lod_tree).
void run_method(const BuildingInput& in, const Samples& samples, const LodParams& P, int threads,
                const Progress& progress, const Budget& budget, LodResult& R) {
  auto& st = R.stats;
  const auto t1 = Clock::now();

  progress(0.0, "planes");
  Planes planes = planar_primitives(in, samples, P, threads, st);
  budget.check("planes");

  progress(0.1, "io-view");
  std::optional<IoViewStep> io_step;
  try {
    io_step.emplace(io_view_step(samples, planes, P, threads, budget, st));
  } catch (const LodCancelled&) {
    throw;
  } catch (const LodBudgetExceeded&) {
    throw;
  } catch (const LodError& e) {
    if (!planes.heights || !P.airborne.block ||
        !block_fallback(samples, *planes.heights, e.what(), R))
      throw;
    return;
  }
  IoViewStep& io = *io_step;
  const SortStep S = sort_step(samples, planes, io, P, R);
  st.t_ioview = seconds_since(t1);
  budget.check("io-view");

  progress(0.4, "lod-tree");
  const auto t2 = Clock::now();
  const TreeStep T = tree_step(planes, io.box, S, P, threads, budget, st);
  st.t_tree = seconds_since(t2);
  budget.check("lod-tree");

  progress(0.6, "traversal");
  const auto t3 = Clock::now();
  models_step(samples, planes, T, P, threads, progress, budget, R);
  st.t_traversal = seconds_since(t3);

  if (P.bsp.baseline)
    baseline_step(planes.prims, planes.heights.has_value(), io.box, S.sorted, P, st);
}

}  // namespace

LodResult fallback_result(const BuildingInput& in, const std::string& reason) {
  LodResult r;
  r.status = Status::fallback;
  r.reason = reason;
  r.stats.input_points = int(in.points.size());
  r.stats.input_faces = int(in.triangles.size());
  r.models.push_back(extruded_outline(in));
  return r;
}

LodResult build_lod_tree(const BuildingInput& in, const LodParams& params,
                         const LodExecution& exec) {
  params.validate();
  check_input(in);
  LodResult R;
  R.stats.input_points = int(in.points.size());
  R.stats.input_faces = int(in.triangles.size());
  const Progress progress(exec.progress, exec.user);
  const int threads = std::max(1, exec.threads);
  const auto start = Clock::now();
  Budget budget{params.budget.time_budget_s > 0
                    ? start + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(params.budget.time_budget_s))
                    : Clock::time_point::max()};
  // Oriented samples of the input surface (normals estimated when missing).
  progress(0.0, "samples");
  // A city chunk of airborne LiDAR (a point cloud with walls along its
  // footprint) needs no normal propagation: its roofs face up.
  const bool city_lidar = params.airborne.mode != AirborneMode::Off && !in.is_mesh() &&
                          params.closure.footprint_walls && in.footprint.size() >= 3;
  const auto ts = Clock::now();
  const Samples samples = make_samples(in, params.normals, !city_lidar);
  R.stats.t_samples = seconds_since(ts);
  R.stats.normals_estimated = samples.normals_estimated;
  if (samples.normals_estimated)
    R.stats.notes.push_back("normals estimated and oriented (input had none)");
  Vec3 lo = samples.points.front(), hi = lo;
  for (const auto& p : samples.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double diag = std::max(1e-9, (hi - lo).norm());
  R.stats.bbox_diagonal = diag;
  const auto fall_back = [&](const std::string& reason) {
    LodResult f = fallback_result(in, reason);  // may throw LodError: no area at all
    R.status = f.status;
    R.reason = f.reason;
    R.models = std::move(f.models);
  };
  const LodResult fresh = R;
  try {
    run_method(in, samples, params, threads, progress, budget, R);
  } catch (const LodCancelled&) {
    throw;  // asked to stop: no model, not even the fallback
  } catch (const std::bad_alloc& e) {
    fall_back(e.what());
  } catch (const std::exception& e) {
    // (ours) A point cloud the rays could not label (a scan with many wall points
    // but gaps in them) is tried again as airborne LiDAR: walls on its outline,
    // cells labelled by its roof height field. Not after the budget.
    const std::string why = e.what();
    const bool retry = !in.is_mesh() && params.airborne.mode == AirborneMode::Auto &&
                       !airborne_input(in, samples, params) &&
                       !dynamic_cast<const LodBudgetExceeded*>(&e);
    if (!retry) {
      fall_back(why);
    } else {
      LodParams as_airborne = params;
      as_airborne.airborne.mode = AirborneMode::On;
      R = fresh;
      R.stats.notes.push_back("the rays failed (" + why +
                              "): modelled as airborne LiDAR (walls on the outline, cells "
                              "labelled by the roof height field)");
      try {
        run_method(in, samples, as_airborne, threads, progress, budget, R);
      } catch (const LodCancelled&) {
        throw;
      } catch (const std::exception& e2) {
        fall_back(why + "; as airborne LiDAR, " + e2.what());
      }
    }
  }
  // Fidelity of every model against the input (e1, e2 in % of the bbox diagonal).
  progress(0.9, "metrics");
  const auto tm = Clock::now();
  const FidelityMeter meter(in, samples, diag, params.metrics.samples);
  std::vector<const TriangleMesh*> meshes;
  for (const auto& m : R.models) meshes.push_back(&m.mesh);
  const std::vector<Fidelity> fidelity = meter.measure_all(meshes, threads);
  for (size_t i = 0; i < R.models.size(); ++i) {
    auto& m = R.models[i];
    m.e1 = fidelity[i].e1;
    m.e2 = fidelity[i].e2;
    m.hausdorff = fidelity[i].hausdorff;
    if (m.volume == 0.0) m.volume = mesh_volume(m.mesh);
  }
  if (R.status == Status::ok && R.stats.block_first && !R.stats.low_object.empty()) {
    const int dropped = drop_low_object_worse_than_block(R.models);
    if (R.models.size() == 1) {  // the block alone: the tree did not model it
      R.status = Status::fallback;
      R.reason = R.stats.low_object;
      R.models.front().kind = ModelKind::fallback;
      R.stats.notes.push_back(
          "fallback model: the outline extruded to its best-fitting height (LoD1.2 block); "
          "no model of the low object's chain fits the points better");
    } else if (dropped > 0) {
      R.stats.notes.push_back(std::to_string(dropped) +
                              " models of the low object's chain fitting the points worse than "
                              "the LoD1.2 block dropped");
    }
  }
  if (R.status == Status::ok && R.stats.block_first) {
    R.stats.worse_than_block = drop_worse_than_block(R.models);
    if (R.stats.worse_than_block > 0)
      R.stats.notes.push_back(std::to_string(R.stats.worse_than_block) +
                              " models fitting the points and the roof worse than the LoD1.2 "
                              "block dropped");
    const int last_levels = drop_worse_last_levels(R.models);
    if (last_levels > 0)
      R.stats.notes.push_back(std::to_string(last_levels) +
                              " models of the last level dropped: its anchor fits the points and "
                              "the roof worse than the anchor before it");
  }
  R.stats.t_metrics = seconds_since(tm);
  // The input's colours (if any) onto the faces of every model.
  const auto tc = Clock::now();
  colour_models(in, samples, params.colour, R.models, threads);
  R.stats.t_colour = seconds_since(tc);
  progress(1.0, "done");
  return R;
}

}  // namespace citylod::lod
