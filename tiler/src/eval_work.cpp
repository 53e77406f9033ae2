// `citylod eval WORK`: every model of every building of a work directory
// against the building's chunk (see eval_city.hpp).
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>

#include <omp.h>

#include "cli_common.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/workdir.hpp"
#include "eval_city.hpp"
#include "eval_format.hpp"
#include "lod_io.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// The models listed in lod/<id>/report.json (empty when there is no report).
void read_report(const std::string& work, const io::ChunkRecord& rec, WorkBuildingEval& b) {
  const std::string dir = io::lod_dir(work, rec.id);
  const std::string path = (fs::path(dir) / "report.json").string();
  b.status = rec.status;
  b.reason = rec.reason;
  if (!fs::exists(path)) {
    if (b.reason.empty()) b.reason = "no report.json";
    return;
  }
  nlohmann::json rep;
  {
    std::ifstream f(path);
    if (!f) throw io::IoError(path, "cannot open");
    try {
      f >> rep;
    } catch (const std::exception& e) {
      throw io::IoError(path, std::string("not valid JSON (") + one_line_text(e.what()) + ")");
    }
  }
  if (!rep.is_object()) throw io::IoError(path, "not a JSON object");
  b.status = rep.contains("status") && rep["status"].is_string() ? rep["status"].get<std::string>() : "ok";
  b.reason = rep.contains("reason") && rep["reason"].is_string() ? rep["reason"].get<std::string>() : "";
  if (!rep.contains("models")) return;
  if (!rep["models"].is_array()) throw io::IoError(path, "\"models\" is not an array");
  int index = 0;
  for (const auto& m : rep["models"]) {
    if (!m.is_object() || !m.contains("file") || !m["file"].is_string())
      throw io::IoError(path, "model " + std::to_string(index) + " has no \"file\"");
    WorkModelEval e;
    e.file = m["file"].get<std::string>();
    e.kind = m.contains("kind") && m["kind"].is_string() ? m["kind"].get<std::string>() : "anchor";
    e.level = m.contains("level") && m["level"].is_number_integer() ? m["level"].get<int>() : 0;
    e.step = m.contains("step") && m["step"].is_number_integer() ? m["step"].get<int>() : index;
    b.models.push_back(e);
    ++index;
  }
  std::stable_sort(b.models.begin(), b.models.end(),
                   [](const WorkModelEval& x, const WorkModelEval& y) { return x.step < y.step; });
  b.has_lod = !b.models.empty();
}

/// Chunk + models of one building: the evaluations.
void evaluate_building(const std::string& work, const io::ChunkRecord& rec, WorkBuildingEval& b, int samples) {
  b.chunk = io::chunk_path(work, rec.id);
  if (!fs::exists(b.chunk)) throw io::IoError(b.chunk, "chunk of building '" + rec.id + "' is missing");
  const LoadedBuilding ref = load_building(b.chunk);
  if (ref.input.points.empty()) throw io::IoError(b.chunk, "chunk of building '" + rec.id + "' is empty");
  b.reference_points = ref.is_mesh ? 0 : ref.input.points.size();
  b.reference_triangles = ref.input.triangles.size();
  const std::string dir = io::lod_dir(work, rec.id);
  for (auto& m : b.models) {
    const fs::path f = m.file;
    const std::string path = (f.is_absolute() ? f : fs::path(dir) / f).string();
    if (!fs::exists(path)) throw io::IoError(path, "model listed in " + dir + "/report.json is missing");
    const io::TriangleMesh mesh = io::read_mesh(path);
    lod::TriangleMesh model;
    model.vertices.reserve(mesh.vertices.size());
    for (const auto& v : mesh.vertices)
      model.vertices.emplace_back(v[0] - ref.origin[0], v[1] - ref.origin[1], v[2] - ref.origin[2]);
    for (const auto& t : mesh.triangles) model.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
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
    const bool anchor = m.kind != "interpolation";
    if (b.finest < 0 || anchor || b.models[size_t(b.finest)].kind == "interpolation") b.finest = i;
  }
}

struct Stat {
  double mean = 0, median = 0, max = 0;
  std::string argmax;
};

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

