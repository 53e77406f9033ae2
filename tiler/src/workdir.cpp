// Every JSON record of the work directory, read and written in one place
// (see workdir.hpp for the files and the defaults of absent fields).
#include "citylod/tiler/workdir.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/json_file.hpp"
#include "citylod/io/reader.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using nlohmann::json;

void StatusCounts::add(Status s) {
  switch (s) {
    case Status::ok:
      ++ok;
      break;
    case Status::fallback:
      ++fallback;
      break;
    case Status::skipped:
      ++skipped;
      break;
    case Status::pending:
    case Status::failed:
      ++failed;
      break;
  }
}

// ------------------------------------------------------------ ids and paths
namespace {
bool safe_name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
         c == '_' || c == '.';
}

/// `name` quoted for a message: printable ASCII kept, the rest as \xNN, cut at 60 characters.
std::string shown_name(const std::string& name) {
  std::string q = "'";
  for (std::size_t i = 0; i < name.size() && i < 60; ++i) {
    const auto c = static_cast<unsigned char>(name[i]);
    if (c >= 0x20 && c < 0x7f) {
      q += char(c);
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      q += b;
    }
  }
  return q + (name.size() > 60 ? "...'" : "'");
}

const std::string& checked_id(const std::string& id) {
  if (!is_safe_id(id))
    throw std::invalid_argument("building id " + shown_name(id) + " is not a safe file name");
  return id;
}
}  // namespace

bool is_safe_id(const std::string& id) {
  if (id.empty() || id.size() > kMaxIdLength || id[0] == '.') return false;
  if (id.find("..") != std::string::npos) return false;
  return std::all_of(id.begin(), id.end(), safe_name_char);
}

void require_safe_id(const std::string& id, const std::string& file) {
  if (!is_safe_id(id))
    throw io::IoError(file, "building id " + shown_name(id) + " is not a safe name (1-" +
                                std::to_string(kMaxIdLength) +
                                " characters of A-Z a-z 0-9 . _ -, no leading '.', no '..')");
}

// ------------------------------------------------------------ paths
namespace {
// The names of a `citylod tile -o DIR` output, as run_report.json records them too.
constexpr const char* kWorkName = "work";
constexpr const char* kTilesetName = "tileset";
}  // namespace

std::string run_work_dir(const std::string& d) {
  return (fs::path(d) / kWorkName).string();
}
std::string run_tileset_dir(const std::string& d) {
  return (fs::path(d) / kTilesetName).string();
}
std::string run_cityjson_path(const std::string& d) {
  return (fs::path(d) / "buildings.city.jsonl").string();
}
std::string tileset_json_path(const std::string& t) {
  return (fs::path(t) / "tileset.json").string();
}
std::string buildings_json_path(const std::string& t) {
  return (fs::path(t) / "buildings.json").string();
}
std::string run_report_path(const std::string& d) {
  return (fs::path(d) / "run_report.json").string();
}
std::string manifest_path(const std::string& w) {
  return (fs::path(w) / "manifest.json").string();
}
std::string chunks_dir(const std::string& w) {
  return (fs::path(w) / "chunks").string();
}
std::string lod_root(const std::string& w) {
  return (fs::path(w) / "lod").string();
}
std::string chunk_path(const std::string& w, const std::string& id) {
  return (fs::path(chunks_dir(w)) / (checked_id(id) + ".ply")).string();
}
std::string lod_dir(const std::string& w, const std::string& id) {
  return (fs::path(lod_root(w)) / checked_id(id)).string();
}
std::string report_file(const std::string& dir) {
  return (fs::path(dir) / "report.json").string();
}
std::string params_file(const std::string& dir) {
  return (fs::path(dir) / "params.json").string();
}
std::string lod_report_path(const std::string& w, const std::string& id) {
  return report_file(lod_dir(w, id));
}
std::string overrides_path(const std::string& w) {
  return (fs::path(w) / "overrides.json").string();
}

namespace {
const char* marker_suffix(LodMarker m) {
  switch (m) {
    case LodMarker::running:
      return ".running";
    case LodMarker::suspect:
      return ".suspect";
    case LodMarker::crashed:
      return ".crashed";
  }
  return ".running";
}
}  // namespace

