// `citylod split INPUT... --out WORK`: parse, call split_scene(), report.
#include <cstdio>
#include <stdexcept>

#include "cli_common.hpp"
#include "split.hpp"

namespace citylod::tiler {

int cmd_split(ArgParser& args) {
  const SplitOptions d;
  auto num = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return std::string(b);
  };
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
          "Buildings come from --footprints (GeoJSON polygons) or from clustering the points above "
          "the\n"
          "ground (LAS class 6 when present; trees rejected by class or by PCA features).\n"
          "Re-running with the same inputs and options does nothing.")
      .option("out", 'o', "WORK", "work directory (created)")
      .option("crs", 0, "CRS",
              "CRS of the input: EPSG:nnnn, WKT or PROJ string (default: from the LAS file)")
      .option("origin", 0, "LAT,LON,H",
              "data in local ENU metres at this origin (degrees, ellipsoidal m)")
      .option("geoid", 0, "MODEL", "input heights are orthometric on MODEL (egm96)")
      .option("footprints", 0, "FILE",
              "building footprints (GeoJSON Polygon/MultiPolygon with an id property)")
      .option("footprint-buffer", 0, "M", "points this close outside a footprint belong to it",
              num(d.footprint_buffer))
      .option("memory-limit", 'm', "SIZE", "memory budget, e.g. 512M, 2G", "2G")
      .option("cell-size", 0, "M", "grid cell size", num(d.cell_size))
      .option("halo", 0, "M", "margin loaded around each cell", num(d.halo))
      .option("max-halo", 0, "M", "halo growth limit for buildings larger than the halo",
              num(d.max_halo))
      .option("min-height", 0, "M", "building points lie this high above the ground",
              num(d.seg.min_height))
      .option("min-area", 0, "M2", "smaller clusters are not buildings", num(d.seg.min_area))
      .option("cluster-tolerance", 0, "M", "clustering distance", num(d.seg.cluster_tolerance))
      .option("dtm-window", 0, "M", "ground filter window (without a ground class)",
              num(d.seg.dtm_window))
      .flag("ignore-classes", 0, "segment as if the input had no LAS classes")
      .flag("force", 'f', "split again even if WORK is up to date")
      .positional("INPUT", "point cloud or mesh file(s) of one scene", Arity::one_or_more);
  if (!args.parse()) return 0;

  SplitOptions o;
  o.inputs = args.positionals();
  if (!args.has("out")) throw UsageError("--out WORK is required");
  o.work_dir = args.get("out");
  o.crs = args.get("crs");
  o.origin = args.get("origin");
  o.geoid = args.get("geoid");
  o.footprints = args.get("footprints");
  o.footprint_buffer = args.get_double("footprint-buffer");
  o.cell_size = args.get_double("cell-size");
  o.halo = args.get_double("halo");
  o.max_halo = std::max(args.get_double("max-halo"), o.halo);
  o.seg.min_height = args.get_double("min-height");
  o.seg.min_area = args.get_double("min-area");
  o.seg.cluster_tolerance = args.get_double("cluster-tolerance");
  o.seg.dtm_window = args.get_double("dtm-window");
  o.ignore_classes = args.has("ignore-classes");
  o.force = args.has("force");
  try {
    o.memory_limit = parse_memory_size(args.get("memory-limit"));
    o.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }

  Progress progress("split");
  SplitReport r;
  try {
    r = split_scene(o, [&progress](double f, const char* stage) {
      progress.update(f, stage);
      return true;
    });
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  progress.finish();
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
        "footprints: %zu in file, %zu meet the data, %zu got a chunk (%zu of %zu entirely inside)",
        r.footprints_total, r.footprints_in_scene, r.footprints_with_chunk,
        r.footprints_inside_with_chunk, r.footprints_inside);
    log_info(line);
  } else {
    std::string rej;
    for (const auto& [why, n] : r.rejected_by)
      rej += (rej.empty() ? "" : ", ") + std::to_string(n) + " " + why;
    log_info("clusters rejected: " + std::to_string(r.clusters_rejected) +
             (rej.empty() ? "" : " (" + rej + ")"));
  }
  std::snprintf(line, sizeof line, "origin lon %.8f lat %.8f h %.3f; manifest %s/manifest.json",
                r.origin_lon, r.origin_lat, r.origin_h, o.work_dir.c_str());
  log_info(line);
  return 0;
}

}  // namespace citylod::tiler
