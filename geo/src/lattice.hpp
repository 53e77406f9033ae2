// citylod::geo::detail::Lattice — CRS -> ENU for large batches through a cached node
// lattice (Georef::to_local_inplace).
#pragma once
#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <utility>
#include <vector>

namespace citylod::geo::detail {

/// The map CRS (x, y, z) -> ENU is smooth in x, y and linear in z (the horizontal
/// operation ignores z, the geoid adds a height that does not depend on it, and the
/// ECEF of a geodetic point is linear in its height). So it is evaluated exactly
/// (by `exact`, PROJ) only at the nodes of a lattice of square cells, at two
/// heights, and in between by biquadratic interpolation over the cell's 3 x 3 nodes
/// (corners, edge midpoints, centre), linear in z.
///
/// Each cell is checked once against the exact map at three points (two heights
/// and a third between them): a cell whose check misses by more than `tolerance`
/// metres (a PROJ operation that changes within it, a grid's kink) or whose nodes
/// do not transform is evaluated exactly, point by point. So is every point that
/// is not finite or too far out for a cell index, and errors are the exact path's.
/// The result of a point depends only on its coordinates, not on the batch or on
/// what is cached: deterministic, whatever the batches and threads.
class Lattice {
 public:
  /// The exact map, in place, 3 x N; throws GeoError for a point it cannot map.
  using Exact = std::function<void(Eigen::Ref<Eigen::Matrix3Xd>)>;

  /// `cell`: cell side in CRS units; `height`: the second node height (CRS units,
  /// the first is 0); `tolerance`: metres.
  Lattice(double cell, double height, double tolerance);

  /// CRS -> ENU, in place.
  void apply(Eigen::Ref<Eigen::Matrix3Xd> points, const Exact& exact);

  /// Cells evaluated through the lattice / exactly so far (for tests and notes).
  std::size_t fast_cells() const;
  std::size_t exact_cells() const;

 private:
  struct Node {
    Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // ENU at z = 0, d/dz
    bool ok = false;
  };
  struct Cell {
    std::int64_t cx = 0, cy = 0;
    Node nodes[3][3];  // [along x][along y]
  };
  static std::uint64_t key(std::int64_t i, std::int64_t j) {
    return (std::uint64_t(i) << 32) ^ (std::uint64_t(j) & 0xffffffffu);
  }
  void prepare(const std::vector<std::pair<std::int64_t, std::int64_t>>& cells, const Exact& exact);
  Eigen::Vector3d interpolate(const Cell& c, const Eigen::Vector3d& p) const;

  double cell_, height_, tolerance_;
  std::unordered_map<std::uint64_t, Node> nodes_;      // node (i, j) at spacing cell / 2
  std::unordered_map<std::uint64_t, int> cell_index_;  // into cells_; -1: evaluated exactly
  std::vector<Cell> cells_;
  std::size_t exact_cells_ = 0;
};

}  // namespace citylod::geo::detail