std::string dir_lock_path(const std::string& d) {
  return (fs::path(d) / ".citylod.lock").string();
}
std::string shard_lock_path(const std::string& d, int index, int count) {
  return (fs::path(d) /
          (".citylod.shard-" + std::to_string(index) + "-of-" + std::to_string(count) + ".lock"))
      .string();
}
std::string output_lock_path(const std::string& out) {
  fs::path p = fs::absolute(out).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return (p.parent_path() / ("." + p.filename().string() + ".citylod.lock")).string();
}

namespace {
constexpr const char* kSplitStaging = ".split.tmp.";
}  // namespace

std::string split_staging_dir(const std::string& w, long pid) {
  return (fs::path(w) / (kSplitStaging + std::to_string(pid))).string();
}
long split_staging_pid(const std::string& name) {
  const std::string prefix = kSplitStaging;
  if (name.rfind(prefix, 0) != 0) return -1;
  return std::max(0L, std::strtol(name.c_str() + prefix.size(), nullptr, 10));
}
std::string split_spill_dir(const std::string& s) {
  return (fs::path(s) / "spill").string();
}
std::string split_faces_dir(const std::string& s) {
  return (fs::path(s) / "faces").string();
}
std::string split_old_chunks_dir(const std::string& s) {
  return (fs::path(s) / "chunks.old").string();
}

