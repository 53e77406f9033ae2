// `citylod eval WORK`: every model of every building of a work directory
// against the building's chunk (see citylod/tiler/eval.hpp).
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>

#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/eval.hpp"
#include "citylod/tiler/threads.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// The models listed in lod/<id>/report.json (none when there is no report).
void read_report(const std::string& work, const ChunkRecord& rec, WorkBuildingEval& b) {
  b.status = rec.status;
  b.reason = rec.reason;
  const std::optional<LodReport> rep = find_lod_report(work, rec.id);
  if (!rep) {
    if (b.reason.empty()) b.reason = "no report.json";
    return;
  }
  b.status = rep->status;
  b.reason = rep->reason;
  for (const ModelRecord& m : rep->models)
    b.models.push_back({m.file, m.kind, m.level, m.step, false, {}});
  std::stable_sort(b.models.begin(), b.models.end(),
                   [](const WorkModelEval& x, const WorkModelEval& y) { return x.step < y.step; });
  b.has_lod = !b.models.empty();
}

/// Chunk + models of one building: the evaluations.
void evaluate_building(const std::string& work, const ChunkRecord& rec, WorkBuildingEval& b,
                       int samples) {
  b.chunk = chunk_path(work, rec.id);
  if (!fs::exists(b.chunk))
    throw io::IoError(b.chunk, "chunk of building '" + rec.id + "' is missing");
  const LoadedBuilding ref = load_building(b.chunk);
  if (ref.input.points.empty())
    throw io::IoError(b.chunk, "chunk of building '" + rec.id + "' is empty");
  b.reference_points = ref.is_mesh ? 0 : ref.input.points.size();
  b.reference_triangles = ref.input.triangles.size();
  const std::string dir = lod_dir(work, rec.id);
  for (auto& m : b.models) {
    const fs::path f = m.file;
    const std::string path = (f.is_absolute() ? f : fs::path(dir) / f).string();
    if (!fs::exists(path))
      throw io::IoError(path, "model listed in " + dir + "/report.json is missing");
    const lod::TriangleMesh model = to_lod_mesh(io::read_mesh(path), ref.origin);
    if (model.triangles.empty()) {
      m.empty = true;
      m.e.check = lod::check_mesh(model);
      continue;
    }
    m.e = lod::evaluate_model(model, ref.input, samples);
    b.diagonal = m.e.diagonal;
  }
  // Finest: the last anchor (a fallback counts as one), else the last non-empty model.
  for (int i = 0; i < int(b.models.size()); ++i) {
    const auto& m = b.models[size_t(i)];
    if (m.empty) continue;
    const bool anchor = is_anchor(m.kind);
    if (b.finest < 0 || anchor || !is_anchor(b.models[size_t(b.finest)].kind)) b.finest = i;
  }
}

}  // namespace

namespace {
Stat stat(std::vector<std::pair<double, std::string>> v) {
  Stat s;
  if (v.empty()) return s;
  double sum = 0;
  for (const auto& [x, id] : v) {
    sum += x;
    if (s.argmax.empty() || x > s.max) {
      s.max = x;
      s.argmax = id;
    }
  }
  s.mean = sum / double(v.size());
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  s.median = n % 2 ? v[n / 2].first : (v[n / 2 - 1].first + v[n / 2].first) / 2;
  return s;
}

}  // namespace

WorkSummary summarize(const WorkEval& w) {
  WorkSummary s;
  std::vector<std::pair<double, std::string>> e1, e2;
  for (const auto& b : w.buildings) {
    if (!b.has_lod) {
      s.without_lod.emplace_back(b.id,
                                 to_string(b.status) + (b.reason.empty() ? "" : ": " + b.reason));
      continue;
    }
    ++s.buildings;
    bool fallback = b.status == Status::fallback;
    for (const auto& m : b.models) {
      fallback = fallback || m.kind == ModelKind::fallback;
      ++s.models;
      if (m.empty) {
        ++s.empty;
        continue;
      }
      s.closed += m.e.check.closed;
      s.edge_manifold += m.e.check.edge_manifold;
      s.oriented += m.e.check.oriented;
      s.self_intersecting += m.e.check.self_intersecting;
      s.pinched += m.e.check.pinched_vertices > 0;
      s.not_one_shell += m.e.check.shells != 1;
      s.valid += m.e.check.valid();
    }
    if (fallback)
      s.fallbacks.emplace_back(b.id,
                               b.reason.empty() ? std::string("(no reason given)") : b.reason);
    if (b.finest >= 0) {
      e1.emplace_back(b.models[size_t(b.finest)].e.e1, b.id);
      e2.emplace_back(b.models[size_t(b.finest)].e.e2, b.id);
    }
  }
  s.finest_e1 = stat(e1);
  s.finest_e2 = stat(e2);
  return s;
}

WorkEval evaluate_work(const std::string& work_dir, const EvalOptions& o,
                       const ProgressFn& progress) {
  if (!fs::is_directory(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  const Manifest man = read_manifest(work_dir);
  if (man.chunks.empty())
    throw io::IoError(manifest_path(work_dir), "the manifest lists no buildings");
  WorkEval w;
  w.work = work_dir;
  w.samples = o.samples;
  w.manifest_buildings = man.chunks.size();
  std::vector<const ChunkRecord*> recs;
  for (const auto& c : man.chunks) recs.push_back(&c);
  std::sort(recs.begin(), recs.end(), [](const auto* a, const auto* b) { return a->id < b->id; });
  w.buildings.resize(recs.size());
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < recs.size(); ++i) {
    w.buildings[i].id = recs[i]->id;
    read_report(work_dir, *recs[i], w.buildings[i]);
    if (w.buildings[i].has_lod) todo.push_back(i);
  }
  if (todo.empty())
    throw io::IoError(
        work_dir,
        "no building has LOD output (lod/<id>/report.json with models; run 'citylod lod " +
            work_dir + "' first)");
  // Largest chunks first (dynamic schedule); results land in their own slot.
  std::stable_sort(todo.begin(), todo.end(), [&](std::size_t a, std::size_t b) {
    return recs[a]->points + recs[a]->triangles > recs[b]->points + recs[b]->triangles;
  });
  std::vector<std::string> errors(recs.size());
  std::mutex mutex;
  std::size_t done = 0;
  const int threads = resolve_threads(o.threads);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (long k = 0; k < long(todo.size()); ++k) {
    const std::size_t i = todo[size_t(k)];
    try {
      evaluate_building(work_dir, *recs[i], w.buildings[i], o.samples);
    } catch (const std::exception& e) {
      errors[i] = e.what();
    }
    std::lock_guard<std::mutex> lock(mutex);
    notify_count(progress, "eval", ++done, todo.size(), "buildings");
  }
  notify_finished(progress, "eval");
  for (const auto& e : errors)
    if (!e.empty()) throw std::runtime_error(e);  // the first in id order
  return w;
}

}  // namespace citylod::tiler