struct WorkSummary {
  std::size_t buildings = 0, models = 0, closed = 0, edge_manifold = 0, oriented = 0, self_intersecting = 0,
              empty = 0;
  Stat finest_e1, finest_e2;
  std::vector<std::pair<std::string, std::string>> fallbacks, without_lod;  // id, reason
};

WorkSummary summarize(const WorkEval& w) {
  WorkSummary s;
  std::vector<std::pair<double, std::string>> e1, e2;
  for (const auto& b : w.buildings) {
    if (!b.has_lod) {
      s.without_lod.emplace_back(b.id, b.status + (b.reason.empty() ? "" : ": " + b.reason));
      continue;
    }
    ++s.buildings;
    bool fallback = b.status == "fallback";
    for (const auto& m : b.models) {
      fallback = fallback || m.kind == "fallback";
      ++s.models;
      if (m.empty) {
        ++s.empty;
        continue;
      }
      s.closed += m.e.check.closed;
      s.edge_manifold += m.e.check.edge_manifold;
      s.oriented += m.e.check.oriented;
      s.self_intersecting += m.e.check.self_intersecting;
    }
    if (fallback) s.fallbacks.emplace_back(b.id, b.reason.empty() ? std::string("(no reason given)") : b.reason);
    if (b.finest >= 0) {
      e1.emplace_back(b.models[size_t(b.finest)].e.e1, b.id);
      e2.emplace_back(b.models[size_t(b.finest)].e.e2, b.id);
    }
  }
  s.finest_e1 = stat(e1);
  s.finest_e2 = stat(e2);
  return s;
}

}  // namespace