std::string lod_marker_path(const std::string& w, const std::string& id, LodMarker m) {
  return lod_dir(w, id) + marker_suffix(m);
}
std::string marker_id(const std::string& name, LodMarker m) {
  const std::string suffix = marker_suffix(m);
  if (name.size() <= suffix.size() ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
    return "";
  return name.substr(0, name.size() - suffix.size());
}

namespace {

using io::read_json_file;

/// A double that may have been written as null (NaN, inf).
double number(const json& j, const char* key, double def) {
  auto it = j.find(key);
  if (it == j.end()) return def;
  if (it->is_null()) return std::numeric_limits<double>::quiet_NaN();
  return it->get<double>();
}

std::map<std::string, std::string> string_map(const json& j) {
  std::map<std::string, std::string> m;
  if (!j.is_object()) return m;
  for (const auto& [k, v] : j.items()) m[k] = v.is_string() ? v.get<std::string>() : v.dump();
  return m;
}

// ------------------------------------------------------------ manifest
json to_json(const ChunkRecord& c) {
  json o;
  o["id"] = c.id;
  o["origin"] = c.origin;
  o["bbox_min"] = c.bbox_min;
  o["bbox_max"] = c.bbox_max;
  o["points"] = c.points;
  o["triangles"] = c.triangles;
  o["outline"] = c.outline;
  o["ground_z"] = c.ground_z;
  o["source"] = c.source;
  o["status"] = to_string(c.status);
  if (!c.reason.empty()) o["reason"] = c.reason;
  o["content_hash"] = c.content_hash;
  if (!c.attributes.empty()) o["attributes"] = c.attributes;
  return o;
}

ChunkRecord chunk_from_json(const json& o) {
  ChunkRecord c;
  c.id = o.at("id").get<std::string>();
  c.origin = o.at("origin").get<std::array<double, 3>>();
  c.bbox_min = o.at("bbox_min").get<std::array<double, 3>>();
  c.bbox_max = o.at("bbox_max").get<std::array<double, 3>>();
  c.points = o.value("points", std::uint64_t(0));
  c.triangles = o.value("triangles", std::uint64_t(0));
  if (o.contains("outline")) c.outline = o.at("outline").get<std::vector<std::array<double, 2>>>();
  c.ground_z = o.value("ground_z", 0.0);
  c.source = o.value("source", "");
  c.status = status_from_string(o.value("status", "pending"));
  c.reason = o.value("reason", "");
  c.content_hash = o.value("content_hash", "");
  if (o.contains("attributes") && o.at("attributes").is_object()) c.attributes = o.at("attributes");
  return c;
}

// ------------------------------------------------------------ report.json
/// Face colours as runs of equal values: [n, r, g, b], or [n] without colour.
json colour_runs(const std::vector<FaceColour>& c) {
  json runs = json::array();
  for (size_t i = 0; i < c.size();) {
    size_t j = i + 1;
    while (j < c.size() && (c[j] == c[i] || (c[j][3] == 0 && c[i][3] == 0))) ++j;
    if (c[i][3] == 0)
      runs.push_back({j - i});
    else
      runs.push_back({j - i, c[i][0], c[i][1], c[i][2]});
    i = j;
  }
  return runs;
}

std::vector<FaceColour> colours_from_runs(const json& runs, std::uint64_t expected,
                                          const std::string& path, const std::string& what) {
  auto bad = [&](const std::string& why) { return io::IoError(path, what + " colours: " + why); };
  if (!runs.is_array()) throw bad("not an array of runs");
  std::vector<FaceColour> out;
  for (const auto& r : runs) {
    if (!r.is_array() || (r.size() != 1 && r.size() != 4))
      throw bad("a run is not [n] or [n, r, g, b]");
    for (const auto& v : r)
      if (!v.is_number_unsigned()) throw bad("a run holds something other than a count or 0-255");
    const std::uint64_t n = r[0].get<std::uint64_t>();
    if (n == 0 || n > expected - out.size()) throw bad("the runs do not add up to the faces");
    FaceColour c{0, 0, 0, 0};
    if (r.size() == 4) {
      for (size_t k = 1; k < 4; ++k) {
        if (r[k].get<std::uint64_t>() > 255) throw bad("a colour value exceeds 255");
        c[k - 1] = std::uint8_t(r[k].get<std::uint64_t>());
      }
      c[3] = 255;
    }
    out.insert(out.end(), size_t(n), c);
  }
  if (out.size() != expected) throw bad("the runs do not add up to the faces");
  return out;
}

json to_json(const ModelRecord& m) {
  json j = {{"file", m.file},
            {"kind", lod::to_string(m.kind)},
            {"level", m.level},
            {"step", m.step},
            {"cuts", m.cuts},
            {"diff_sum", m.diff_sum},
            {"polygons", m.polygons},
            {"triangles", m.triangles},
            {"volume", m.volume},
            {"e1", m.e1},
            {"e2", m.e2},
            {"hausdorff_m", m.hausdorff_m}};
  if (m.roof_rmse_m >= 0) j["roof_rmse_m"] = m.roof_rmse_m;
  if (!m.polygon_colours.empty() || !m.triangle_colours.empty())
    j["colours"] = {{"polygons", colour_runs(m.polygon_colours)},
                    {"triangles", colour_runs(m.triangle_colours)}};
  return j;
}

std::vector<ModelRecord> models_from_json(const json& arr, const std::string& path) {
  if (!arr.is_array()) throw io::IoError(path, "\"models\" is not an array");
  std::vector<ModelRecord> out;
  int index = 0;
  for (const auto& m : arr) {
    if (!m.is_object() || !m.contains("file") || !m["file"].is_string())
      throw io::IoError(path, "model " + std::to_string(index) + " has no \"file\"");
    ModelRecord r;
    r.file = m["file"].get<std::string>();
    // a plain file name in the report's folder: nothing outside it is read
    if (r.file.empty() || r.file[0] == '.' || r.file.size() > 255 ||
        r.file.find_first_of("/\\") != std::string::npos || r.file.find('\0') != std::string::npos)
      throw io::IoError(path, "model " + std::to_string(index) + ": file " + shown_name(r.file) +
                                  " is not a plain file name in the report's folder");
    try {
      r.kind = model_kind_from_string(m.value("kind", std::string("anchor")));
    } catch (const std::invalid_argument& e) {
      throw io::IoError(path, "model " + std::to_string(index) + ": " + e.what());
    }
    r.level = m.contains("level") && m["level"].is_number_integer() ? m["level"].get<int>() : 0;
    r.step = m.contains("step") && m["step"].is_number_integer() ? m["step"].get<int>() : index;
    r.cuts = m.value("cuts", 0);
    r.diff_sum = number(m, "diff_sum", 0);
    r.polygons = m.value("polygons", std::uint64_t(0));
    r.triangles = m.value("triangles", std::uint64_t(0));
    r.volume = number(m, "volume", 0);
    r.e1 = number(m, "e1", -1);
    r.e2 = number(m, "e2", -1);
    r.hausdorff_m = number(m, "hausdorff_m", -1);
    r.roof_rmse_m = number(m, "roof_rmse_m", -1);
    if (m.contains("colours")) {
      const json& c = m["colours"];
      const std::string what = "model " + std::to_string(index);
      if (!c.is_object() || !c.contains("polygons") || !c.contains("triangles"))
        throw io::IoError(path, what + ": \"colours\" is not {\"polygons\", \"triangles\"}");
      r.polygon_colours = colours_from_runs(c["polygons"], r.polygons, path, what + " polygon");
      r.triangle_colours = colours_from_runs(c["triangles"], r.triangles, path, what + " triangle");
    }
    out.push_back(r);
    ++index;
  }
  return out;
}

json to_json(const LodReport& r) {
  json j;
  j["input"] = r.input;
  j["status"] = to_string(r.status);
  if (!r.reason.empty()) j["reason"] = r.reason;
  if (!r.id.empty()) j["id"] = r.id;
  if (!r.key.empty()) j["key"] = r.key;
  j["parameters"] = json::object();
  for (const auto& [k, v] : r.parameters) j["parameters"][k] = v;
  j["parameters"][kThreadsKey] = std::to_string(r.threads);
  j["counts"] = json::object();
  for (const auto& [k, v] : r.counts) j["counts"][k] = v;
  j["lod_tree_vs_bsp_tree"] = json::object();
  for (const auto& [k, v] : r.lod_tree_vs_bsp_tree) j["lod_tree_vs_bsp_tree"][k] = v;
  j["bbox_diagonal_m"] = r.bbox_diagonal_m;
  j["normals_estimated"] = r.normals_estimated;
  j["walls_inferred"] = r.walls_inferred;
  j["timings_s"] = json::object();
  for (const auto& [k, v] : r.timings_s) j["timings_s"][k] = v;
  j["notes"] = r.notes;
  json models = json::array();
  for (const auto& m : r.models) models.push_back(to_json(m));
  j["models"] = models;
  if (r.models_all) {
    json all = json::array();
    for (const auto& m : *r.models_all) all.push_back(to_json(m));
    j["models_all"] = all;
    j["selected_steps"] = r.selected_steps;
  }
  return j;
}

LodReport lod_report_from_json(const json& j, const std::string& path) {
  if (!j.is_object()) throw io::IoError(path, "not a JSON object");
  LodReport r;
  try {
    r.input = j.value("input", std::string());
    // A report that does not say how it went is not trusted (workdir.hpp).
    const auto st = j.find("status");
    r.status = st != j.end() && st->is_string() ? status_from_string(st->get<std::string>())
                                                : Status::failed;
    if (st == j.end()) r.reason = "report.json records no status";
    if (j.contains("reason") && j["reason"].is_string()) r.reason = j["reason"].get<std::string>();
    r.id = j.value("id", std::string());
    if (!r.id.empty()) require_safe_id(r.id, path);
    r.key = j.value("key", std::string());
    if (j.contains("parameters")) r.parameters = string_map(j["parameters"]);
    if (const auto t = r.parameters.find(kThreadsKey); t != r.parameters.end()) {
      r.threads = std::atoi(t->second.c_str());
      r.parameters.erase(t);
    }
    if (j.contains("counts"))
      for (const auto& [k, v] : j["counts"].items()) r.counts[k] = v.get<std::int64_t>();
    if (j.contains("lod_tree_vs_bsp_tree"))
      for (const auto& [k, v] : j["lod_tree_vs_bsp_tree"].items())
        r.lod_tree_vs_bsp_tree[k] = v.get<std::int64_t>();
    r.bbox_diagonal_m = number(j, "bbox_diagonal_m", 0);
    r.normals_estimated = j.value("normals_estimated", false);
    r.walls_inferred = j.value("walls_inferred", false);
    if (j.contains("timings_s"))
      for (const auto& [k, v] : j["timings_s"].items())
        r.timings_s[k] = v.is_null() ? std::numeric_limits<double>::quiet_NaN() : v.get<double>();
    r.notes = j.value("notes", std::vector<std::string>{});
    if (j.contains("models")) r.models = models_from_json(j["models"], path);
    if (j.contains("models_all")) r.models_all = models_from_json(j["models_all"], path);
    r.selected_steps = j.value("selected_steps", std::vector<int>{});
  } catch (const io::IoError&) {
    throw;
  } catch (const std::exception& e) {
    throw io::IoError(path, std::string("malformed report: ") + e.what());
  }
  return r;
}

// ------------------------------------------------------------ run_report.json
json to_json(const BuildingRecord& b) {
  json o;
  o["id"] = b.id;
  o["source"] = b.source;
  o["status"] = to_string(b.status);
  if (!b.reason.empty()) o["reason"] = b.reason;
  o["models"] = b.models;
  if (!b.set.empty()) o["set"] = b.set;
  if (!b.select.empty()) o["select"] = b.select;
  return o;
}

BuildingRecord building_from_json(const json& o) {
  BuildingRecord b;
  b.id = o.at("id").get<std::string>();
  if (!is_safe_id(b.id)) checked_id(b.id);
  b.source = o.value("source", std::string());
  b.status = status_from_string(o.value("status", std::string("failed")));
  b.reason = o.value("reason", std::string());
  b.models = o.value("models", std::size_t(0));
  if (o.contains("set")) b.set = string_map(o["set"]);
  b.select = o.value("select", std::vector<int>{});
  return b;
}

json to_json(const AssembleParams& p) {
  return {{"max_tile_triangles", p.max_tile_triangles},
          {"max_tile_bytes", p.max_tile_bytes},
          {"tile_extent_factor", p.tile_extent_factor},
          {"min_tile_extent_m", p.min_tile_extent_m},
          {"max_tiles_per_file", p.max_tiles_per_file},
          {"min_leaf_bytes", p.min_leaf_bytes},
          {"min_change_m", p.min_change_m},
          {"hausdorff_tolerance_m", p.hausdorff_tolerance_m},
          {"quantize", p.quantize},
          {"compression", io::to_string(p.compression)},
          {"building_models", p.building_models},
          {"skip_missing", p.skip_missing}};
}

AssembleParams assemble_params_from_json(const json& j) {
  AssembleParams p;
  p.max_tile_triangles = j.value("max_tile_triangles", p.max_tile_triangles);
  p.max_tile_bytes = j.value("max_tile_bytes", p.max_tile_bytes);
  p.tile_extent_factor = j.value("tile_extent_factor", p.tile_extent_factor);
  p.min_tile_extent_m = j.value("min_tile_extent_m", p.min_tile_extent_m);
  p.max_tiles_per_file = j.value("max_tiles_per_file", p.max_tiles_per_file);
  p.min_leaf_bytes = j.value("min_leaf_bytes", p.min_leaf_bytes);
  p.min_change_m = j.value("min_change_m", p.min_change_m);
  p.hausdorff_tolerance_m = j.value("hausdorff_tolerance_m", p.hausdorff_tolerance_m);
  p.quantize = j.value("quantize", p.quantize);
  // a run report without it predates compression: its tiles are plain
  p.compression = io::compression_from_string(j.value("compression", std::string("none")));
  p.building_models = j.value("building_models", p.building_models);
  p.skip_missing = j.value("skip_missing", p.skip_missing);
  p.validate();
  return p;
}

}  // namespace

// ------------------------------------------------------------ manifest
Manifest read_manifest(const std::string& work_dir) {
  const std::string path = manifest_path(work_dir);
  if (!fs::exists(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  if (!fs::exists(path)) throw io::IoError(path, "missing manifest (run 'citylod split' first)");
  // Its folders must be inside it: a symbolic link would lead deletions elsewhere.
  for (const std::string& sub : {chunks_dir(work_dir), lod_root(work_dir)}) {
    std::error_code ec;
    const fs::path p = sub;
    const auto st = fs::symlink_status(p, ec);
    if (!ec && fs::exists(st) && !fs::is_directory(st))
      throw io::IoError(p.string(), fs::is_symlink(st)
                                        ? "is a symbolic link (a work directory's folders must "
                                          "be inside it)"
                                        : "is not a directory");
  }
  const json j = read_json_file(path);
  Manifest m;
  try {
    m.version = j.at("version").get<int>();
    if (m.version != 1)
      throw io::IoError(path, "unsupported manifest version " + std::to_string(m.version));
    const json& s = j.at("scene");
    m.scene.crs = s.value("crs", "");
    m.scene.origin_crs = s.at("origin_crs").get<std::array<double, 3>>();
    const std::string frame = s.value("frame", "enu");
    if (frame != "enu" && frame != "projected")
      throw io::IoError(path, "unknown scene frame \"" + frame + "\" (enu or projected)");
    m.scene.projected_frame = frame == "projected";
    if (m.scene.projected_frame && m.scene.crs.empty())
      throw io::IoError(path, "a projected scene frame needs a CRS");
    m.scene.origin_lon = s.at("origin_lon").get<double>();
    m.scene.origin_lat = s.at("origin_lat").get<double>();
    m.scene.origin_h = s.at("origin_h").get<double>();
    m.scene.inputs = s.value("inputs", std::vector<std::string>{});
    m.scene.options = s.value("options", "");
    m.scene.notes = s.value("notes", std::vector<std::string>{});
    m.scene.vertical = s.value("vertical", "");
    m.scene.building_points = s.value("building_points", std::int64_t(-1));
    m.scene.unmatched_points = s.value("unmatched_points", std::int64_t(-1));
    for (const auto& c : j.at("chunks")) {
      m.chunks.push_back(chunk_from_json(c));
      require_safe_id(m.chunks.back().id, path);
    }
  } catch (const io::IoError&) {
    throw;
  } catch (const std::exception& e) {
    throw io::IoError(path, std::string("malformed manifest: ") + e.what());
  }
  return m;
}

void require_valid_origin(const Manifest& m, const std::string& work_dir) {
  const auto& sc = m.scene;
  if (!std::isfinite(sc.origin_lat) || !std::isfinite(sc.origin_lon) ||
      std::fabs(sc.origin_lat) > 90 || std::fabs(sc.origin_lon) > 180 ||
      !std::isfinite(sc.origin_h))
    throw io::IoError(manifest_path(work_dir),
                      "scene origin is not a valid longitude/latitude/height");
}

void write_manifest(const std::string& work_dir, const Manifest& m) {
  json j;
  j["version"] = m.version;
  j["scene"] = {{"crs", m.scene.crs},
                {"origin_crs", m.scene.origin_crs},
                {"frame", m.scene.projected_frame ? "projected" : "enu"},
                {"origin_lon", m.scene.origin_lon},
                {"origin_lat", m.scene.origin_lat},
                {"origin_h", m.scene.origin_h},
                {"inputs", m.scene.inputs},
                {"options", m.scene.options},
                {"notes", m.scene.notes}};
  if (!m.scene.vertical.empty()) j["scene"]["vertical"] = m.scene.vertical;
  if (m.scene.building_points >= 0) {
    j["scene"]["building_points"] = m.scene.building_points;
    j["scene"]["unmatched_points"] = m.scene.unmatched_points;
  }
  std::vector<ChunkRecord> sorted = m.chunks;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  json chunks = json::array();
  for (const auto& c : sorted) chunks.push_back(to_json(c));
  j["chunks"] = chunks;
  fs::create_directories(work_dir);
  io::atomic_write_file(manifest_path(work_dir), j.dump(1) + "\n");
}

bool chunk_intact(const std::string& work_dir, const ChunkRecord& c) {
  const std::string path = chunk_path(work_dir, c.id);
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  if (c.content_hash.empty()) return true;
  try {
    return io::hash_file(path) == c.content_hash;
  } catch (const io::IoError&) {
    return false;
  }
}

void require_own_chunks(const std::string& work_dir) {
  const fs::path chunks = chunks_dir(work_dir);
  std::error_code ec;
  if (!fs::exists(chunks, ec) || fs::exists(manifest_path(work_dir), ec)) return;
  if (fs::is_directory(chunks, ec) && fs::is_empty(chunks, ec)) return;
  throw io::IoError(chunks.string(),
                    "exists and is not empty, but " + work_dir +
                        " has no manifest.json: not made by 'citylod split'; not replaced "
                        "(move it away or choose another work directory)");
}

// ------------------------------------------------------------ report.json
LodReport read_lod_report(const std::string& path) {
  return lod_report_from_json(read_json_file(path), path);
}

std::vector<const ChunkRecord*> buildings_to_model(const Manifest& m, const std::string& work_dir,
                                                   std::size_t* skipped) {
  std::vector<const ChunkRecord*> recs;
  std::size_t n_skipped = 0;
  for (const auto& c : m.chunks) {
    if (c.skipped())
      ++n_skipped;
    else
      recs.push_back(&c);
  }
  std::sort(recs.begin(), recs.end(), [](const auto* a, const auto* b) { return a->id < b->id; });
  for (std::size_t i = 1; i < recs.size(); ++i)
    if (recs[i]->id == recs[i - 1]->id)
      throw io::IoError(manifest_path(work_dir), "building id '" + recs[i]->id + "' appears twice");
  if (skipped) *skipped = n_skipped;
  return recs;
}

std::optional<LodReport> find_lod_report(const std::string& work_dir, const std::string& id) {
  const std::string path = lod_report_path(work_dir, id);
  if (!fs::exists(path)) return std::nullopt;
  return read_lod_report(path);
}

void write_params_record(const std::string& dir,
                         const std::map<std::string, std::string>& parameters, int threads) {
  json j = json::object();
  for (const auto& [k, v] : parameters) j[k] = v;
  j[kThreadsKey] = std::to_string(threads);
  io::atomic_write_file(params_file(dir), j.dump(2) + "\n");
}

bool write_lod_report(const std::string& path, const LodReport& r) {
  const std::string text = to_json(r).dump(2) + "\n";
  if (fs::exists(path)) {
    std::ifstream f(path, std::ios::binary);
    const std::string old((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    if (old == text) return false;
  }
  io::atomic_write_file(path, text);
  return true;
}

io::TriangleMesh read_model_file(const std::string& file) {
  return fs::path(file).extension() == ".ply" ? io::read_mesh(file, io::Format::ply)
                                              : io::read_mesh(file);
}

BuildingModels read_building_models(
    const std::string& work_dir, const std::string& id,
    const std::function<io::TriangleMesh(const std::string& file)>& read,
    const std::vector<std::size_t>* only) {
  BuildingModels b;
  b.report_path = lod_report_path(work_dir, id);
  if (!fs::exists(b.report_path))
    throw io::IoError(
        b.report_path,
        "building '" + id + "' has no LOD models (run 'citylod lod' on the work directory first)");
  b.report = read_lod_report(b.report_path);
  if (b.report.models.empty()) {
    std::string why = "building '" + id + "' has no models in report.json (status \"" +
                      std::string(to_string(b.report.status)) + "\"";
    if (!b.report.reason.empty()) why += ": " + json(b.report.reason).dump();
    throw io::IoError(b.report_path, why + ")");
  }
  const fs::path dir = lod_dir(work_dir, id);
  for (const ModelRecord& m : b.report.models) {
    const fs::path f = m.file;
    b.files.push_back((f.is_absolute() ? f : dir / f).string());
    if (!fs::exists(b.files.back()))
      throw io::IoError(b.files.back(), "model listed in " + b.report_path + " is missing");
  }
  b.meshes.resize(b.files.size());
  for (std::size_t i = 0; i < b.files.size(); ++i)
    if (!only || std::find(only->begin(), only->end(), i) != only->end())
      b.meshes[i] = read(b.files[i]);
  return b;
}

// ------------------------------------------------------------ overrides.json
Overrides read_overrides(const std::string& work_dir) {
  Overrides o;
  const std::string path = overrides_path(work_dir);
  if (!fs::exists(path)) return o;
  json j;
  try {
    j = read_json_file(path);
  } catch (const io::IoError&) {
    throw std::runtime_error(path + ": not valid JSON");
  }
  if (!j.is_object() || !j.contains("buildings") || !j["buildings"].is_object())
    throw std::runtime_error(path + ": not a citylod overrides file");
  try {
    for (const auto& [id, b] : j["buildings"].items()) {
      if (!is_safe_id(id)) checked_id(id);
      BuildingOverride bo;
      if (b.contains("set")) bo.set = string_map(b["set"]);
      if (b.contains("select"))
        for (const auto& s : b["select"]) bo.select.push_back(s.get<int>());
      o[id] = bo;
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": malformed overrides (" + std::string(e.what()) + ")");
  }
  return o;
}

void write_overrides(const std::string& work_dir, const Overrides& o) {
  json j;
  j["buildings"] = json::object();
  for (const auto& [id, b] : o) {
    if (b.set.empty() && b.select.empty()) continue;
    json e = json::object();
    if (!b.set.empty()) e["set"] = b.set;
    if (!b.select.empty()) e["select"] = b.select;
    j["buildings"][id] = e;
  }
  io::atomic_write_file(overrides_path(work_dir), j.dump(2) + "\n");
}

// ------------------------------------------------------------ run_report.json
RunReport read_run_report(const std::string& out_dir) {
  const std::string path = run_report_path(out_dir);
  if (!fs::exists(path))
    throw std::runtime_error(path + ": not found (DIR must be a 'citylod tile' output)");
  const json j = read_json_file(path);
  RunReport r;
  try {
    r.command = j.value("command", r.command);
    r.inputs = j.value("inputs", std::vector<std::string>{});
    r.threads = j.value("threads", r.threads);
    const json st = j.value("stages", json::object());
    r.split = st.value("split", json::object()).get<RunReport::Split>();
    r.lod = st.value("lod", json::object()).get<RunReport::Lod>();
    r.assemble = st.value("assemble", json::object()).get<RunReport::Assemble>();
    const json sum = j.value("summary", json::object());
    r.ok = sum.value("ok", std::size_t(0));
    r.fallback = sum.value("fallback", std::size_t(0));
    r.failed = sum.value("failed", std::size_t(0));
    r.skipped = sum.value("skipped", std::size_t(0));
    r.seconds_total = number(j, "seconds_total", 0);
    const json rss = j.value("peak_rss_bytes", json::object());
    r.peak_rss_self = rss.value("self", std::uint64_t(0));
    r.peak_rss_children = rss.value("children", std::uint64_t(0));
    if (j.contains("lod_params")) r.lod_params = string_map(j["lod_params"]);
    r.assemble_params = assemble_params_from_json(j.value("assemble_params", json::object()));
    for (const auto& b : j.value("buildings", json::array()))
      r.buildings.push_back(building_from_json(b));
    if (j.contains("last_rebuild")) {
      const json& l = j["last_rebuild"];
      RunReport::LastRebuild lr;
      lr.building = l.value("building", std::string());
      if (l.contains("set")) lr.set = string_map(l["set"]);
      lr.select = l.value("select", std::vector<int>{});
      lr.report_changed = l.value("report_changed", false);
      lr.changed = l.value("changed", std::vector<std::string>{});
      lr.added = l.value("added", std::vector<std::string>{});
      lr.removed = l.value("removed", std::vector<std::string>{});
      r.last_rebuild = lr;
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": malformed run report (" + std::string(e.what()) + ")");
  }
  return r;
}

void write_run_report(const std::string& out_dir, const RunReport& r) {
  json j;
  j["command"] = r.command;
  j["inputs"] = r.inputs;
  j["threads"] = r.threads;
  j["stages"] = {{"split", r.split}, {"lod", r.lod}, {"assemble", r.assemble}};
  j["summary"] = {
      {"ok", r.ok}, {"fallback", r.fallback}, {"failed", r.failed}, {"skipped", r.skipped}};
  j["seconds_total"] = r.seconds_total;
  j["peak_rss_bytes"] = {{"self", r.peak_rss_self}, {"children", r.peak_rss_children}};
  j["lod_params"] = json::object();
  for (const auto& [k, v] : r.lod_params) j["lod_params"][k] = v;
  j["assemble_params"] = to_json(r.assemble_params);
  j["work"] = kWorkName;  // where DIR's parts are, for a reader of the file
  j["tileset"] = kTilesetName;
  json bs = json::array();
  for (const auto& b : r.buildings) bs.push_back(to_json(b));
  j["buildings"] = bs;
  if (r.last_rebuild) {
    const auto& l = *r.last_rebuild;
    j["last_rebuild"] = {{"building", l.building}, {"set", l.set},
                         {"select", l.select},     {"report_changed", l.report_changed},
                         {"changed", l.changed},   {"added", l.added},
                         {"removed", l.removed}};
  }
  fs::create_directories(out_dir);
  io::atomic_write_file(run_report_path(out_dir), j.dump(2) + "\n");
}

}  // namespace citylod::tiler
