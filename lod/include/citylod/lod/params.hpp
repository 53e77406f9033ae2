// Parameters of every stage of the LOD-Tree method, one struct per stage, with
// the defaults of the paper (Section 4 and appendices B-C).
#pragma once

#include <string>
#include <vector>

namespace citylod::lod {

/// The modes of the parameters below, by the words params.json and --set use
/// (to_string / LodParams::set).
enum class Uncovered { Noise, S0, Last };   ///< ioview.uncovered
enum class VolumeScale { Ratio, M3 };       ///< cluster.volume_scale
enum class Terrain { Plinth, Cut };         ///< closure.terrain
enum class AirborneMode { Auto, On, Off };  ///< airborne.mode
const char* to_string(Uncovered v);         ///< noise, s0, last
const char* to_string(VolumeScale v);       ///< ratio, m3
const char* to_string(Terrain v);           ///< plinth, cut
const char* to_string(AirborneMode v);      ///< auto, on, off

/// Normal estimation when the input has none (points) — PCA over k neighbours.
struct NormalParams {
  int k_neighbors = 12;
};

/// Plane detection by region growing (paper: eps 0.15 m, theta 40 deg, sigma 15).
struct PlaneParams {
  double epsilon = 0.15;
  double max_angle_deg = 40.0;
  int min_region_size = 15;
  int k_neighbors = 12;
  int max_planes = 400;
};

/// Alpha-shapes of the planar primitives (paper: alpha = 7 m).
struct AlphaParams {
  double alpha = 7.0;
};

/// BSP of the enlarged bounding box (Appendix B).
struct BspParams {
  double bbox_enlarge = 0.05;
  int max_cells = 60000;
  bool baseline = false;
};

/// In/out labelling by ray casting (Appendix C).
struct LabelParams {
  int rays_per_cell = 100;
  /// (ours) ray origins per cell: 1 = the paper's centre only; more spreads the
  /// rays over the centre and points halfway to the cell's vertices.
  int origins_per_cell = 1;
};

/// IO-View analysis (Section 4.1).
struct IoViewParams {
  double separation_coverage = 0.5;
  double min_principal_area = 0.5;
  /// true: the paper's rule, a face counts towards a plane's principal area
  /// and host contact only where its alpha-shape covers it. false (ours,
  /// default): the whole face on the plane counts (BENCHMARKS.md: the paper's
  /// rule takes 82 of cgal_building's 193 principal planes out of S0 and its
  /// finest e2 from 0.497 to 0.637 %, over the 0.5 % target).
  bool covered_only = false;
  /// With covered_only: the primitives on whose plane the V_in/V_out
  /// interface lies (over min_principal_area) but whose alpha-shapes cover too
  /// little of it to be principal, and which bound no secondary structure.
  /// "noise": left out of S; "s0": in S0 after the principal primitives;
  /// "last": one more, last level set. Not the default: with covered_only,
  /// cgal_building's finest e2 is 0.637 / 0.718 / 0.708 % (BENCHMARKS.md).
  Uncovered uncovered = Uncovered::Noise;
};

/// Two-stage mean-shift clustering (Section 4.1).
struct ClusterParams {
  double area_bandwidth = 2.0;
  /// stage 2: mean volume per cluster -> level sets. "ratio" (ours): a factor,
  /// mean shift on ln V with bandwidth ln 4 (mean volumes within a factor ~4
  /// share a level set); "m3": the literal reading, bandwidth 4 m^3 on V.
  double volume_bandwidth = 4.0;
  VolumeScale volume_scale = VolumeScale::Ratio;
};

/// Adaptive regularization (Section 4.1).
struct RegularizationParams {
  bool enabled = true;
  double principal_angle_deg = 5.0;
  double principal_distance = 0.01;
  double secondary_angle_deg = 15.0;
  double secondary_distance = 0.01;
  double vertical_host_deg = 5.0;
  int min_cutouts_for_templates = 4;  // the paper's "more than three"
};

/// LOD-Tree construction and traversal (Section 4.2).
struct TreeParams {
  int merge_k = 10;
  double label_volume_ratio = 0.65;
  double interpolation_ratio = 0.80;
  /// (ours) no interpolation model once the diff sum is below this fraction of
  /// the level's initial diff sum: the remaining changes are too small to see,
  /// and without it the 80 % rule yields one model per 20 % of an ever smaller tail.
  double interpolation_floor = 0.02;
};

/// Work bounds per building; hitting one gives a recorded fallback.
struct BudgetParams {
  double time_budget_s = 120.0;
};

/// Closure of airborne LiDAR buildings that have roofs but few walls.
struct ClosureParams {
  bool enabled = true;
  double wall_fraction_min = 0.05;
  double outline_alpha = 1.5;
  /// What becomes of a terrain sheet around the building (photogrammetry
  /// meshes cut out of a city model): "plinth" keeps it as the top of a solid
  /// under the whole scene (what the paper's BSP labelling of such an input
  /// gives: the model represents all of the input), "cut" leaves it out and
  /// closes the building at the terrain's height under its own outline (the
  /// city pipeline, whose chunks have no ground, sets this).
  Terrain terrain = Terrain::Plinth;
  /// Walls along a given footprint even when some walls were scanned
  /// (airborne LiDAR hits towers and facades in part; without them a tower's
  /// cells see the sky sideways and are lost). City runs set this; a single
  /// building's scan without a footprint is unaffected.
  bool footprint_walls = false;
  double plinth_depth = 0.5;
  /// (ours) No ground height given (a lone building's points) and the lowest samples are
  /// roof, not wall bottoms (half of the points within 1 m of the lowest: roof-only LiDAR of
  /// a shed or a flat annex spans 0.2 m): the ground is put this far below the lowest
  /// sample, a storey, instead of at it, where the building has no height (City3D AHN3: 76
  /// of 800 buildings "no cell labelled inside").
  double unknown_ground_depth = 3.0;
  /// (ours) Meshes on a footprint (city mesh chunks, labelled by rays): the
  /// inferred walls stand under the roof's profile along their edge, not up
  /// to the highest sample within 1 m (whose back votes the cells over a low
  /// wing or a gable's slopes inside).
  bool wall_profile = true;
  /// (ours) Meshes on a footprint: an inferred wall within this distance
  /// (m, and 3 degrees) of a seen vertical plane takes its plane, so the BSP
  /// cuts no sliver cells between them; 0 = never.
  double wall_snap = 0.15;
};

/// (ours) Airborne LiDAR (a point cloud that sees few walls) is 2.5D: walls
/// stand on the outline, cells are labelled in/out by a robust roof height
/// field instead of rays, vertical walls are inferred where the roof steps
/// down, and the chain starts with the outline extruded to its best-fitting
/// height (LoD1.2 block).
struct AirborneParams {
  /// auto: point clouds seeing less than `wall_fraction_max` of walls, and city chunks on a
  /// footprint; on: every input; off: none (rays label the cells)
  AirborneMode mode = AirborneMode::Auto;
  /// (ours) auto: a point cloud whose share of wall samples (|normal.z| < 0.3) is below this
  /// is airborne. City3D's AHN3 buildings reach 0.29 (p90 0.13), DALES 0.43 (p90 0.05); a
  /// terrestrial or MVS scan of facades 0.5 (cgal_building.ply). Was closure.wall_fraction_min
  /// (0.05): 339 of 800 AHN3 buildings went to the rays, 244 fell back. A point cloud above
  /// it whose rays fail is tried again as airborne before it falls back.
  double wall_fraction_max = 0.35;
  double cell = 0.5;
  double fill_radius = 1.5;
  /// A roof plane's edge gets a step wall where the roof beyond it,
  /// extrapolated back to the edge (probed step_probe and step_probe + 1 m
  /// beyond), lies this much lower; or where the roof step_probe beyond lies
  /// step_min_raw lower (the rule before session 27, which a roof sloping
  /// down from the edge also meets). City runs take 0.5 m (tiler
  /// city_lod_params): stair houses, parapets and dormers 0.5-1 m high
  /// (City3D scene finest median 0.179 -> 0.172 m). Without a footprint
  /// 0.3 m with the raw rule made 14 of City3D's 920 finest models
  /// self-intersecting: 1 m there, the rule before.
  double step_min = 1.0;
  double step_min_raw = 1.0;
  double step_probe = 0.75;
  double step_alpha = 1.0;
  double step_min_edge = 1.0;
  int origins_per_cell = 9;
  /// Smallest plane (points) on airborne input: the paper's 15 suit dense
  /// MVS; at AHN3's ~10 points/m^2 they lose roof parts under 1.5 m^2
  /// (Delft tile: finest RMSE median 0.193 m with 15, 0.136 m with 8).
  int min_region_size = 8;
  bool block = true;
  /// Roof planes refitted robustly before the BSP: Tukey-weighted least
  /// squares (scale 1.4826 MAD), points within `roof_edge_margin` of the
  /// outline weighted down linearly (gutters, wall tops and eaves mixed into
  /// the edge returns pull a plane fitted to all its points off the roof).
  /// Off: the region growing's least-squares planes. Tuned on the Delft
  /// tile's 26 buildings (roof height RMSE median 0.051 -> 0.045 m), the
  /// refit lost on 1,188 City3D scene buildings: finest RMSE median 0.177 m
  /// with it, 0.174 m without, better than roofer's LoD2.2 on 646 / 748.
  bool roof_refit = false;
  /// Returns farther inside the outline than this are the roof as the
  /// scanner saw it (`roof_rmse`); nearer ones weigh less in the refit.
  double roof_edge_margin = 1.5;
  /// Roof planes and inferred walls outside every IO-View structure form the
  /// last level set (the paper drops them as noise; on airborne LiDAR they are
  /// roof detail. Delft tile: the 7689-point building's finest RMSE 0.286 ->
  /// 0.178 m).
  bool detail_level = true;
  /// Support planes of the LOD-Tree BSP whose normals are within
  /// plane_merge_angle_deg (either orientation) and whose polygons each lie
  /// within plane_merge_distance of the other's plane are one plane (0: off):
  /// two such planes (e.g. a scanned wall 2 cm beside the footprint's wall)
  /// cross or run side by side at a hair's breadth and cut wedges and slabs
  /// under a validator's 1 mm snap, which fold when it welds them. Under
  /// the 0.15 m of LiDAR plane detection they are one surface. Not on other
  /// inputs: a dense cloud's window recesses are that close (cgal_building's
  /// finest e2 0.497 -> 0.631 % at 5 cm, 0.505 % at 1 cm / 1 degree).
  double plane_merge_distance = 0.05;
  double plane_merge_angle_deg = 3.0;
};

/// (ours) Consistent orientation of the detected planes before IO-View: a
/// plane whose front the other planes see as clearly more inside than its back
/// (input normals pointing into the building) is turned round.
struct OrientParams {
  bool enabled = true;
  int points_per_plane = 4;
  int rays = 100;
  double offset = 0.1;
  double margin = 0.2;
};

/// Evaluation (e1/e2 RMSE).
struct MetricParams {
  int samples = 5000;  // on point clouds e1 takes at most 2 per input point, at least 250
};

/// Input colours onto the models' faces (ours; the paper has no colour): each
/// input point goes to the nearest face within `distance` whose plane is
/// within `max_angle_deg` of the point's normal (so a coarse model's roof, a
/// little above or below the roof points, takes their colour too, and a wall
/// does not take the colour of the roof edge's returns); a plane region
/// (coplanar faces sharing edges) with at least `min_points` points gets
/// their per-channel median colour.
struct ColourParams {
  bool enabled = true;
  double distance = 1.0;
  double max_angle_deg = 60;
  int min_points = 5;
};

/// One parameter described: dotted name, value (as items() writes it), unit ("" for
/// switches and modes), the rule it must meet (or the words it takes) and what it does.
struct ParamInfo {
  std::string name, value, unit, rule, doc;
};

/// Every parameter of the LOD stages. Each field's unit, rule and one-line doc
/// are declared once, in visit() (lod/src/params.cpp), and listed by
/// `citylod lod --help`; its default is its initialiser.
struct LodParams {
  NormalParams normals;
  PlaneParams planes;
  AlphaParams alpha;
  BspParams bsp;
  LabelParams labels;
  IoViewParams ioview;
  ClusterParams cluster;
  RegularizationParams regularization;
  TreeParams tree;
  BudgetParams budget;
  ClosureParams closure;
  AirborneParams airborne;
  OrientParams orient;
  MetricParams metrics;
  ColourParams colour;

  /// Throws std::invalid_argument naming the offending parameter.
  void validate() const;
  /// Set one parameter by dotted name ("planes.epsilon", "tree.merge_k", ...).
  /// Throws std::invalid_argument for an unknown name or bad value.
  void set(const std::string& name, const std::string& value);
  /// All parameters as (dotted name, value) pairs, in a fixed order.
  std::vector<std::pair<std::string, std::string>> items() const;
  /// All parameters as `citylod lod --help` lists them, in the order of items().
  std::vector<ParamInfo> describe() const;
};

}  // namespace citylod::lod
