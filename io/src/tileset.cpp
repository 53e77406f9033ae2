// tileset.json writer (3D Tiles 1.1).
#include "citylod/io/tileset.hpp"

#include <cmath>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"

namespace citylod::io {

namespace {

constexpr double kGrid = 1e-6;
constexpr const char* kWhere = "tileset.json";

nlohmann::ordered_json box_json(const TileBox& b) {
  nlohmann::ordered_json a = nlohmann::ordered_json::array();
  for (double x : b.v) a.push_back(x);
  return {{"box", a}};
}

void check_number(double x, const char* what) {
  if (!std::isfinite(x)) throw IoError(kWhere, std::string(what) + " is not finite");
}

nlohmann::ordered_json tile_json(const Tile& t, bool is_root) {
  if (is_root && t.refine.empty())
    throw IoError(kWhere, "the root tile needs refine (REPLACE or ADD)");
  if (!t.refine.empty() && t.refine != "REPLACE" && t.refine != "ADD")
    throw IoError(kWhere, "refine must be REPLACE or ADD, not '" + t.refine + "'");
  check_number(t.geometric_error, "geometricError");
  if (t.geometric_error < 0) throw IoError(kWhere, "negative geometricError");
  for (double x : t.box.v) check_number(x, "boundingVolume");
  nlohmann::ordered_json j;
  j["boundingVolume"] = box_json(t.box);
  j["geometricError"] = t.geometric_error;
  if (!t.refine.empty()) j["refine"] = t.refine;
  if (t.transform) {
    nlohmann::ordered_json m = nlohmann::ordered_json::array();
    for (double x : *t.transform) {
      check_number(x, "transform");
      m.push_back(x);
    }
    j["transform"] = m;
  }
  if (!t.content_uri.empty()) {
    nlohmann::ordered_json c;
    if (t.content_box) c["boundingVolume"] = box_json(*t.content_box);
    c["uri"] = t.content_uri;
    j["content"] = c;
  }
  if (!t.children.empty()) {
    nlohmann::ordered_json ch = nlohmann::ordered_json::array();
    for (const auto& c : t.children) ch.push_back(tile_json(c, false));
    j["children"] = ch;
  }
  return j;
}

}  // namespace

TileBox TileBox::from_bbox(const BBox3& b) {
  if (b.empty()) throw IoError(kWhere, "bounding box of an empty tile");
  TileBox t;
  for (int k = 0; k < 3; ++k) {
    const double lo = b.min[size_t(k)], hi = b.max[size_t(k)];
    const double c = std::round((lo + hi) / 2 / kGrid) * kGrid;
    // Half size rounded up on the grid, large enough for both ends seen from
    // the rounded centre, plus one grid step against rounding of c +- h.
    const double h = std::ceil(std::max(hi - c, c - lo) / kGrid) * kGrid + kGrid;
    t.v[size_t(k)] = c;
    t.v[size_t(3 + 4 * k)] = h;  // diagonal entries of the half-axis matrix
  }
  return t;
}

BBox3 TileBox::to_bbox() const {
  BBox3 b;
  Vec3d ext{0, 0, 0};
  for (int axis = 0; axis < 3; ++axis)
    for (int k = 0; k < 3; ++k) ext[size_t(k)] += std::fabs(v[size_t(3 + 3 * axis + k)]);
  b.add(Vec3d{v[0] - ext[0], v[1] - ext[1], v[2] - ext[2]});
  b.add(Vec3d{v[0] + ext[0], v[1] + ext[1], v[2] + ext[2]});
  return b;
}

std::string tileset_json(const Tileset& ts) {
  check_number(ts.geometric_error, "tileset geometricError");
  if (ts.geometric_error < 0) throw IoError(kWhere, "negative geometricError");
  nlohmann::ordered_json j;
  nlohmann::ordered_json asset{{"version", "1.1"}};
  if (!ts.tileset_version.empty()) asset["tilesetVersion"] = ts.tileset_version;
  if (!ts.generator.empty()) asset["generator"] = ts.generator;
  j["asset"] = asset;
  j["geometricError"] = ts.geometric_error;
  j["root"] = tile_json(ts.root, true);
  if (ts.extras.is_object() && !ts.extras.empty()) j["extras"] = ts.extras;
  return j.dump() + "\n";  // compact: a client downloads it before any geometry
}

void write_tileset(const std::string& path, const Tileset& ts) {
  atomic_write_file(path, tileset_json(ts));
}

std::size_t tile_count(const Tile& t) {
  std::size_t n = 1;
  for (const auto& c : t.children) n += tile_count(c);
  return n;
}

int tile_depth(const Tile& t) {
  int d = 0;
  for (const auto& c : t.children) d = std::max(d, 1 + tile_depth(c));
  return d;
}

}  // namespace citylod::io
