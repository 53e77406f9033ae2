#include "citylod/io/workdir.hpp"

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace citylod::io {

namespace fs = std::filesystem;
using nlohmann::json;

std::string manifest_path(const std::string& w) { return (fs::path(w) / "manifest.json").string(); }
std::string chunk_path(const std::string& w, const std::string& id) {
  return (fs::path(w) / "chunks" / (id + ".ply")).string();
}
std::string lod_dir(const std::string& w, const std::string& id) { return (fs::path(w) / "lod" / id).string(); }

namespace {

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string hex16(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

}  // namespace

std::string hash_hex(const void* data, std::size_t size, std::uint64_t seed) {
  return hex16(fnv1a(seed, data, size));
}

std::string hash_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw IoError(path, "cannot open for hashing");
  std::uint64_t h = 0xcbf29ce484222325ULL;
  std::vector<char> buf(1 << 16);
  while (f) {
    f.read(buf.data(), std::streamsize(buf.size()));
    const auto n = f.gcount();
    if (n <= 0) break;
    h = fnv1a(h, buf.data(), std::size_t(n));
  }
  return hex16(h);
}

namespace {

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
  o["status"] = c.status;
  if (!c.reason.empty()) o["reason"] = c.reason;
  o["content_hash"] = c.content_hash;
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
  c.status = o.value("status", "pending");
  c.reason = o.value("reason", "");
  c.content_hash = o.value("content_hash", "");
  return c;
}

}  // namespace

Manifest read_manifest(const std::string& work_dir) {
  const std::string path = manifest_path(work_dir);
  if (!fs::exists(work_dir)) throw IoError(work_dir, "work directory does not exist");
  std::ifstream f(path);
  if (!f) throw IoError(path, "missing manifest (run 'citylod split' first)");
  json j;
  try {
    f >> j;
  } catch (const std::exception& e) {
    throw IoError(path, std::string("not valid JSON: ") + e.what());
  }
  Manifest m;
  try {
    m.version = j.at("version").get<int>();
    if (m.version != 1) throw IoError(path, "unsupported manifest version " + std::to_string(m.version));
    const json& s = j.at("scene");
    m.scene.crs = s.value("crs", "");
    m.scene.origin_crs = s.at("origin_crs").get<std::array<double, 3>>();
    m.scene.origin_lon = s.at("origin_lon").get<double>();
    m.scene.origin_lat = s.at("origin_lat").get<double>();
    m.scene.origin_h = s.at("origin_h").get<double>();
    m.scene.inputs = s.value("inputs", std::vector<std::string>{});
    m.scene.options = s.value("options", "");
    m.scene.notes = s.value("notes", std::vector<std::string>{});
    for (const auto& c : j.at("chunks")) m.chunks.push_back(chunk_from_json(c));
  } catch (const IoError&) {
    throw;
  } catch (const std::exception& e) {
    throw IoError(path, std::string("malformed manifest: ") + e.what());
  }
  return m;
}

void write_manifest(const std::string& work_dir, const Manifest& m) {
  json j;
  j["version"] = m.version;
  j["scene"] = {{"crs", m.scene.crs},
                {"origin_crs", m.scene.origin_crs},
                {"origin_lon", m.scene.origin_lon},
                {"origin_lat", m.scene.origin_lat},
                {"origin_h", m.scene.origin_h},
                {"inputs", m.scene.inputs},
                {"options", m.scene.options},
                {"notes", m.scene.notes}};
  std::vector<ChunkRecord> sorted = m.chunks;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  json chunks = json::array();
  for (const auto& c : sorted) chunks.push_back(to_json(c));
  j["chunks"] = chunks;
  fs::create_directories(work_dir);
  atomic_write_file(manifest_path(work_dir), j.dump(1) + "\n");
}

}  // namespace citylod::io