WorkEval evaluate_work(const std::string& work_dir, const EvalOptions& o) {
  if (!fs::is_directory(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  const io::Manifest man = io::read_manifest(work_dir);
  if (man.chunks.empty()) throw io::IoError(io::manifest_path(work_dir), "the manifest lists no buildings");
  WorkEval w;
  w.work = work_dir;
  w.samples = o.samples;
  w.manifest_buildings = man.chunks.size();
  std::vector<const io::ChunkRecord*> recs;
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
    throw io::IoError(work_dir, "no building has LOD output (lod/<id>/report.json with models; run 'citylod lod " +
                                    work_dir + "' first)");
  // Largest chunks first (dynamic schedule); results land in their own slot.
  std::stable_sort(todo.begin(), todo.end(), [&](std::size_t a, std::size_t b) {
    return recs[a]->points + recs[a]->triangles > recs[b]->points + recs[b]->triangles;
  });
  std::vector<std::string> errors(recs.size());
  Progress progress("eval", todo.size(), "buildings");
  std::mutex mutex;
  const int threads = o.threads > 0 ? o.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (long k = 0; k < long(todo.size()); ++k) {
    const std::size_t i = todo[size_t(k)];
    try {
      evaluate_building(work_dir, *recs[i], w.buildings[i], o.samples);
    } catch (const std::exception& e) {
      errors[i] = e.what();
    }
    std::lock_guard<std::mutex> lock(mutex);
    progress.advance(1);
  }
  progress.finish();
  for (const auto& e : errors)
    if (!e.empty()) throw std::runtime_error(e);  // the first in id order
  return w;
}

nlohmann::ordered_json to_json(const WorkEval& w) {
  using J = nlohmann::ordered_json;
  const WorkSummary s = summarize(w);
  J out;
  out["mode"] = "work";
  out["work"] = w.work;
  out["samples"] = w.samples;
  J bs = J::array();
  for (const auto& b : w.buildings) {
    J jb;
    jb["id"] = b.id;
    jb["status"] = b.status;
    if (!b.reason.empty()) jb["reason"] = b.reason;
    jb["has_lod"] = b.has_lod;
    if (b.has_lod) {
      jb["reference"] = {{"file", b.chunk},
                         {"points", b.reference_points},
                         {"triangles", b.reference_triangles},
                         {"diagonal_m", b.diagonal}};
      jb["finest_step"] = b.finest >= 0 ? J(b.models[size_t(b.finest)].step) : J(nullptr);
      J ms = J::array();
      for (const auto& m : b.models) {
        J jm = model_json(m.e, m.empty);
        J head{{"file", m.file}, {"kind", m.kind}, {"level", m.level}, {"step", m.step}};
        head.update(jm);
        ms.push_back(head);
      }
      jb["models"] = ms;
    }
    bs.push_back(jb);
  }
  out["buildings"] = bs;
  J sum;
  sum["manifest_buildings"] = w.manifest_buildings;
  sum["buildings"] = s.buildings;
  sum["models"] = s.models;
  sum["closed"] = s.closed;
  sum["edge_manifold"] = s.edge_manifold;
  sum["oriented"] = s.oriented;
  sum["self_intersecting"] = s.self_intersecting;
  sum["empty"] = s.empty;
  auto stat_json = [](const Stat& st) {
    return J{{"mean", st.mean}, {"median", st.median}, {"max", st.max}, {"max_building", st.argmax}};
  };
  sum["finest_e1_percent"] = stat_json(s.finest_e1);
  sum["finest_e2_percent"] = stat_json(s.finest_e2);
  J fb = J::array();
  for (const auto& [id, why] : s.fallbacks) fb.push_back({{"id", id}, {"reason", why}});
  sum["fallbacks"] = fb;
  J nl = J::array();
  for (const auto& [id, why] : s.without_lod) nl.push_back({{"id", id}, {"reason", why}});
  sum["without_lod"] = nl;
  out["summary"] = sum;
  return out;
}

std::string to_text(const WorkEval& w) {
  const WorkSummary s = summarize(w);
  std::string out = strf("work directory %s: %zu buildings in the manifest, %zu with LOD output, %zu models "
                         "(e1/e2 with %d samples per surface, %% of the reference's bbox diagonal)\n\n",
                         w.work.c_str(), w.manifest_buildings, s.buildings, s.models, w.samples);
  std::size_t idw = 8;
  for (const auto& b : w.buildings)
    if (b.has_lod) idw = std::max(idw, b.id.size());
  out += strf("%-*s %4s %-13s %3s %9s %-6s %-8s %-8s %12s %8s %8s %11s\n", int(idw), "building", "step", "kind", "L",
              "triangles", "closed", "manifold", "self-int", "volume m3", "e1 %", "e2 %", "Hausdorff m");
  for (const auto& b : w.buildings) {
    if (!b.has_lod) continue;
    for (std::size_t i = 0; i < b.models.size(); ++i) {
      const WorkModelEval& m = b.models[i];
      const std::string kind = m.kind + (int(i) == b.finest ? "*" : "");
      if (m.empty) {
        out += strf("%-*s %4d %-13s %3d %9d %-6s %-8s %-8s %12s %8s %8s %11s\n", int(idw), b.id.c_str(), m.step,
                    kind.c_str(), m.level, 0, "-", "-", "-", "-", "-", "-", "-");
        continue;
      }
      out += strf("%-*s %4d %-13s %3d %9zu %-6s %-8s %-8s %12.3f %8.3f %8.3f %11.3f\n", int(idw), b.id.c_str(),
                  m.step, kind.c_str(), m.level, m.e.triangles, yes_no(m.e.check.closed),
                  yes_no(m.e.check.edge_manifold), yes_no(m.e.check.self_intersecting), m.e.volume, m.e.e1, m.e.e2,
                  m.e.hausdorff);
    }
  }
  out += "(* = finest model of the building: its last anchor)\n\n";
  out += strf("summary: %zu buildings, %zu models: %zu closed, %zu edge-manifold, %zu self-intersecting", s.buildings,
              s.models, s.closed, s.edge_manifold, s.self_intersecting);
  if (s.empty) out += strf(", %zu empty", s.empty);
  out += "\n";
  out += strf("finest model per building: e2 mean %.3f %%, median %.3f %%, max %.3f %% (%s); "
              "e1 mean %.3f %%, median %.3f %%, max %.3f %% (%s)\n",
              s.finest_e2.mean, s.finest_e2.median, s.finest_e2.max, s.finest_e2.argmax.c_str(), s.finest_e1.mean,
              s.finest_e1.median, s.finest_e1.max, s.finest_e1.argmax.c_str());
  out += strf("fallbacks: %zu\n", s.fallbacks.size());
  for (const auto& [id, why] : s.fallbacks) out += "  " + id + ": " + why + "\n";
  if (!s.without_lod.empty()) {
    out += strf("without LOD output: %zu\n", s.without_lod.size());
    for (const auto& [id, why] : s.without_lod) out += "  " + id + ": " + why + "\n";
  }
  return out;
}

}  // namespace citylod::tiler
