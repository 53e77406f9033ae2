// Internal: planar primitives (paper Section 4.1): region-growing plane
// detection, alpha-shapes and convex hulls. Implemented in planes.cpp (CGAL
// inside).
#pragma once

#include "samples.hpp"

#include <array>
#include <vector>

namespace citylod::lod::detail {

/// A planar primitive with its alpha-shape and convex hull.
struct Primitive {
  Vec3 normal = Vec3::UnitZ();  ///< unit, oriented like its inliers' normals (outward)
  double d = 0.0;               ///< plane: normal.dot(x) + d = 0
  std::vector<int> inliers;     ///< indices into Samples
  Vec3 centroid = Vec3::Zero();
  Vec3 u = Vec3::UnitX(), v = Vec3::UnitY();  ///< orthonormal in-plane axes, u x v = normal
  std::vector<Vec3> hull;  ///< convex hull of the projected inliers, CCW about normal
  std::vector<std::array<Vec3, 3>> alpha_tris;  ///< alpha-shape as triangles on the plane
  double hull_area = 0.0;
  double alpha_area = 0.0;
  bool inferred = false;       ///< closure plane (ground / outline wall), not detected
  bool from_template = false;  ///< cuboid template face
};

/// Orthonormal in-plane frame with u x v = n (u horizontal for non-horizontal planes).
void plane_frame(const Vec3& n, Vec3& u, Vec3& v);

/// Region growing (CGAL Shape_detection): on the points of a cloud, on the
/// faces of a mesh. Deterministic. Largest planes first; at most p.max_planes
/// (`*found`, when given, receives the number of regions found before the cap).
/// Shapes (alpha-shapes, hulls) with `alpha`. The neighbour lists of a cloud
/// are found on `threads` threads (the regions do not depend on it).
std::vector<Primitive> detect_planes(const BuildingInput& in, const Samples& s,
                                     const PlaneParams& p, const AlphaParams& alpha = {},
                                     int threads = 1, int* found = nullptr);

/// (Re)computes centroid, u/v, hull and alpha-shape of a primitive from its
/// inliers projected on its current plane.
void compute_shape(Primitive& prim, const Samples& s, const AlphaParams& p);

}  // namespace citylod::lod::detail
