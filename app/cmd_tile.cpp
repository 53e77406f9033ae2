// `citylod tile INPUT... --out DIR`: split -> lod -> assemble in one command
// (tiler::run_city, city_run.hpp).
#include <cstdio>

#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/workdir.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

int cmd_tile(ArgParser& args) {
  args.usage("INPUT... --out DIR")
      .describe(
          "One-command city run: split the scene into buildings (DIR/work), build every\n"
          "building's LOD-Tree (in parallel, resumable, each building isolated: a crash or\n"
          "failure gives that building its fallback model and the reason) and assemble the\n"
          "3D Tiles tileset (DIR/tileset), and DIR/buildings.city.jsonl (CityJSON 2.0, every\n"
          "building's chain). Writes DIR/run_report.json. Re-running the same\n"
          "command resumes: an up-to-date split is kept and finished buildings are reused.\n"
          "Per-building changes: 'citylod rebuild DIR --building ID'.");
  args.option("out", 'o', "DIR", "output directory (work/, tileset/, run_report.json)");
  declare_split_options(args);
  declare_lod_param_options(args, city_lod_params());
  declare_threads_option(args,
                         "cells segmented at once (split), buildings processed at once (LOD stage) "
                         "and assemble's threads");
  declare_assemble_options(args);
  args.flag("force", 'f', "split again even if DIR/work is up to date");
  args.flag("no-cityjson", 0,
            "do not write DIR/buildings.city.jsonl (CityJSON 2.0, docs/cityjson.md)");
  args.positional("INPUT", "point cloud or mesh file(s) of one scene", Arity::one_or_more);
  if (!args.parse()) return 0;
  if (!args.has("out")) throw UsageError("--out DIR is required");

  tiler::CityRunOptions o;
  o.out_dir = args.get("out");
  o.split = parse_split_options(args, args.positionals(),
                                tiler::run_work_dir(o.out_dir));  // run_city sets it too
  o.split.force = args.has("force");
  o.lod = parse_lod_params(args, city_lod_params());
  o.threads = parse_threads(args);
  o.assemble = parse_assemble_options(args);
  o.cityjson = !args.has("no-cityjson");

  ProgressDisplay bars;
  const tiler::CityRunResult r = usage_errors([&] { return tiler::run_city(o, bars.fn()); });
  bars.finish();

  const tiler::RunReport& rep = r.report;
  log_info(
      "tile: " + std::to_string(rep.buildings.size()) + " buildings: " + std::to_string(rep.ok) +
      " ok, " + std::to_string(rep.fallback) + " fallback, " + std::to_string(rep.failed) +
      " failed" +
      (rep.skipped ? ", " + std::to_string(rep.skipped) + " skipped by split" : std::string()) +
      "; lod " + std::to_string(rep.lod.computed) + " computed, " + std::to_string(rep.lod.reused) +
      " reused");
  for (const auto& p : r.problems) log_info("  " + p);
  if (!rep.split.vertical.empty()) log_info("tile: " + rep.split.vertical);
  if (rep.split.unmatched_points >= 0)
    log_info("tile: " + std::to_string(rep.split.unmatched_points) + " of " +
             std::to_string(rep.split.building_points) +
             " building points outside every footprint" +
             (o.split.unmatched == SplitOptions::Unmatched::segment
                  ? ": " + std::to_string(rep.split.unmatched_chunks) +
                        " buildings without footprint made of them"
                  : std::string(" (dropped; --unmatched segment models them)")));
  log_info("tile: time split " + strf("%.1f", rep.split.seconds) + " s, lod " +
           strf("%.1f", rep.lod.seconds) + " s, assemble " + strf("%.1f", rep.assemble.seconds) +
           " s, total " + strf("%.1f", rep.seconds_total) + " s; peak memory " +
           strf("%.0f", double(rep.peak_rss_self) / (1 << 20)) + " MiB (this process), " +
           strf("%.0f", double(rep.peak_rss_children) / (1 << 20)) + " MiB (LOD stage)");
  log_info("tile: wrote " + tiler::tileset_json_path(tiler::run_tileset_dir(o.out_dir)) + " (" +
           std::to_string(rep.assemble.tiles) + " tiles) and " + tiler::run_report_path(o.out_dir));
  if (o.cityjson)
    log_info("tile: wrote " + tiler::run_cityjson_path(o.out_dir) + " (" +
             std::to_string(r.cityjson.buildings) + " buildings, " +
             std::to_string(r.cityjson.geometries) + " solids, " +
             std::to_string(r.cityjson.invalid) + " models left out as invalid" +
             (r.cityjson.coloured
                  ? ", " + std::to_string(r.cityjson.coloured) + " with the input's colours"
                  : std::string()) +
             ")");
  return 0;
}

}  // namespace citylod::app
