// Value types of citylod::io: point sets and meshes as read from / written to
// files. Plain data, double-precision coordinates (inputs are often in UTM or
// national grids with 1e5..1e7 m magnitudes: never store those in float).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace citylod::io {

using Vec3d = std::array<double, 3>;
using Vec3f = std::array<float, 3>;
using Rgb8 = std::array<std::uint8_t, 3>;
/// A face colour: rgb (sRGB, 8 bit) + a (255 = coloured, 0 = no colour).
using Rgba8 = std::array<std::uint8_t, 4>;

/// Axis-aligned box; empty() until the first add().
struct BBox3 {
  Vec3d min{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
  Vec3d max{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};

  bool empty() const { return min[0] > max[0]; }
  void add(const Vec3d& p) {
    for (int i = 0; i < 3; ++i) {
      if (p[i] < min[i]) min[i] = p[i];
      if (p[i] > max[i]) max[i] = p[i];
    }
  }
  void add(const BBox3& b) {
    if (!b.empty()) {
      add(b.min);
      add(b.max);
    }
  }
};

/// A batch of points. Every attribute vector is either empty (attribute absent)
/// or has exactly positions.size() entries.
struct PointSet {
  std::vector<Vec3d> positions;
  std::vector<Vec3f> normals;         ///< empty or one per point
  std::vector<Rgb8> colors;           ///< empty or one per point (8 bit per channel)
  std::vector<std::uint8_t> classes;  ///< empty or one per point (ASPRS class for LAS)

  std::size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_classes() const { return !classes.empty(); }
  void clear() {
    positions.clear();
    normals.clear();
    colors.clear();
    classes.clear();
  }
  /// Appends all points of `other`. Attributes present in only one of the two
  /// sets are dropped (a set keeps an attribute only if every point has it).
  void append(const PointSet& other);
  /// True when every attribute vector is empty or positions-sized.
  bool consistent() const;
};

/// Indexed triangle mesh. Polygons of the input are triangulated on read
/// (ear clipping: non-convex faces too).
struct TriangleMesh {
  std::vector<Vec3d> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<Vec3f> normals;  ///< empty or one per vertex
  std::vector<Rgb8> colors;    ///< empty or one per vertex
};

/// Mesh with faces of any number of vertices (footprints, LOD models before
/// triangulation).
struct PolygonMesh {
  std::vector<Vec3d> vertices;
  std::vector<std::vector<std::uint32_t>> faces;
};

/// Faces of any number of vertices in one flat layout: face i has the vertex indices
/// corners[offsets[i]] .. corners[offsets[i + 1] - 1]. A batch of a streamed mesh.
struct FaceBatch {
  std::vector<std::uint32_t> corners;
  std::vector<std::size_t> offsets{0};

  std::size_t size() const { return offsets.size() - 1; }
  const std::uint32_t* face(std::size_t i) const { return corners.data() + offsets[i]; }
  std::size_t face_size(std::size_t i) const { return offsets[i + 1] - offsets[i]; }
  void clear() {
    corners.clear();
    offsets.assign(1, 0);
  }
};

/// Fan-triangulates every face (exact for convex faces).
TriangleMesh triangulate_fan(const PolygonMesh& mesh);

/// Triangulates every face by ear clipping in its plane (Newell normal):
/// exact for any simple polygon, convex or not (merged coplanar faces of LOD
/// models, building outlines). A face with no ear left (self-touching,
/// degenerate) has its remainder fanned.
TriangleMesh triangulate_polygons(const PolygonMesh& mesh);

/// One face of triangulate_polygons(): its `n` vertex indices `face` and their positions
/// `corners` (corners[i] is vertex face[i]; read only when n > 3, may be null otherwise);
/// its triangles, as vertex indices, appended to `out` (none when n < 3).
void triangulate_face(const Vec3d* corners, const std::uint32_t* face, std::size_t n,
                      std::vector<std::array<std::uint32_t, 3>>& out);

}  // namespace citylod::io
