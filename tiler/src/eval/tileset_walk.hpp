// The tileset.json reader of `citylod eval TILESET`: walks the tile tree and
// its external tilesets and lists every glb content with its level, geometric
// error and transform. Hostile input is bounded: tiles nested <= 256 levels,
// <= 5 M tiles in all, external tilesets <= 8 deep and each read once (a cycle
// or a repeat is an error), only local relative glb / json contents. Errors
// are io::IoError naming the file. Depends on citylod::io only (fuzzed by
// tests/fuzz/fuzz_tileset.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace citylod::tiler {

struct TilesetWalk {
  using Mat4 = std::array<double, 16>;  // column-major, as in 3D Tiles
  struct Content {
    std::string file;  ///< path to read
    std::string rel;   ///< relative to the top tileset's directory
    int level = 0;     ///< tile depth (an external tileset's root is one deeper)
    double error = 0;  ///< the tile's geometricError
    Mat4 transform{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  ///< content -> world
  };
  std::vector<Content> contents;  ///< in tree order (depth first)
  std::size_t tiles = 0;
  int depth = 0;
};

/// Reads `path` (a tileset.json) and the external tilesets it names.
TilesetWalk walk_tileset(const std::string& path);

}  // namespace citylod::tiler
