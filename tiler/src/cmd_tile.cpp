// `citylod tile INPUT... --out DIR`: split -> lod -> assemble in one command.
//   DIR/work          the work directory (split chunks, lod/<id>/, overrides.json)
//   DIR/tileset       the 3D Tiles tileset
//   DIR/run_report.json  what happened (stages, per-building status, options)
// Resumable: split is skipped when up to date, finished buildings are reused
// (their report.json key), assemble always rewrites the tileset (deterministic).
// Fork-safety: the LOD stage runs in a supervised child (supervise.hpp); this
// process enters no OpenMP region before it (split uses none; assemble does and
// runs after).
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "assemble.hpp"
#include "cli_common.hpp"
#include "lod_stage.hpp"
#include "split.hpp"
#include "stage_options.hpp"
#include "supervise.hpp"

#include "citylod/io/atomic_file.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

long max_rss_kb(int who) {
  rusage u{};
  ::getrusage(who, &u);
  return u.ru_maxrss;  // KiB on Linux
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

}  // namespace

int cmd_tile(ArgParser& args) {
  args.usage("INPUT... --out DIR")
      .describe(
          "One-command city run: split the scene into buildings (DIR/work), build every\n"
          "building's LOD-Tree (in parallel, resumable, each building isolated: a crash or\n"
          "failure gives that building its fallback model and the reason) and assemble the\n"
          "3D Tiles tileset (DIR/tileset). Writes DIR/run_report.json. Re-running the same\n"
          "command resumes: an up-to-date split is kept and finished buildings are reused.\n"
          "Per-building changes: 'citylod rebuild DIR --building ID'.");
  args.option("out", 'o', "DIR", "output directory (work/, tileset/, run_report.json)");
  declare_split_options(args);
  declare_lod_param_options(args);
  args.option("threads", 't', "N", "buildings processed at once (LOD stage); also assemble's threads", "1");
  declare_assemble_options(args);
  args.flag("force", 'f', "split again even if DIR/work is up to date");
  args.positional("INPUT", "point cloud or mesh file(s) of one scene", Arity::one_or_more);
  if (!args.parse()) return 0;
  if (!args.has("out")) throw UsageError("--out DIR is required");

  const auto t_start = std::chrono::steady_clock::now();
  const std::string dir = args.get("out");
  const std::string work = (fs::path(dir) / "work").string();
  const std::string tileset = (fs::path(dir) / "tileset").string();
  SplitOptions so = parse_split_options(args, args.positionals(), work);
  so.force = args.has("force");
  lod::LodParams params = parse_lod_params(args, city_lod_params());
  const auto threads = args.get_int("threads");
  if (threads < 1) throw UsageError("--threads must be >= 1");
  params.threads = 1;
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  AssembleParams ap = parse_assemble_options(args);
  ap.threads = int(threads);
  fs::create_directories(dir);

  nlohmann::json report;
  report["command"] = "tile";
  report["inputs"] = so.inputs;
  report["threads"] = threads;

  // ---- split (no OpenMP in this process before the fork below)
  auto t0 = std::chrono::steady_clock::now();
  SplitReport sr;
  {
    Progress progress("split");
    try {
      sr = split_scene(so, [&progress](double f, const char* stage) {
        progress.update(f, stage);
        return true;
      });
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    progress.finish();
  }
  const double t_split = since(t0);
  for (const auto& n : sr.notes) log_info("note: " + n);
  log_info("split: " + (sr.up_to_date ? std::string("up to date, ") : std::string()) + std::to_string(sr.chunks) +
           " chunks in " + fmt("%.1f", t_split) + " s");
  report["stages"]["split"] = {{"seconds", t_split}, {"up_to_date", sr.up_to_date}, {"chunks", sr.chunks},
                               {"points", sr.points}, {"crs", sr.crs}};

  // ---- lod, in a supervised child
  t0 = std::chrono::steady_clock::now();
  const Overrides overrides = read_overrides(work);
  const std::string attempts = (fs::path(work) / ".tile_lod_attempts.jsonl").string();
  fs::remove(attempts);
  const int rc = supervise(work, [&]() {
    const CityLodReport r = run_city_lod(work, params, int(threads));
    std::ofstream f(attempts, std::ios::app);
    f << nlohmann::json{{"total", r.total}, {"computed", r.computed}, {"reused", r.reused}}.dump() << "\n";
    return f ? 0 : 1;
  });
  const double t_lod = since(t0);
  if (rc != 0) throw std::runtime_error(work + ": the LOD stage failed (exit " + std::to_string(rc) + ")");
  std::size_t total = 0, reused = 0, computed = 0, n_attempts = 0;
  {
    std::ifstream f(attempts);
    std::string line;
    while (std::getline(f, line)) {
      const auto j = nlohmann::json::parse(line);
      total = j.value("total", std::size_t(0));
      if (n_attempts++ == 0) reused = j.value("reused", std::size_t(0));
    }
    computed = total - reused;  // each building finished in exactly one attempt (or was reused)
  }
  fs::remove(attempts);
  const std::vector<std::string> sel_warnings = apply_model_selections(work, overrides);
  for (const auto& w : sel_warnings) log_warn(w);
  report["stages"]["lod"] = {{"seconds", t_lod},  {"buildings", total},          {"computed", computed},
                             {"reused", reused},  {"restarts", n_attempts ? n_attempts - 1 : 0}};

  // ---- assemble (OpenMP: after the fork)
  t0 = std::chrono::steady_clock::now();
  AssembleStats st;
  {
    Progress prog("assemble");
    st = assemble(work, tileset, ap, [&](double f, const char* stage) { prog.update(f, stage); });
    prog.finish();
  }
  const double t_asm = since(t0);
  for (const auto& w : st.warnings) log_warn(w);
  report["stages"]["assemble"] = {{"seconds", t_asm},        {"buildings", st.buildings},
                                  {"tiles", st.tiles},        {"glb_bytes", st.glb_bytes},
                                  {"models_kept", st.models_kept}, {"depth", st.depth},
                                  {"warnings", st.warnings}};

  // ---- summary + run report
  const nlohmann::json buildings = building_records(work, overrides);
  std::size_t ok = 0, fallback = 0, failed = 0, skipped = 0;
  std::vector<std::string> problems;
  for (const auto& b : buildings) {
    const std::string s = b["status"];
    if (s == "ok") ++ok;
    else if (s == "fallback") ++fallback;
    else if (s == "skipped") ++skipped;
    else ++failed;
    if (s == "fallback" || s == "failed") problems.push_back(b["id"].get<std::string>() + " (" + s + "): " +
                                                             b.value("reason", std::string()));
  }
  const double t_total = since(t_start);
  const long rss_self = max_rss_kb(RUSAGE_SELF), rss_children = max_rss_kb(RUSAGE_CHILDREN);
  report["summary"] = {{"ok", ok}, {"fallback", fallback}, {"failed", failed}, {"skipped", skipped}};
  report["seconds_total"] = t_total;
  report["peak_rss_bytes"] = {{"self", std::uint64_t(rss_self) * 1024}, {"children", std::uint64_t(rss_children) * 1024}};
  nlohmann::json lp = nlohmann::json::object();
  for (const auto& [k, v] : params.items())
    if (k != "threads") lp[k] = v;
  report["lod_params"] = lp;
  report["assemble_params"] = assemble_params_json(ap);
  report["work"] = "work";
  report["tileset"] = "tileset";
  report["buildings"] = buildings;
  io::atomic_write_file((fs::path(dir) / "run_report.json").string(), report.dump(2) + "\n");

  log_info("tile: " + std::to_string(buildings.size()) + " buildings: " + std::to_string(ok) + " ok, " +
           std::to_string(fallback) + " fallback, " + std::to_string(failed) + " failed" +
           (skipped ? ", " + std::to_string(skipped) + " skipped by split" : std::string()) + "; lod " +
           std::to_string(computed) + " computed, " + std::to_string(reused) + " reused");
  for (const auto& p : problems) log_info("  " + p);
  log_info("tile: time split " + fmt("%.1f", t_split) + " s, lod " + fmt("%.1f", t_lod) + " s, assemble " +
           fmt("%.1f", t_asm) + " s, total " + fmt("%.1f", t_total) + " s; peak memory " +
           fmt("%.0f", double(rss_self) / 1024) + " MiB (this process), " + fmt("%.0f", double(rss_children) / 1024) +
           " MiB (LOD stage)");
  log_info("tile: wrote " + tileset + "/tileset.json (" + std::to_string(st.tiles) + " tiles) and " + dir +
           "/run_report.json");
  return 0;
}

}  // namespace citylod::tiler
