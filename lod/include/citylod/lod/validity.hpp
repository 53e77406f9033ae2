// Validity of a solid as val3dity (ISO 19107, the validator 3DBAG publishes
// with) judges it at its tolerances: vertices closer than `snap` are one
// vertex, each face is one planar, simple ring (distance to its fitted plane,
// and the normals of its constrained triangulation within an angle), each
// shell a closed, 2-manifold, outward, self-intersection-free surface of one
// connected piece. check_mesh (lod.hpp) is the exact check of a triangle mesh;
// check_solid is what a validator reading the written polygons finds.
#pragma once

#include "citylod/lod/types.hpp"

#include <string>
#include <vector>

namespace citylod::lod {

/// val3dity's default tolerances.
struct Tolerances {
  double snap = 0.001;                ///< m: vertices at most this far apart are one vertex
  double planarity_d2p = 0.01;        ///< m: a face vertex's distance to the fitted plane
  double planarity_normals_deg = 20;  ///< degrees: between the triangles of one face
};

/// A solid as a validator reads it: vertices and shells (the first the outer
/// one, the others cavities), each a list of faces, each face one ring of
/// vertex indices (no repeated closing vertex), counter-clockwise seen from
/// outside the solid.
struct PolygonSolid {
  std::vector<Vec3> vertices;
  std::vector<std::vector<std::vector<int>>> shells;
};

/// The first error found, with val3dity's code (0: valid). Codes used:
/// 101 too few points, 102 consecutive points the same (after snapping),
/// 104 ring self-intersection / collapsed, 203 non-planar (distance),
/// 204 non-planar (normals), 301 too few polygons, 302 not closed,
/// 303 non-manifold vertex, 304 non-manifold edge, 305 several connected
/// components, 306 self-intersection, 307 wrong orientation.
struct SolidCheck {
  int error = 0;
  int shell = -1, face = -1;  ///< where (face index within its shell)
  std::string detail;
  bool valid() const { return error == 0; }
};

SolidCheck check_solid(const PolygonSolid& solid, const Tolerances& tol = {});

/// The volume a closed shell encloses (faces as rings over `vertices`,
/// counter-clockwise seen from outside): positive for an outer shell, negative
/// for a cavity's (faces facing into it).
double signed_volume(const std::vector<Vec3>& vertices, const std::vector<std::vector<int>>& faces);

/// Faces (rings over `vertices`) as a solid: its shells are the edge-connected
/// pieces of the surface, the one enclosing the largest positive volume first
/// (the outer shell), then the others (cavities) in order of their first face.
/// `shell_of`, when given, receives the shell of each face.
PolygonSolid make_solid(std::vector<Vec3> vertices, const std::vector<std::vector<int>>& faces,
                        std::vector<int>* shell_of = nullptr);

/// The ring and planarity checks alone, of every face (after the shell's
/// snapping): per shell, per face, the error code (101, 102, 104, 203, 204)
/// or 0. A writer replaces the faces that fail by their triangles.
std::vector<std::vector<int>> face_errors(const PolygonSolid& solid, const Tolerances& tol = {});

/// The smallest distance between two distinct vertices used by the solid's
/// faces (infinity for fewer than two): > tol.snap means no snapping merges.
double min_vertex_distance(const PolygonSolid& solid);

}  // namespace citylod::lod
