// Writers for points and meshes. All outputs are written atomically
// (temp file + rename, see atomic_file.hpp). Throw IoError.
#pragma once

#include <string>

#include "citylod/io/types.hpp"

namespace citylod::io {

struct PlyWriteOptions {
  bool binary = true;            ///< binary_little_endian; false = ascii
  bool double_precision = true;  ///< x y z as double (keeps georeferenced coordinates exact)
  std::string comment;           ///< optional "comment" header line
};

/// Points with their optional normals (nx ny nz float), colours (red green
/// blue uchar) and classes (classification uchar).
void write_ply(const std::string& path, const PointSet& points, const PlyWriteOptions& opt = {});
/// The bytes write_ply(path, points, opt) writes (`path` only names the points in
/// errors): a caller that also hashes or defers the file.
std::string ply_bytes(const std::string& path, const PointSet& points,
                      const PlyWriteOptions& opt = {});
/// Triangle mesh: vertex element (+ normals/colours if present) and face
/// element with "list uchar int vertex_indices".
void write_ply(const std::string& path, const TriangleMesh& mesh, const PlyWriteOptions& opt = {});
/// Polygon mesh, faces of any size.
void write_ply(const std::string& path, const PolygonMesh& mesh, const PlyWriteOptions& opt = {});

/// Wavefront OBJ ("v" and "f", 1-based indices; "vn" per vertex when the
/// mesh has normals). Coordinates are printed with 17 significant digits.
void write_obj(const std::string& path, const TriangleMesh& mesh);
void write_obj(const std::string& path, const PolygonMesh& mesh);

}  // namespace citylod::io
