// 3D Tiles 1.1 tileset.json: a plain tile tree and its deterministic writer.
//
// Every number is written in the shortest form that reads back to the same
// double; bounding boxes are rounded outward to 1e-6 m by TileBox::from_bbox so
// that the file is stable and still contains what the box was built from.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "citylod/io/types.hpp"

namespace citylod::io {

/// 3D Tiles "box": centre, then the x, y and z half-axis vectors (12 numbers),
/// in the frame of the tile (after its transform and those of its ancestors).
struct TileBox {
  std::array<double, 12> v{};
  /// Axis-aligned box containing `b` (which must not be empty), rounded outward to 1e-6.
  static TileBox from_bbox(const BBox3& b);
  /// The axis-aligned box this box spans (exact for axis-aligned boxes).
  BBox3 to_bbox() const;
};

struct Tile {
  TileBox box;                 ///< boundingVolume: contains content and children
  double geometric_error = 0;  ///< metres
  std::optional<std::array<double, 16>> transform;  ///< column-major, relative to the parent
  std::string refine;                  ///< "REPLACE" / "ADD"; "" inherits (root must set it)
  std::string content_uri;             ///< relative to tileset.json; "" = no content
  std::optional<TileBox> content_box;  ///< content.boundingVolume (tighter than box)
  std::vector<Tile> children;
};

struct Tileset {
  double geometric_error = 0;  ///< error when the tileset is not rendered at all
  std::string generator = "citylod";
  std::string tileset_version;    ///< asset.tilesetVersion, optional
  nlohmann::ordered_json extras;  ///< top-level "extras" (object or null)
  Tile root;
};

/// The tileset.json text (asset.version "1.1", two-space indent, trailing newline).
/// Throws IoError("tileset.json: ...") when the root has no refine or an error
/// is negative / not finite.
std::string tileset_json(const Tileset& ts);

/// Writes tileset_json(ts) to `path` atomically.
void write_tileset(const std::string& path, const Tileset& ts);

/// Counts tiles (root included) and the deepest depth (root = 0).
std::size_t tile_count(const Tile& t);
int tile_depth(const Tile& t);

}  // namespace citylod::io
