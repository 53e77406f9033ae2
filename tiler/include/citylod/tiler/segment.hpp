// Part of the split stage: per-cell ground classification, vegetation features and
// building segmentation (PCL stays inside segment.cpp). Works on the points of
// one cell plus its halo, in scene ENU metres.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "citylod/io/types.hpp"
#include "citylod/tiler/footprints.hpp"

namespace citylod::tiler {

/// What the point classes of the scene can be trusted for.
enum class ClassMode {
  none,       ///< no classes (or --ignore-classes): DTM by grid-minimum opening, features for trees
  ground,     ///< class 2 present, no building class: DTM from class 2, features for trees
  buildings,  ///< classes 2 and 6 present: buildings are class 6
};
const char* class_mode_name(ClassMode m);

/// Parameters of the segmentation, metres unless stated.
struct SegmentParams {
  double dtm_resolution = 1.0;     ///< DTM grid step
  double dtm_window = 48.0;        ///< opening window of the grid-minimum DTM (> largest building)
  double ground_tolerance = 0.5;   ///< a point is ground if z - DTM < this (no ground class)
  double min_height = 2.0;         ///< building candidates lie this high above the ground
  double cluster_tolerance = 1.0;  ///< Euclidean clustering distance (2D)
  int min_cluster_points = 30;     ///< smaller clusters are noise
  double min_area = 12.0;          ///< m^2, 2D convex hull of a building cluster
  double min_building_height = 2.5;  ///< highest point above ground of a building cluster
  int feature_neighbours = 16;       ///< k of the local PCA
  double max_scatter = 0.04;         ///< lambda3/lambda1 above which a point looks like foliage
  double max_vegetation_ratio =
      0.5;  ///< rejected when foliage points in its hull / members exceed this
  double min_planar_fraction = 0.6;  ///< rejected when fewer cluster points have planarity > 0.5
  double min_width = 3.0;  ///< narrower clusters (2D hull width) are vehicles, hedges, walls
  /// Without a building class, clusters lower than this (buses, vans, hedges, sheds under trees)
  /// must also have at most `low_max_vegetation_ratio` foliage and `low_min_planar_fraction` planar
  /// points.
  double low_height = 5.0;
  double low_max_vegetation_ratio = 0.1;
  double low_min_planar_fraction = 0.7;
};

/// Height grid over a region (ENU metres), aligned to multiples of the resolution
/// so that overlapping regions agree.
struct GroundGrid {
  double x0 = 0, y0 = 0, res = 1;
  int nx = 0, ny = 0;
  std::vector<float> z;
  double at(double x, double y) const;  ///< nearest cell, clamped to the grid
};

/// One cluster found in a cell.
struct Cluster {
  std::vector<std::uint32_t> members;  ///< indices into the cell's points
  io::Vec3d centroid{0, 0, 0};
  /// Lexicographically smallest member position: exact, the same in every view that
  /// holds the whole cluster, so it decides which cell owns the cluster.
  io::Vec3d anchor{0, 0, 0};
  Ring hull;                    ///< 2D convex hull, CCW
  double area = 0;              ///< hull area
  double width = 0;             ///< hull width (smallest extent over all directions)
  double height = 0;            ///< max height above ground
  double vegetation_ratio = 0;  ///< foliage-like points inside the hull / members
  double planar_fraction = 0;   ///< members with planarity > 0.5 / members
  bool building = false;
  std::string reject_reason;  ///< why it is not a building
};

struct CellSegmentation {
  GroundGrid dtm;
  std::vector<float> hag;             ///< height above ground per point
  std::vector<std::uint8_t> ground;   ///< 1 = ground point
  std::vector<std::uint8_t> foliage;  ///< 1 = rejected as vegetation-like (point level)
  std::vector<Cluster> clusters;      ///< empty unless clustering was asked for
};

/// Ground, height above ground, point-level vegetation flags and (when `cluster`)
/// building clusters of the points `pos` (scene ENU; `cls` empty or one per point).
/// `region` = {xmin, ymin, xmax, ymax}, the area the points were gathered from.
CellSegmentation segment_cell(const std::vector<io::Vec3d>& pos,
                              const std::vector<std::uint8_t>& cls, ClassMode mode,
                              const SegmentParams& params, const std::array<double, 4>& region,
                              bool cluster);

/// Euclidean clustering as PCL's EuclideanClusterExtraction does it (the same
/// clusters in the same order), on a hash grid of tolerance-sized cells instead of a
/// kd-tree: two points are neighbours when their float squared distance, summed axis by
/// axis (FLANN's L2_Simple<float>), is < float(double(float(tolerance))^2) (FLANN's radius
/// test as PCL calls it); clusters are the connected sets, found from seeds in index
/// order, each with its indices ascending; those of >= `min_size` points, sorted by size
/// as PCL sorts them (largest first). Why not PCL's kd-tree: BENCHMARKS.md, "Splitting".
std::vector<std::vector<std::uint32_t>> euclidean_clusters(
    const std::vector<std::array<float, 3>>& points, double tolerance, std::size_t min_size);

/// ASPRS classes never part of a building: ground, vegetation, noise, water, ...
bool non_building_class(std::uint8_t c);

}  // namespace citylod::tiler
