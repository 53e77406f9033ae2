// `citylod rebuild DIR --building ID [--set P=V,...] [--select STEPS]`: change one
// building of a `citylod tile` output and update the tileset.
//
// --set: the building's parameter overrides are merged into DIR/work/overrides.json
//        (later `tile` runs keep them) and its LOD is recomputed (run_lod_stage with
//        only = {ID}, in a supervised child).
// --select: pins which of its candidate models (by step, see its report.json) are
//        shown; persisted in overrides.json and applied to its report.json
//        ("models" filtered, full list in "models_all").
// Then assemble runs into DIR/.tileset.rebuild; files whose bytes differ from
// DIR/tileset are copied over (new ones added, vanished ones removed,
// tileset.json last) and listed. Assemble itself recomputes the whole tileset.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "assemble.hpp"
#include "cli_common.hpp"
#include "stage_options.hpp"
#include "supervise.hpp"

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/workdir.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// Relative path -> content hash of every regular file under `root`.
std::map<std::string, std::string> hash_tree(const fs::path& root) {
  std::map<std::string, std::string> h;
  if (!fs::exists(root)) return h;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) h[fs::relative(e.path(), root).generic_string()] = io::hash_file(e.path().string());
  return h;
}

bool same_bytes(const fs::path& a, const fs::path& b) {
  if (fs::file_size(a) != fs::file_size(b)) return false;
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  return std::equal(std::istreambuf_iterator<char>(fa), std::istreambuf_iterator<char>(),
                    std::istreambuf_iterator<char>(fb), std::istreambuf_iterator<char>());
}

void replace_file(const fs::path& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  const fs::path tmp = to.string() + ".rebuild.tmp";
  fs::copy_file(from, tmp, fs::copy_options::overwrite_existing);
  fs::rename(tmp, to);
}

std::vector<int> parse_select(const std::string& s) {
  std::vector<int> steps;
  if (s == "all" || s == "auto") return steps;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (*end != '\0' || v < 0) throw UsageError("--select expects model steps like 0,3,5 (or 'all'), got '" + item + "'");
    steps.push_back(int(v));
  }
  if (steps.empty()) throw UsageError("--select: no steps given");
  std::sort(steps.begin(), steps.end());
  steps.erase(std::unique(steps.begin(), steps.end()), steps.end());
  return steps;
}

}  // namespace

