// `citylod split INPUT... --out WORK`: parse, call split_scene(), report.
#include <cstdio>
#include <stdexcept>

#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/split.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

int cmd_split(ArgParser& args) {
  args.usage("INPUT... --out WORK")
      .describe(
          "Streams a georeferenced scene (PLY/LAS/XYZ point clouds, or PLY/OBJ/OFF meshes) into "
          "one chunk per\n"
          "building: WORK/chunks/<id>.ply (binary, double xyz relative to the chunk origin, local "
          "ENU metres)\n"
          "and WORK/manifest.json. Memory is bounded by --memory-limit, not by the input size. "
          "Georeferencing:\n"
          "--crs, else the CRS inside the LAS file, or --origin for data already in a local metric "
          "frame.\n"
          "Buildings come from --footprints (any OGR source: GeoPackage, SQLite, Shapefile, "
          "GeoJSON,\n"
          "FlatGeobuf, PG:...) or from clustering the points above the ground (LAS class 6 when\n"
          "present; trees rejected by class or by PCA features). Heights follow the CRS\n"
          "(--vertical auto: RD New -> NAP); the tileset carries ellipsoidal heights.\n"
          "Re-running with the same inputs and options does nothing.")
      .option("out", 'o', "WORK", "work directory (created)");
  declare_split_options(args);
  declare_threads_option(args, "cells segmented at once");
  args.flag("force", 'f', "split again even if WORK is up to date")
      .positional("INPUT", "point cloud or mesh file(s) of one scene", Arity::one_or_more);
  if (!args.parse()) return 0;

  if (!args.has("out")) throw UsageError("--out WORK is required");
  SplitOptions o = parse_split_options(args, args.positionals(), args.get("out"));
  o.force = args.has("force");
  o.threads = parse_threads(args);

  ProgressDisplay bars;
  const tiler::DirLock lock(o.work_dir);  // one writer per work directory
  const SplitReport r = usage_errors([&] { return tiler::split_checked(o, bars.fn()); });
  bars.finish();
  if (r.up_to_date) {
    log_info("split: " + o.work_dir + " is up to date (" + std::to_string(r.chunks) + " chunks)");
    return 0;
  }
  for (const auto& n : r.notes) log_info("note: " + n);
  for (const auto& c : r.cluster_log) log_debug(c);
  char line[512];
  std::snprintf(line, sizeof line,
                "split: %s points -> %zu chunks in %.1f s (%s pts/s); cell %.0f m, %zu cells, %s",
                human_count(double(r.points)).c_str(), r.chunks, r.seconds,
                human_count(double(r.points) / std::max(r.seconds, 1e-9)).c_str(), r.cell_size,
                r.cells, r.class_mode.c_str());
  log_info(line);
  if (!o.footprints.empty()) {
    std::snprintf(
        line, sizeof line,
        "footprints: %zu in file, %zu meet the data, %zu got a chunk (%zu of the %zu entirely "
        "inside the data)",
        r.footprints_total, r.footprints_in_scene, r.footprints_with_chunk,
        r.footprints_inside_with_chunk, r.footprints_inside);
    log_info(line);
    if (r.footprints_repaired || r.footprints_skipped)
      log_info("footprints: " + std::to_string(r.footprints_repaired) + " repaired, " +
               std::to_string(r.footprints_skipped) + " skipped (see the notes)");
    if (r.unmatched_points >= 0)
      log_info("unmatched: " + std::to_string(r.unmatched_points) + " of " +
               std::to_string(r.building_points) + " building points outside every footprint" +
               (o.unmatched == SplitOptions::Unmatched::segment
                    ? " -> " + std::to_string(r.unmatched_chunks) + " buildings without footprint"
                    : std::string(" (dropped; --unmatched segment models them)")));
  } else {
    std::string rej;
    for (const auto& [why, n] : r.rejected_by)
      rej += (rej.empty() ? "" : ", ") + std::to_string(n) + " " + why;
    log_info("clusters rejected: " + std::to_string(r.clusters_rejected) +
             (rej.empty() ? "" : " (" + rej + ")"));
  }
  if (!r.vertical.empty()) log_info(r.vertical);
  std::snprintf(line, sizeof line, "origin lon %.8f lat %.8f h %.3f; manifest %s/manifest.json",
                r.origin_lon, r.origin_lat, r.origin_h, o.work_dir.c_str());
  log_info(line);
  return 0;
}

}  // namespace citylod::app
