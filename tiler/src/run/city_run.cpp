// The city run (city_run.hpp): split -> supervised LOD stage -> assemble -> run report.
// Fork-safety: the LOD stage runs in a supervised child (supervise.hpp) and
// schedules its buildings on std::threads, so run_city() may follow an earlier
// run's OpenMP regions (assemble) in the same process.
#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/option_names.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <set>
#include <stdexcept>

#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/log.hpp"
#include "citylod/tiler/supervise.hpp"
#include "citylod/tiler/threads.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::uint64_t max_rss_bytes(int who) {
  rusage u{};
  ::getrusage(who, &u);
  return std::uint64_t(u.ru_maxrss) * 1024;  // KiB on Linux
}

std::string fixed1(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

}  // namespace

// ------------------------------------------------------------ the LOD stage, supervised
std::string describe(const CityLodSummary& s) {
  return "lod: " + std::to_string(s.buildings) + " buildings (" + std::to_string(s.computed) +
         " computed, " + std::to_string(s.reused) + " reused): " + std::to_string(s.ok) + " ok, " +
         std::to_string(s.fallback) + " fallback, " + std::to_string(s.failed) + " failed in " +
         fixed1(s.seconds) + " s" +
         (s.restarts ? " (" + std::to_string(s.restarts) + " restarts after a crash)"
                     : std::string());
}

CityLodSummary run_lod_supervised(const LodStageOptions& o, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  LodStageOptions every = o;
  every.only.clear();
  const LodStagePlan plan = plan_lod_stage(every);  // before the fork: what is up to date
  const LodStageLock lock(o);  // one writer (shards: one per shard); the worker inherits it
  CityLodSummary s;
  s.buildings = plan.items.size();
  if (o.only.empty()) {
    s.reused = plan.up_to_date();
    s.computed = s.buildings - s.reused;
  } else {
    for (const auto& it : plan.items)
      s.computed += std::find(o.only.begin(), o.only.end(), it.chunk->id) != o.only.end() ? 1 : 0;
    s.reused = s.buildings - s.computed;
  }
  int crashes = 0;
  const int rc = supervise(
      o.work_dir,
      [&]() {
        run_lod_stage(o, progress);
        return 0;
      },
      1000, &crashes);
  if (rc != 0)
    throw std::runtime_error(o.work_dir + ": the LOD stage failed (exit " + std::to_string(rc) +
                             ")");
  s.restarts = std::size_t(crashes);
  for (const auto& it : plan.items) {
    Status st = Status::failed;
    std::string why = "no report";
    try {
      if (const auto r = find_lod_report(o.work_dir, it.chunk->id)) {
        st = r->status;
        why = r->reason;
      }
    } catch (const std::exception& e) {
      why = e.what();
    }
    s.add_lod_outcome(st);
    if (st != Status::ok) s.problems.emplace_back(it.chunk->id, why);
  }
  std::sort(s.problems.begin(), s.problems.end());
  s.seconds = since(t0);
  log_info(describe(s));
  for (const auto& [id, why] : s.problems) log_warn("lod: " + id + ": " + why);
  return s;
}

// ------------------------------------------------------------ building blocks
std::vector<std::string> apply_model_selections(const std::string& work_dir,
                                                const Overrides& overrides) {
  std::vector<std::string> warnings;
  const Manifest m = read_manifest(work_dir);
  for (const auto& c : m.chunks) {
    std::optional<LodReport> rep;
    try {
      rep = find_lod_report(work_dir, c.id);
    } catch (const std::exception&) {
      continue;  // unreadable: assemble names it
    }
    if (!rep) continue;
    LodReport& r = *rep;
    const std::vector<ModelRecord> all = r.all_models();
    auto it = overrides.find(c.id);
    std::vector<int> sel = it == overrides.end() ? std::vector<int>{} : it->second.select;
    if (!sel.empty()) {
      std::vector<ModelRecord> chosen;
      bool anchor = false;
      std::set<int> found;
      for (const auto& mr : all) {
        if (std::find(sel.begin(), sel.end(), mr.step) == sel.end()) continue;
        chosen.push_back(mr);
        found.insert(mr.step);
        anchor |= is_anchor(mr.kind);
      }
      if (found.size() != std::set<int>(sel.begin(), sel.end()).size() || !anchor) {
        warnings.push_back(
            c.id + ": model selection ignored (" +
            (anchor ? std::string("unknown steps") : std::string("no anchor model selected")) +
            " for the current models; run '" + rerun_name("rebuild", "select") + "' again)");
        sel.clear();
      } else {
        r.models = chosen;
        r.models_all = all;
        r.selected_steps = sel;
      }
    }
    if (sel.empty()) {
      r.models = all;
      r.models_all.reset();
      r.selected_steps.clear();
    }
    write_lod_report(lod_report_path(work_dir, c.id), r);  // only when the bytes change
  }
  return warnings;
}

