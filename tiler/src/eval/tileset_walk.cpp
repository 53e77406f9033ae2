// The tileset.json walker of `citylod eval TILESET` (see tileset_walk.hpp).
#include "eval/tileset_walk.hpp"

#include <algorithm>
#include <filesystem>
#include <set>

#include <nlohmann/json.hpp>

#include "citylod/io/error.hpp"
#include "citylod/io/glb_reader.hpp"
#include "citylod/io/json_file.hpp"
#include "citylod/io/reader.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using Mat4 = TilesetWalk::Mat4;

namespace {

constexpr Mat4 kIdentity{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
constexpr int kMaxExternalDepth = 8;
// Bounds of a hostile tileset (a real one is < 30 levels deep): recursion depth,
// and tiles in all (each external tileset is read once, so fan-out cannot multiply).
constexpr int kMaxTileDepth = 256;
constexpr std::size_t kMaxTiles = 5'000'000;

struct Walker {
  fs::path top_dir;
  std::vector<TilesetWalk::Content> contents;
  std::size_t tiles = 0;
  int depth = 0;
  std::set<std::string> external_seen;  // canonical paths of the tilesets read

  void tileset(const std::string& path, int level, const Mat4& parent, int external_depth) {
    std::error_code ec;
    const fs::path canon = fs::weakly_canonical(path, ec);
    if (!external_seen.insert(ec ? path : canon.string()).second)
      throw io::IoError(path,
                        "tileset referenced more than once (a cycle or a repeat; each "
                        "external tileset is read once)");
    const nlohmann::json ts = io::read_json_file(path);
    if (!ts.is_object() || !ts.contains("root") || !ts["root"].is_object())
      throw io::IoError(path, "not a 3D Tiles tileset (no \"root\" tile)");
    tile(ts["root"], path, fs::path(path).parent_path(), "root", level, parent, external_depth);
  }

  void tile(const nlohmann::json& t, const std::string& file, const fs::path& base,
            const std::string& where, int level, const Mat4& parent, int external_depth) {
    if (!t.is_object()) throw io::IoError(file, where + " is not a JSON object");
    if (level > kMaxTileDepth)
      throw io::IoError(
          file, "tiles nested deeper than " + std::to_string(kMaxTileDepth) + " levels (not read)");
    if (++tiles > kMaxTiles)
      throw io::IoError(file, "more than " + std::to_string(kMaxTiles) + " tiles (not read)");
    depth = std::max(depth, level);
    Mat4 m = parent;
    if (t.contains("transform")) {
      const auto& tr = t["transform"];
      if (!tr.is_array() || tr.size() != 16)
        throw io::IoError(file, where + ": \"transform\" is not 16 numbers");
      Mat4 local;
      for (std::size_t i = 0; i < 16; ++i) {
        if (!tr[i].is_number())
          throw io::IoError(file, where + ": \"transform\" is not 16 numbers");
        local[i] = tr[i].get<double>();
      }
      m = io::multiply(parent, local);
    }
    const double error = t.contains("geometricError") && t["geometricError"].is_number()
                             ? t["geometricError"].get<double>()
                             : 0.0;
    std::vector<const nlohmann::json*> cs;
    if (t.contains("content")) cs.push_back(&t["content"]);
    if (t.contains("contents")) {
      if (!t["contents"].is_array())
        throw io::IoError(file, where + ": \"contents\" is not an array");
      for (const auto& c : t["contents"]) cs.push_back(&c);
    }
    for (const auto* c : cs) {
      if (!c->is_object()) throw io::IoError(file, where + ": content is not a JSON object");
      const char* key = c->contains("uri") ? "uri" : "url";  // 1.1 / 1.0
      if (!c->contains(key) || !(*c)[key].is_string())
        throw io::IoError(file, where + ": content has no uri");
      std::string uri = (*c)[key].get<std::string>();
      if (uri.find("://") != std::string::npos || uri.rfind("data:", 0) == 0)
        throw io::IoError(file,
                          where + ": content '" + uri + "' is not a local file (not supported)");
      uri = uri.substr(0, uri.find('?'));
      const fs::path p = (base / uri).lexically_normal();
      const std::string ext = "." + io::extension_of(p.string());
      if (ext == ".json") {
        if (external_depth >= kMaxExternalDepth)
          throw io::IoError(p.string(), "external tilesets nested deeper than " +
                                            std::to_string(kMaxExternalDepth));
        tileset(p.string(), level + 1, m, external_depth + 1);
      } else if (ext == ".glb") {
        TilesetWalk::Content r;
        r.file = p.string();
        r.rel = p.lexically_relative(top_dir).generic_string();
        if (r.rel.empty()) r.rel = r.file;
        r.level = level;
        r.error = error;
        r.transform = m;
        contents.push_back(r);
      } else {
        throw io::IoError(
            p.string(), "unsupported tile content '" + ext + "' (only glb and external tilesets)");
      }
    }
    if (t.contains("children")) {
      const auto& ch = t["children"];
      if (!ch.is_array()) throw io::IoError(file, where + ": \"children\" is not an array");
      for (std::size_t i = 0; i < ch.size(); ++i)
        tile(ch[i], file, base,
             (where.size() < 200 ? where : "...") + ".children[" + std::to_string(i) + "]",
             level + 1, m, external_depth);
    }
  }
};

}  // namespace

TilesetWalk walk_tileset(const std::string& path) {
  Walker w;
  w.top_dir = fs::path(path).parent_path().lexically_normal();
  w.tileset(path, 0, kIdentity, 0);
  TilesetWalk r;
  r.contents = std::move(w.contents);
  r.tiles = w.tiles;
  r.depth = w.depth;
  return r;
}

}  // namespace citylod::tiler
