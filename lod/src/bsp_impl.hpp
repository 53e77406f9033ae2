// Internal to bsp*.cpp: the exact (EPECK) representation behind detail::Bsp.
// Only bsp.cpp, bsp_adjacency.cpp and bsp_extract.cpp include this header (CGAL
// stays inside them).
//
// Representation (Appendix B of the paper, ARCHITECTURE.md "Numeric robustness"):
//  - a plane table of exact planes built from double coefficients (merged when
//    equal within 1e-12); the 6 box planes first, then the support planes of
//    the input polygons, then the "edge planes" bounding the input polygons;
//  - every vertex is the intersection of 3 planes of the table, constructed
//    once (depth-1 lazy construction), with the set of table planes it lies on
//    and a cache of its signs w.r.t. other planes;
//  - a convex polygon = support plane + vertex loop + one "edge plane" per
//    edge (a table plane containing the edge, other than the support);
//  - a cell = closed convex polyhedron = faces (polygon + side of its plane on
//    which the cell lies), each loop counter-clockwise seen from outside.
#pragma once

#include "bsp.hpp"

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace citylod::lod::detail::bspi {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using FT = K::FT;
using ET = FT::ET;  ///< exact number type (GMP rationals)
using EK = K::Exact_kernel;
using Point3 = K::Point_3;
using Plane3 = K::Plane_3;

struct Vertex {
  Point3 p;                            ///< lazy intersection of the 3 defining planes
  std::array<int, 3> def{-1, -1, -1};  ///< the defining planes
  Vec3 approx = Vec3::Zero();
  std::vector<int> planes;                         ///< table planes the vertex lies on (exactly)
  std::vector<std::pair<int, signed char>> signs;  ///< cached non-zero signs
};

/// Convex polygon: loop v (CCW seen from +normal of `plane` for input pieces,
/// from outside the cell for cell faces), e[i] = plane containing edge v[i]->v[i+1].
struct Poly {
  int plane = -1;
  std::vector<int> v;
  std::vector<int> e;
};

struct Face {
  Poly poly;
  bool cell_pos = false;  ///< the cell lies on the positive side of poly.plane
};

struct Cell {
  std::vector<Face> faces;
};

struct Piece {
  Poly poly;
  int primitive = -1;
};

struct CutKey {
  int a, b, p;
  bool operator==(const CutKey& o) const { return a == o.a && b == o.b && p == o.p; }
};
struct CutKeyHash {
  size_t operator()(const CutKey& k) const {
    uint64_t h = (uint64_t(uint32_t(k.a)) * 0x9E3779B97F4A7C15ULL) ^
                 (uint64_t(uint32_t(k.b)) * 0xC2B2AE3D27D4EB4FULL) ^
                 (uint64_t(uint32_t(k.p)) * 0x165667B19E3779F9ULL);
    return size_t(h ^ (h >> 29));
  }
};

/// All state of a Bsp (Bsp::Impl derives from it; helpers take it by reference).
struct BspData {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  PlaneMerge merge;  ///< supports this close are one plane (bsp.cpp, snap_to_near_support)
  std::vector<Plane3> planes;                  ///< exact table
  std::vector<std::array<double, 4>> dplanes;  ///< their (unit) double coefficients
  int n_split_planes = 6;                      ///< planes() = dplanes[0, n_split_planes)
  std::vector<Vertex> verts;
  std::unordered_map<CutKey, int, CutKeyHash> cut_memo;     ///< (edge endpoints, plane) -> vertex
  std::unordered_map<CutKey, int, CutKeyHash> triple_memo;  ///< sorted plane triple -> vertex
  std::vector<BspNode> nodes;
  std::vector<Cell> cells;  ///< one polyhedron per node
  bool cap_hit = false;

  // --- construction helpers (bsp.cpp) ---
  /// Index of a plane equal (within 1e-12, either orientation) to c, adding it
  /// if new; *flip = +1 if the table plane has the same orientation, -1 otherwise.
  int find_or_add_plane(const std::array<double, 4>& c, int* flip);
  int add_vertex(const Point3& p, const std::array<int, 3>& def, std::vector<int> on_planes);
  /// Exact intersection point of 3 table planes, computed with integer
  /// determinants, as exact numbers (a lazy point made of them has no DAG to
  /// evaluate). Throws std::logic_error when the planes are not independent.
  void exact_coords_of(const std::array<int, 3>& def, ET out[3]) const;
  /// Exact sign of vertex v w.r.t. table plane P (cached).
  int sign(int v, int P);
  /// Exact sign of the point of the 3 table planes `def` w.r.t. table plane
  /// P, with integer determinants.
  int exact_sign_of(const std::array<int, 3>& def, int P) const;
  /// Vertex where edge (a,b) (on planes S and E) crosses P; memoized by (a,b,P)
  /// and by the plane triple.
  int cut(int a, int b, int S, int E, int P);
  /// Split a convex polygon by P; parts with a strictly negative (positive)
  /// vertex go to *neg (*pos) (either may be null). Unused outputs are cleared.
  void split_poly(const Poly& f, int P, Poly* neg, Poly* pos);
  /// Strict split of a cell by P (P must cut the open cell). cap = the section
  /// polygon, CCW seen from +P.
  void split_cell(const Cell& c, int P, Cell* neg, Cell* pos, Poly* cap);
  /// -1/0/+1: all vertices <=0 / mixed (P cuts the open cell) / all >=0; 2 if all on P.
  int classify_cell(const Cell& c, int P);
  void fill_node_geometry(BspNode& n, const Cell& c) const;
  std::vector<int> cell_vertex_ids(const Cell& c) const;
};

/// Surface extraction (bsp_extract.cpp).
BspSurface extract_surface(const BspData& D, const std::vector<int>& partition,
                           std::vector<char> inside, ExtractCache* cache);

}  // namespace citylod::lod::detail::bspi

namespace citylod::lod::detail {
struct Bsp::Impl : bspi::BspData {};
}  // namespace citylod::lod::detail
