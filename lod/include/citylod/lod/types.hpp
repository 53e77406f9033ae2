// Value types of citylod::lod's public interface. Plain data, no CGAL.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace citylod::lod {

using Vec3 = Eigen::Vector3d;
using Vec2 = Eigen::Vector2d;
/// 8-bit colour (sRGB as the input stores it).
using Rgb8 = std::array<std::uint8_t, 3>;
/// A face's colour: rgb + a (255 = coloured, 0 = no colour: the fixed material).
using Rgba8 = std::array<std::uint8_t, 4>;

/// One building as the LOD engine sees it, in a local metric frame (metres,
/// z up, coordinates small: the caller has moved the origin near the data).
/// Either a point cloud (points [+ normals]) or a triangle mesh (points are the
/// mesh vertices, triangles index them).
struct BuildingInput {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;                  ///< empty, or one per point
  std::vector<std::array<int, 3>> triangles;  ///< empty for point clouds
  std::vector<Rgb8> colors;                   ///< empty, or one per point (LAS RGB, PLY colours)
  std::vector<Vec2> footprint;                ///< optional outline (xy, CCW) of the building
  double ground_z = 0.0;  ///< ground height (used with footprint / LiDAR closure)
  bool has_ground_z = false;
  std::string name;  ///< for messages only

  bool is_mesh() const { return !triangles.empty(); }
};

/// Polygon mesh: vertices and faces (each a CCW loop seen from outside).
struct PolygonMesh {
  std::vector<Vec3> vertices;
  std::vector<std::vector<int>> faces;
};

/// Triangle mesh (indexed).
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
};

/// Progress and cancellation: called with a fraction in [0,1] and a stage
/// name; return false to cancel (the engine then throws LodCancelled, a
/// LodError naming the stage and "cancelled", from the stage it was in).
using ProgressFn = bool (*)(double fraction, const char* stage, void* user);

}  // namespace citylod::lod
