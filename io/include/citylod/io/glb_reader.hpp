// Reading binary glTF (glb) back: the triangles of every mesh primitive with
// their node transforms, EXT_mesh_features feature ids and the
// EXT_structural_metadata property tables. Used by `citylod eval TILESET` to
// check what a tileset actually holds (the writer is io/gltf.hpp). tinygltf
// parses the glTF; the container, accessors and indices are checked first so
// that a corrupt file is an IoError naming it, never a crash.
//
//   const io::GlbDocument d = io::read_glb("tiles/r_0.glb");
//   for (const auto& p : d.primitives)       // node-local positions + node matrix
//     for (const auto& t : p.triangles) ...  // p.feature_ids[t[k]] ->
//     d.property_tables[p.property_table]
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "citylod/io/types.hpp"

namespace citylod::io {

/// One TRIANGLES primitive of one mesh instance (a node with a mesh).
struct GlbPrimitive {
  int node = 0;  ///< node index in the glb
  std::string node_name;
  int position_accessor = -1;  ///< POSITION accessor (primitives of a node often share it)
  /// Node to scene transform (glTF y-up frame), column-major 4x4, the product
  /// of the node's and its ancestors' matrix / TRS.
  std::array<double, 16> matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  /// POSITION values as stored (node-local; normalized integers mapped to [-1, 1]).
  std::vector<Vec3d> positions;
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices into positions
  /// Per vertex: feature id of the primitive's first EXT_mesh_features feature
  /// id set (attribute, or the vertex index for implicit ids); empty when the
  /// primitive has no EXT_mesh_features.
  std::vector<std::int64_t> feature_ids;
  int property_table = -1;  ///< property table of that feature id set, -1 if none
  int material = -1;
};

/// One EXT_structural_metadata property table: STRING and ENUM properties
/// (enum values as their names) in `strings`, SCALAR and BOOLEAN (0 / 1)
/// properties in `numbers`;
/// other property types are not read.
struct GlbPropertyTable {
  std::string name, class_name;
  std::size_t count = 0;
  std::map<std::string, std::vector<std::string>> strings;
  std::map<std::string, std::vector<double>> numbers;
};

struct GlbDocument {
  std::vector<GlbPrimitive> primitives;  ///< scene order (default scene, depth first)
  std::vector<GlbPropertyTable> property_tables;
  std::vector<std::string> extensions_used;
  std::string generator;
};

/// Reads a glb file. Throws IoError("<path>: <reason>") when it cannot be
/// read or is not a valid glb v2 (bad header or chunk lengths, JSON errors,
/// accessors outside their buffers, indices out of range, ...).
GlbDocument read_glb(const std::string& path);
/// The same from bytes in memory; `name` is used in error messages.
GlbDocument parse_glb(const std::string& bytes, const std::string& name);

/// Applies a column-major 4x4 transform to a point.
Vec3d transform_point(const std::array<double, 16>& m, const Vec3d& p);
/// a * b (column-major 4x4).
std::array<double, 16> multiply(const std::array<double, 16>& a, const std::array<double, 16>& b);

}  // namespace citylod::io
