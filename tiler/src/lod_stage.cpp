#include "lod_stage.hpp"

#include "lod_io.hpp"
#include "stage_options.hpp"

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/workdir.hpp"
#include "citylod/lod/lod.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>

#include <unistd.h>

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

constexpr const char* kEngineVersion = "citylod-lod-6";

/// The key recorded in a finished building's report.json ("" when absent/unreadable).
std::string recorded_key(const std::string& dir) {
  std::ifstream f(fs::path(dir) / "report.json");
  if (!f) return "";
  try {
    nlohmann::json j;
    f >> j;
    return j.value("key", "");
  } catch (...) {
    return "";
  }
}

lod::BuildingInput chunk_input(const std::string& work, const io::ChunkRecord& c) {
  lod::BuildingInput in;
  const std::string path = io::chunk_path(work, c.id);
  const io::FileInfo info = io::read_header(path);
  if (info.has_faces) {
    const io::TriangleMesh m = io::read_mesh(path);
    for (const auto& v : m.vertices) in.points.emplace_back(v[0], v[1], v[2]);
    for (const auto& t : m.triangles) in.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
  } else {
    const io::PointSet p = io::read_points(path);
    for (const auto& v : p.positions) in.points.emplace_back(v[0], v[1], v[2]);
    if (p.has_normals())
      for (const auto& n : p.normals) in.normals.emplace_back(n[0], n[1], n[2]);
  }
  for (const auto& q : c.outline) in.footprint.emplace_back(q[0] - c.origin[0], q[1] - c.origin[1]);
  in.ground_z = c.ground_z - c.origin[2];
  in.has_ground_z = true;
  in.name = c.id;
  return in;
}

struct Outcome {
  std::string status, reason;
};

/// Runs one building and publishes WORK/lod/<id>/ atomically (its report.json
/// carries the resume key). Never throws for the building's own trouble: the
/// reason goes into the report. A building that crashed an earlier run is not
/// retried: it gets the engine's fallback model.
Outcome process_building(const std::string& work, const io::ChunkRecord& c, const lod::LodParams& p,
                         const std::string& key, bool crashed_before) {
  const std::string dir = io::lod_dir(work, c.id);
  const std::string stage = dir + ".tmp." + std::to_string(::getpid());
  fs::remove_all(stage);
  lod::LodResult r;
  try {
    const lod::BuildingInput in = chunk_input(work, c);
    r = crashed_before ? lod::fallback_result(in, "crashed in an earlier run; not retried")
                       : lod::build_lod_tree(in, p);
  } catch (const std::exception& e) {  // unreadable chunk, or no model at all (no points, no area)
    r = lod::LodResult{};
    r.status = "failed";
    r.reason = e.what();
  }
  write_lod_output(stage, r, p, io::chunk_path(work, c.id), {0, 0, 0}, false, {{"id", c.id}, {"key", key}});
  fs::remove_all(dir);
  fs::rename(stage, dir);
  return {r.status, r.reason};
}

}  // namespace

std::string lod_key(const std::string& content_hash, const lod::LodParams& p) {
  std::string s = std::string(kEngineVersion) + "|" + content_hash;
  for (const auto& [k, v] : p.items())
    if (k != "threads") s += "|" + k + "=" + v;
  return io::hash_hex(s.data(), s.size());
}

void parse_shard(const std::string& s, int& index, int& count) {
  const auto slash = s.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("");
    size_t a = 0, b = 0;
    index = std::stoi(s.substr(0, slash), &a);
    count = std::stoi(s.substr(slash + 1), &b);
    if (a != slash || b != s.size() - slash - 1) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw std::invalid_argument("--shard expects I/N, got '" + s + "'");
  }
  if (count < 1 || index < 0 || index >= count)
    throw std::invalid_argument("--shard " + s + ": need 0 <= I < N");
}

LodStageReport run_lod_stage(const LodStageOptions& o, LodStageProgress progress, void* user) {
  const auto t0 = std::chrono::steady_clock::now();
  LodStageReport rep;
  const io::Manifest m = io::read_manifest(o.work_dir);
  lod::LodParams params = o.params;
  params.threads = 1;  // parallelism is across buildings; results do not depend on it
  params.validate();

  // This shard's chunks (rank in id order, so every shard agrees), largest first.
  std::vector<const io::ChunkRecord*> todo;
  for (size_t i = 0; i < m.chunks.size(); ++i) {
    const auto& c = m.chunks[i];
    if (!o.only.empty() && std::find(o.only.begin(), o.only.end(), c.id) == o.only.end()) continue;
    if (o.only.empty() && int(i % size_t(o.shard_count)) != o.shard_index) continue;
    if (c.status == "skipped") continue;
    todo.push_back(&c);
  }
  std::stable_sort(todo.begin(), todo.end(), [](const io::ChunkRecord* a, const io::ChunkRecord* b) {
    const auto sa = a->points + a->triangles, sb = b->points + b->triangles;
    return sa != sb ? sa > sb : a->id < b->id;
  });
  rep.total = todo.size();
  fs::create_directories(fs::path(o.work_dir) / "lod");

  std::mutex mu;
  size_t done = 0;
  // Per-building parameter overrides (`citylod rebuild --set`, WORK/overrides.json)
  // apply wherever the stage runs: tile, lod WORK, Slurm shards.
  const Overrides overrides = read_overrides(o.work_dir);
  auto run_one = [&](const io::ChunkRecord& c) {
    const std::string dir = io::lod_dir(o.work_dir, c.id);
    lod::LodParams bp = params_for(params, overrides, c.id);
    bp.threads = 1;
    const std::string key = lod_key(c.content_hash, bp);
    const std::string running = dir + ".running", suspect = dir + ".suspect", crashed = dir + ".crashed";
    Outcome out;
    bool reused = false;
    if (o.only.empty() && recorded_key(dir) == key) {
      reused = true;
      std::ifstream f(fs::path(dir) / "report.json");
      nlohmann::json j;
      f >> j;
      out = {j.value("status", "ok"), j.value("reason", "")};
    } else {
      const bool crashed_before = fs::exists(crashed);
      io::atomic_write_file(running, c.id + "\n");
      fs::remove(suspect);
      out = process_building(o.work_dir, c, bp, key, crashed_before);
      fs::remove(running);
      fs::remove(crashed);
    }
    std::lock_guard<std::mutex> lock(mu);
    (reused ? rep.reused : rep.computed)++;
    if (out.status == "ok") ++rep.ok;
    else if (out.status == "fallback") ++rep.fallback;
    else ++rep.failed;
    if (out.status != "ok") rep.problems.emplace_back(c.id, out.reason);
    ++done;
    if (progress) progress(done, rep.total, user);
  };
  // Buildings that were running when an earlier process crashed go first, one
  // at a time: if one crashes again it is the only one running, and the
  // supervisor (supervise.hpp) marks it crashed.
  std::vector<const io::ChunkRecord*> rest;
  for (const auto* c : todo) {
    if (fs::exists(io::lod_dir(o.work_dir, c->id) + ".suspect")) run_one(*c);
    else rest.push_back(c);
  }
  const long n = long(rest.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::max(1, o.threads))
  for (long i = 0; i < n; ++i) run_one(*rest[size_t(i)]);
  std::sort(rep.problems.begin(), rep.problems.end());
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace citylod::tiler