std::vector<BuildingRecord> building_records(const std::string& work_dir,
                                             const Overrides& overrides) {
  std::vector<BuildingRecord> out;
  const Manifest m = read_manifest(work_dir);
  for (const auto& c : m.chunks) {
    BuildingRecord b;
    b.id = c.id;
    b.source = c.source;
    if (c.skipped()) {
      b.status = Status::skipped;
      b.reason = c.reason.empty() ? std::string("skipped by split") : c.reason;
    } else {
      std::optional<LodReport> r;
      try {
        r = find_lod_report(work_dir, c.id);
      } catch (const std::exception&) {
      }
      if (!r) {
        b.status = Status::failed;
        b.reason = "no report.json (LOD stage did not finish this building)";
      } else {
        b.status = r->status;
        b.reason = r->reason;
        b.models = r->models.size();
        if (b.models == 0 && b.reason.empty()) b.reason = "no models";
      }
    }
    auto it = overrides.find(c.id);
    if (it != overrides.end()) {
      b.set = it->second.set;
      b.select = it->second.select;
    }
    out.push_back(b);
  }
  return out;
}

// ------------------------------------------------------------ split, checked
SplitReport split_checked(SplitOptions so, const ProgressFn& progress) {
  const std::string& work = so.work_dir;
  require_own_chunks(work);
  SplitReport r = split_scene(so, progress);
  if (!r.up_to_date) return r;
  // Up to date by its inputs and options: are the chunks still what split wrote?
  const Manifest m = read_manifest(work);
  const auto bad = std::find_if(m.chunks.begin(), m.chunks.end(), [&](const ChunkRecord& c) {
    return !c.skipped() && !chunk_intact(work, c);
  });
  if (bad == m.chunks.end()) return r;
  log_warn("split: " + chunk_path(work, bad->id) +
           " is missing, truncated or changed since split; splitting again");
  so.force = true;
  return split_scene(so, progress);
}

// ------------------------------------------------------------ tile
CityRunResult run_city(const CityRunOptions& opt, const ProgressFn& progress) {
  const auto t_start = std::chrono::steady_clock::now();
  const std::string dir = opt.out_dir;
  const std::string work = run_work_dir(dir);
  const std::string tileset = run_tileset_dir(dir);
  const int threads = resolve_threads(opt.threads);
  SplitOptions so = opt.split;
  so.work_dir = work;
  so.threads = threads;
  const lod::LodParams& params = opt.lod;
  params.validate();
  AssembleParams ap = opt.assemble;
  ap.threads = threads;
  ap.validate();
  fs::create_directories(dir);
  // One writer per output: a second run into DIR refuses at once (dir_lock.hpp).
  const DirLock dir_lock(dir), work_lock(work);

  CityRunResult res;
  RunReport& report = res.report;
  report.command = "tile";
  report.inputs = so.inputs;
  report.threads = threads;

  // ---- split (no OpenMP in this process before the fork below)
  auto t0 = std::chrono::steady_clock::now();
  res.split = split_checked(so, progress);
  const SplitReport& sr = res.split;
  const double t_split = since(t0);
  for (const auto& n : sr.notes) log_info("note: " + n);
  log_info("split: " + (sr.up_to_date ? std::string("up to date, ") : std::string()) +
           std::to_string(sr.chunks) + " chunks in " + fixed1(t_split) + " s");
  report.split = {t_split,     sr.up_to_date,      sr.chunks,           sr.points,          sr.crs,
                  sr.vertical, sr.building_points, sr.unmatched_points, sr.unmatched_chunks};

  // ---- lod, in a supervised child
  const Overrides overrides = read_overrides(work);
  LodStageOptions lo;
  lo.work_dir = work;
  lo.params = params;
  lo.threads = threads;
  res.lod = run_lod_supervised(lo, progress);
  for (const auto& w : apply_model_selections(work, overrides)) log_warn(w);
  report.lod = {res.lod.seconds, res.lod.buildings, res.lod.computed, res.lod.reused,
                res.lod.restarts};

  // ---- assemble (OpenMP: after the fork)
  t0 = std::chrono::steady_clock::now();
  res.assemble = assemble(work, tileset, ap, progress);
  const AssembleStats& st = res.assemble;
  for (const auto& w : st.warnings) log_warn(w);
  report.assemble = {since(t0),      st.buildings, st.tiles,   st.glb_bytes,
                     st.models_kept, st.depth,     st.warnings};

  // ---- CityJSON of the same chains (docs/cityjson.md)
  if (opt.cityjson) {
    CityJsonOptions co;
    co.min_change_m = ap.min_change_m;
    co.hausdorff_tolerance_m = ap.hausdorff_tolerance_m;
    co.skip_missing = ap.skip_missing;
    co.threads = threads;
    co.chains = &st.chains;  // the tileset's chains, not chosen again
    res.cityjson = write_cityjson(work, run_cityjson_path(dir), co, progress);
    for (const auto& w : res.cityjson.warnings) log_warn(w);
  }

  // ---- summary + run report
  report.buildings = building_records(work, overrides);
  for (const auto& b : report.buildings) {
    report.add(b.status);
    if (b.status == Status::fallback || b.status == Status::failed)
      res.problems.push_back(b.id + " (" + to_string(b.status) + "): " + b.reason);
  }
  report.seconds_total = since(t_start);
  report.peak_rss_self = max_rss_bytes(RUSAGE_SELF);
  report.peak_rss_children = max_rss_bytes(RUSAGE_CHILDREN);
  for (const auto& [k, v] : params.items()) report.lod_params[k] = v;
  report.assemble_params = ap;
  write_run_report(dir, report);
  return res;
}

}  // namespace citylod::tiler
