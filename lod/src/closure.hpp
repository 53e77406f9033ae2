// Internal: closure of buildings whose walls or bottom were not scanned
// (ours): ground/base plane, outline walls, terrain kept as a plinth or cut
// off; and the 2D outline tools the airborne step shares. Implemented in
// closure.cpp (CGAL inside).
#pragma once

#include "planes.hpp"

#include <vector>

namespace citylod::lod::detail {

/// Airborne LiDAR closure: when walls are missing (few near-horizontal
/// normals), adds a ground plane and vertical walls through the outline (the
/// footprint when given, else a 2D alpha-shape of the samples, simplified).
/// With p.footprint_walls, walls go along a given footprint even when some
/// walls were scanned. An open bottom gets a base plane; a terrain sheet
/// (params.terrain) becomes a plinth (base + walls along the scene's outline)
/// or is cut off. With `outline_walls` (airborne input, whose height field
/// labels the cells inside the outline) walls go along the outline even when
/// some walls were scanned.
struct Closure {
  enum What { None, Base, Walls, FootprintWalls, Plinth };
  int added = 0;  ///< primitives added
  What what = None;
  std::vector<Vec2> outline;  ///< the outline the walls stand on (CCW), when walls were inferred
  double ground_z = 0;        ///< the ground plane's height
  /// Meshes on a footprint (wall_snap > 0): inferred walls were snapped onto the seen
  /// walls they nearly coincide with (`snapped` of them); to redo after regularization.
  bool snap_walls = false;
  int snapped = 0;
};
Closure close_building(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                       std::vector<Primitive>& prims, bool outline_walls = false);

/// (ours) An inferred outline wall that (nearly) coincides with another
/// vertical plane -- a scanned wall along the same footprint edge (within 3
/// degrees, its edge within max_off of that plane), or another inferred wall
/// on a collinear footprint edge -- takes that plane's exact equation (the
/// largest scanned one first), its hull projected onto it: the exact BSP
/// then cuts along one plane instead of two a few millimetres apart, whose
/// sliver cells turn into sub-millimetre faces. Its alpha triangles stay
/// where they were: coplanar overlapping triangles of two primitives send the
/// ray labelling to exact arithmetic (mesh_city: IO-View 0.7 -> 6 s).
/// Returns the walls snapped.
int snap_inferred_walls(std::vector<Primitive>& prims, double max_off);

/// Largest outer boundary loop (CCW) of the 2D alpha-shape of the points.
std::vector<Vec2> alpha_outline(const std::vector<Vec2>& xy, double alpha);

/// Douglas-Peucker on a closed polygon, then merge of nearly collinear edges.
std::vector<Vec2> simplify_closed(std::vector<Vec2> poly, double tol, double angle_deg);

}  // namespace citylod::lod::detail
