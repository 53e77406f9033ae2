// Internal: adaptive binary space partitioning of a box by convex polygons,
// with exact predicates and constructions (EPECK) — Appendix B. The same class
// serves the IO-View partition (area order) and the LOD-Tree's BSP (scale-sorted
// order), and extracts watertight surfaces from any labelled partition made of
// its nodes. Implemented in bsp.cpp, bsp_adjacency.cpp and bsp_extract.cpp (CGAL
// inside; nothing of CGAL leaks here).
#pragma once

#include "citylod/lod/types.hpp"

#include <array>
#include <memory>
#include <vector>

namespace citylod::lod::detail {

/// BspPolygon::primitive of the cuts that are no primitive (the data box's
/// faces, cut first at level 0: lod_pipeline.cpp, tree.cpp).
constexpr int kBoxCut = -2;

/// A convex polygon on its plane, used to split space.
struct BspPolygon {
  std::array<double, 4> plane;  ///< a,b,c,d with (a,b,c) unit: a x + b y + c z + d = 0
  std::vector<Vec3> polygon;    ///< convex, vertices (nearly) on the plane, any orientation
  int primitive = -1;           ///< caller's id, reported back in nodes
};

struct BspNode {
  int parent = -1;
  std::array<int, 2> children{
      -1, -1};  ///< [0] negative side, [1] positive side of the split plane; -1 for leaves
  int split_primitive = -1;  ///< caller id of the polygon that split this node (-1 for leaves)
  int split_plane = -1;      ///< index into planes() of the split plane
  int depth = 0;
  double volume = 0.0;         ///< m^3
  Vec3 center = Vec3::Zero();  ///< mean of the cell's vertices (inside the cell)
  bool is_leaf() const { return children[0] < 0; }
};

/// Shared face between two nodes of a partition.
struct BspInterface {
  int a = -1, b = -1;  ///< node ids; a on the negative side of the plane, b on the positive side
  int plane = -1;      ///< index into planes()
  double area = 0.0;   ///< m^2
  std::vector<Vec3> polygon;  ///< the shared convex polygon (double)
};

/// Plane regions of earlier extractions, reused when the faces of inside cells
/// on a plane are unchanged: consecutive LOD candidates differ by a few cells,
/// so most planes are. One cache per sequence of extractions (not shared
/// between threads); results are identical with and without it.
class ExtractCache {
 public:
  ExtractCache();
  ~ExtractCache();
  ExtractCache(const ExtractCache&) = delete;
  ExtractCache& operator=(const ExtractCache&) = delete;
  /// Threads inside one extraction (the planes' regions and triangulations
  /// in parallel; the result does not depend on it).
  int threads = 1;
  struct Impl;
  std::unique_ptr<Impl> impl;
};

/// Surface extracted from a labelled partition.
struct BspSurface {
  PolygonMesh polygons;    ///< coplanar faces merged; each face a hole-free CCW (from outside) loop
  TriangleMesh triangles;  ///< watertight, outward, edge-manifold triangulation of the same surface
  int merged_regions = 0;  ///< number of merged coplanar regions (polygons with holes count once)
  int labels_flipped = 0;  ///< cells relabelled to remove non-manifold edges and pinched vertices
  std::vector<char>
      inside;  ///< labels actually used (input labels after relabelling), per partition entry
  std::vector<char>
      edge_repaired;  ///< per partition entry: turned in to remove a non-manifold edge
};

/// (ours) Support planes this close are one plane (Bsp's constructor;
/// LodParams' airborne.plane_merge_distance / _angle_deg). distance 0: off.
struct PlaneMerge {
  double distance = 0;  ///< m
  double angle = 0;     ///< rad
};

class Bsp {
 public:
  /// Adaptive BSP of the box [lo, hi] by `ordered` polygons, processed in the
  /// given order (index 0 first). A node is split only by a polygon piece that
  /// has positive area inside it; pieces spanning the split plane are split and
  /// carried into both children; the splitting piece and pieces lying on the
  /// split plane are consumed. Planes equal up to 1e-12 are merged. Stops
  /// splitting when `max_leaves` leaves exist (cap_hit() then true).
  /// max_leaves <= 0: no limit. Polygons on a box face, of no area, or missing
  /// the open box are ignored; each polygon is clipped to the box. With
  /// merge.distance > 0, a polygon whose plane is within merge.angle of an
  /// earlier polygon's support, each polygon within merge.distance of the
  /// other's plane, takes that support.
  Bsp(const Vec3& lo, const Vec3& hi, const std::vector<BspPolygon>& ordered, int max_leaves,
      PlaneMerge merge = {});
  ~Bsp();
  Bsp(Bsp&&) noexcept;
  Bsp& operator=(Bsp&&) noexcept;

  bool cap_hit() const;
  const std::vector<BspNode>& nodes() const;  ///< nodes()[0] is the root (the box)
  std::vector<int> leaves() const;            ///< leaf ids in increasing order
  std::vector<std::array<double, 4>> planes()
      const;                                        ///< distinct split planes (box planes first: 6)
  std::vector<Vec3> cell_vertices(int node) const;  ///< vertices of a node's polyhedron (double)

  /// Interfaces of positive area between the nodes of `partition` (a set of
  /// disjoint nodes covering the box, e.g. the leaves, or any cut of the tree).
  /// Deterministic order.
  std::vector<BspInterface> adjacency(const std::vector<int>& partition) const;

  /// The boundary between inside and outside nodes of `partition`
  /// (inside[i] labels partition[i]; the outside of the box is out). Output is
  /// closed, outward-oriented, edge-manifold (non-manifold edges are removed by
  /// relabelling the smallest adjacent out-node in), free of self-intersections
  /// and T-junctions; coplanar faces merged. Deterministic. Thread-safe
  /// (const; several threads may extract from one Bsp concurrently).
  BspSurface extract(const std::vector<int>& partition, std::vector<char> inside,
                     ExtractCache* cache = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::lod::detail