int cmd_rebuild(ArgParser& args) {
  args.usage("DIR --building ID [--set NAME=VALUE,...] [--select STEPS]")
      .describe(
          "Change one building of a 'citylod tile' output directory (DIR/work, DIR/tileset)\n"
          "and update the tileset. --set recomputes the building's LOD-Tree with these\n"
          "parameter overrides; --select pins which of its candidate models are shown\n"
          "(steps as listed in DIR/work/lod/<ID>/report.json, e.g. 0,4,9; 'all' = automatic\n"
          "choice again). Both are kept in DIR/work/overrides.json for later runs. Without\n"
          "either, the building is recomputed. Prints the tileset files that changed.");
  args.option("building", 'b', "ID", "the building to change (id from the manifest / run_report.json)");
  args.option("set", 's', "NAME=VALUE[,...]", "parameter overrides for this building (merged with earlier ones)");
  args.flag("reset", 0, "drop this building's earlier parameter overrides first");
  args.option("select", 0, "STEPS", "comma-separated model steps to show, or 'all'");
  args.option("threads", 't', "N", "assemble threads (0 = all cores); the output does not depend on it", "0");
  args.positional("DIR", "output directory of 'citylod tile'", Arity::one);
  if (!args.parse()) return 0;
  if (!args.has("building")) throw UsageError("--building ID is required");
  const auto threads = args.get_int("threads");
  if (threads < 0) throw UsageError("--threads must be >= 0");

  const fs::path dir = args.positionals()[0];
  const std::string id = args.get("building");
  const std::string work = (dir / "work").string();
  const fs::path tileset = dir / "tileset";
  const fs::path run_report_path = dir / "run_report.json";
  nlohmann::json run;
  {
    std::ifstream f(run_report_path);
    if (!f) throw std::runtime_error(run_report_path.string() + ": not found (DIR must be a 'citylod tile' output)");
    try {
      f >> run;
    } catch (const std::exception& e) {
      throw std::runtime_error(run_report_path.string() + ": not valid JSON (" + e.what() + ")");
    }
  }
  lod::LodParams global = city_lod_params();  // a run report of an older version may lack newer names
  const nlohmann::json lod_params = run.value("lod_params", nlohmann::json::object());
  for (const auto& [k, v] : lod_params.items())
    global.set(k, v.is_string() ? v.get<std::string>() : v.dump());
  AssembleParams ap = assemble_params_from_json(run.value("assemble_params", nlohmann::json::object()));
  ap.threads = int(threads);

  const io::Manifest m = io::read_manifest(work);
  const io::ChunkRecord* rec = nullptr;
  for (const auto& c : m.chunks)
    if (c.id == id) rec = &c;
  if (!rec) throw std::runtime_error(io::manifest_path(work) + ": no building '" + id + "'");
  if (rec->status == "skipped")
    throw std::runtime_error("building '" + id + "' was skipped by split (" + rec->reason + "); nothing to rebuild");

  const Overrides old = read_overrides(work);
  Overrides ov = old;
  const std::string report = (fs::path(io::lod_dir(work, id)) / "report.json").string();
  BuildingOverride& bo = ov[id];
  const bool recompute = args.has("set") || args.has("reset") || !args.has("select");
  if (args.has("reset")) bo.set.clear();
  if (args.has("set")) {
    lod::LodParams probe;  // validates names and values
    apply_lod_settings(probe, args.get("set"));
    std::stringstream ss(args.get("set"));
    std::string item;
    while (std::getline(ss, item, ',')) {
      const auto eq = item.find('=');
      if (eq != std::string::npos) bo.set[item.substr(0, eq)] = item.substr(eq + 1);
    }
    try {
      params_for(global, ov, id).validate();
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    if (!args.has("select") && !bo.select.empty()) {
      log_info("rebuild: " + id + ": its model selection was dropped (the models change with the parameters)");
      bo.select.clear();
    }
  }
  if (args.has("select")) bo.select = parse_select(args.get("select"));

  const std::string report_before = fs::exists(report) ? io::hash_file(report) : "";
  write_overrides(work, ov);

  if (recompute) {
    // The LOD stage forks (supervise): no OpenMP in this process before it.
    const int rc = supervise(work, [&]() {
      run_city_lod(work, global, 1, id);
      return 0;
    });
    if (rc != 0) throw std::runtime_error(work + ": the LOD stage failed for '" + id + "' (exit " + std::to_string(rc) + ")");
  }
  for (const auto& w : apply_model_selections(work, ov)) {
    if (w.rfind(id + ":", 0) == 0 && args.has("select")) {
      // A selection that does not fit this building's models is not kept.
      bo.select = old.count(id) ? old.at(id).select : std::vector<int>{};
      write_overrides(work, ov);
      apply_model_selections(work, ov);
      throw std::runtime_error(id + ": --select " + args.get("select") +
                               ": these steps are not among its models or include no anchor (see " + report + ")");
    }
    log_warn(w);
  }
  const std::string report_after = fs::exists(report) ? io::hash_file(report) : "";
  log_info("rebuild: " + report + (report_before == report_after ? " unchanged" : " changed"));

  // Assemble into a staging dir, then replace only the files whose bytes differ.
  const fs::path stage = dir / ".tileset.rebuild";
  fs::remove_all(stage);
  AssembleStats st;
  {
    Progress prog("assemble");
    st = assemble(work, stage.string(), ap, [&](double f, const char* s) { prog.update(f, s); });
    prog.finish();
  }
  for (const auto& w : st.warnings) log_warn(w);
  const auto before = hash_tree(tileset), after = hash_tree(stage);
  std::vector<std::string> changed, added, removed;
  for (const auto& [rel, h] : after) {
    auto it = before.find(rel);
    if (it == before.end()) added.push_back(rel);
    else if (it->second != h || !same_bytes(stage / rel, tileset / rel)) changed.push_back(rel);
  }
  for (const auto& [rel, h] : before)
    if (!after.count(rel)) removed.push_back(rel);
  auto is_root = [](const std::string& r) { return r == "tileset.json"; };
  for (const auto* list : {&changed, &added})
    for (const auto& rel : *list)
      if (!is_root(rel)) replace_file(stage / rel, tileset / rel);
  for (const auto* list : {&changed, &added})
    for (const auto& rel : *list)
      if (is_root(rel)) replace_file(stage / rel, tileset / rel);
  for (const auto& rel : removed) fs::remove(tileset / rel);
  fs::remove_all(stage);

  // Keep the run report in step.
  run["buildings"] = building_records(work, ov);
  run["last_rebuild"] = {{"building", id}, {"set", bo.set}, {"select", bo.select},
                         {"report_changed", report_before != report_after},
                         {"changed", changed}, {"added", added}, {"removed", removed}};
  io::atomic_write_file(run_report_path.string(), run.dump(2) + "\n");

  std::printf("rebuild %s: %zu tileset files changed, %zu added, %zu removed\n", id.c_str(), changed.size(),
              added.size(), removed.size());
  for (const auto& r : changed) std::printf("changed %s\n", r.c_str());
  for (const auto& r : added) std::printf("added %s\n", r.c_str());
  for (const auto& r : removed) std::printf("removed %s\n", r.c_str());
  return 0;
}

}  // namespace citylod::tiler
