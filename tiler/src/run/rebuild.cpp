// rebuild() (city_run.hpp): change one building of a `citylod tile` output and
// update the tileset.
//
// set:    the building's parameter overrides are merged into DIR/work/overrides.json
//         (later `tile` runs keep them) and its LOD is recomputed (the LOD stage with
//         only = {ID}, in a supervised child).
// select: pins which of its candidate models (by step, see its report.json) are
//         shown; persisted in overrides.json and applied to its report.json
//         ("models" filtered, full list in "models_all").
// Then assemble recomputes the whole tileset and switches it in atomically
// (staged, fsync'd, one rename: assemble.hpp); the files whose bytes differ
// are reported (changed, added, removed).
#include <algorithm>
#include <filesystem>
#include <map>
#include <sstream>
#include <stdexcept>

#include "citylod/io/hash.hpp"
#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/cityjson.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/log.hpp"
#include "citylod/tiler/option_names.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// Relative path -> content hash of every regular file under `root`.
std::map<std::string, std::string> hash_tree(const fs::path& root) {
  std::map<std::string, std::string> h;
  if (!fs::exists(root)) return h;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file())
      h[fs::relative(e.path(), root).generic_string()] = io::hash_file(e.path().string());
  return h;
}

struct TreeDiff {
  std::vector<std::string> changed, added, removed;
};

TreeDiff diff(const std::map<std::string, std::string>& before,
              const std::map<std::string, std::string>& after) {
  TreeDiff d;
  for (const auto& [rel, h] : after) {
    auto it = before.find(rel);
    if (it == before.end())
      d.added.push_back(rel);
    else if (it->second != h)
      d.changed.push_back(rel);
  }
  for (const auto& [rel, h] : before)
    if (!after.count(rel)) d.removed.push_back(rel);
  return d;
}

}  // namespace

std::vector<int> parse_select(const std::string& s) {
  std::vector<int> steps;
  if (s == "all" || s == "auto") return steps;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (*end != '\0' || v < 0)
      throw std::invalid_argument(option_name("select") +
                                  " expects model steps like 0,3,5 (or 'all'), got '" + item + "'");
    steps.push_back(int(v));
  }
  if (steps.empty()) throw std::invalid_argument(option_name("select") + ": no steps given");
  std::sort(steps.begin(), steps.end());
  steps.erase(std::unique(steps.begin(), steps.end()), steps.end());
  return steps;
}

RebuildResult rebuild(const RebuildOptions& o, const ProgressFn& progress) {
  const fs::path dir = o.dir;
  const std::string& id = o.building;
  const std::string work = run_work_dir(dir.string());
  const fs::path tileset = run_tileset_dir(dir.string());
  RunReport run = read_run_report(dir.string());
  const DirLock dir_lock(dir.string()), work_lock(work);  // one writer (dir_lock.hpp)
  run = read_run_report(dir.string());                    // as the lock holder sees it
  lod::LodParams global =
      city_lod_params();  // a run report of an older version may lack newer names
  for (const auto& [k, v] : run.lod_params) global.set(k, v);
  AssembleParams ap = run.assemble_params;
  ap.threads = o.threads;

  const Manifest m = read_manifest(work);
  const ChunkRecord* rec = nullptr;
  for (const auto& c : m.chunks)
    if (c.id == id) rec = &c;
  if (!rec) throw std::runtime_error(manifest_path(work) + ": no building '" + id + "'");
  if (rec->skipped())
    throw std::runtime_error("building '" + id + "' was skipped by split (" + rec->reason +
                             "); nothing to rebuild");

  const Overrides old = read_overrides(work);
  Overrides ov = old;
  RebuildResult res;
  res.report = lod_report_path(work, id);
  BuildingOverride& bo = ov[id];
  const bool recompute = o.set || o.reset || !o.select;
  if (o.reset) bo.set.clear();
  if (o.set) {
    lod::LodParams probe;  // validates names and values
    apply_lod_settings(probe, *o.set);
    std::stringstream ss(*o.set);
    std::string item;
    while (std::getline(ss, item, ',')) {
      const auto eq = item.find('=');
      if (eq != std::string::npos) bo.set[item.substr(0, eq)] = item.substr(eq + 1);
    }
    params_for(global, ov, id).validate();
    if (!o.select && !bo.select.empty()) {
      log_info("rebuild: " + id +
               ": its model selection was dropped (the models change with the parameters)");
      bo.select.clear();
    }
  }
  if (o.select) bo.select = parse_select(*o.select);

  const std::string report_before = fs::exists(res.report) ? io::hash_file(res.report) : "";
  write_overrides(work, ov);

  if (recompute) {
    LodStageOptions lo;
    lo.work_dir = work;
    lo.params = global;
    lo.threads = 1;
    lo.only = {id};  // recompute this one; the others are untouched
    run_lod_supervised(lo, progress);
  }
  for (const auto& w : apply_model_selections(work, ov)) {
    if (w.rfind(id + ":", 0) == 0 && o.select) {
      // A selection that does not fit this building's models is not kept.
      bo.select = old.count(id) ? old.at(id).select : std::vector<int>{};
      write_overrides(work, ov);
      apply_model_selections(work, ov);
      throw std::runtime_error(id + ": " + option_name("select") + " " + *o.select +
                               ": these steps are not among its models or include no anchor (see " +
                               res.report + ")");
    }
    log_warn(w);
  }
  const std::string report_after = fs::exists(res.report) ? io::hash_file(res.report) : "";
  res.report_changed = report_before != report_after;
  log_info("rebuild: " + res.report + (res.report_changed ? " changed" : " unchanged"));

  // Assemble publishes the new tileset in one atomic switch (assemble.hpp): killed
  // at any point, DIR/tileset is the previous or the new complete tileset.
  std::error_code ec;
  fs::remove_all(dir / ".tileset.rebuild", ec);  // staging dir of older versions
  const auto before = hash_tree(tileset);
  const AssembleStats st = assemble(work, tileset.string(), ap, progress);
  for (const auto& w : st.warnings) log_warn(w);
  const TreeDiff d = diff(before, hash_tree(tileset));
  res.changed = d.changed;
  res.added = d.added;
  res.removed = d.removed;
  // The CityJSON of a `tile` output follows (docs/cityjson.md).
  const fs::path cj = run_cityjson_path(dir.string());
  if (fs::exists(cj)) {
    CityJsonOptions co;
    co.min_change_m = ap.min_change_m;
    co.hausdorff_tolerance_m = ap.hausdorff_tolerance_m;
    co.skip_missing = ap.skip_missing;
    co.threads = ap.threads;
    co.chains = &st.chains;  // the tileset's chains, not chosen again
    for (const auto& w : write_cityjson(work, cj.string(), co, progress).warnings) log_warn(w);
  }

  // Keep the run report in step.
  run.buildings = building_records(work, ov);
  run.last_rebuild = RunReport::LastRebuild{id,        bo.set,  bo.select, res.report_changed,
                                            d.changed, d.added, d.removed};
  write_run_report(dir.string(), run);
  return res;
}

}  // namespace citylod::tiler
