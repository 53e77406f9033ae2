// `citylod lod INPUT --out DIR`: the LOD-Tree of one building (paper Section 4),
// or `citylod lod WORK`: every building of a work directory (tiler::build_building_lod,
// tiler::run_lod_supervised).
#include <cstdio>
#include <filesystem>

#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/threads.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

namespace {

/// What `citylod lod` made, in words.
void print_summary(const tiler::BuildingLodResult& out, const std::string& dir) {
  const lod::LodResult& r = out.result;
  int anchors = 0, interps = 0;
  const lod::LodModel* finest = nullptr;  // the last anchor
  for (const auto& m : r.models) {
    anchors += m.kind == lod::ModelKind::anchor;
    interps += m.kind == lod::ModelKind::interpolation;
    if (m.kind == lod::ModelKind::anchor) finest = &m;
  }
  const auto& s = r.stats;
  std::string head = "lod: ";
  if (r.status != lod::Status::ok) head += "FALLBACK (" + r.reason + "): ";
  log_info(head + std::to_string(r.models.size()) + " models (" + std::to_string(anchors) +
           " anchor" + (anchors == 1 ? "" : "s") + " = finished levels of detail, " +
           std::to_string(interps) + " interpolation" + (interps == 1 ? "" : "s") +
           " between them) written to " + dir);
  if (s.planes_found > s.planes_detected)
    log_warn("lod: planes.max_planes cap: " + std::to_string(s.planes_found) + " planes found, " +
             std::to_string(s.planes_detected) + " kept (the smallest left out)");
  if (s.bsp_cap_hit)
    log_warn("lod: bsp.max_cells cap reached: the partition stopped part way (report.json notes)");
  log_info("lod: " + std::to_string(s.planes_detected) + " planes detected, " +
           std::to_string(s.planes_sorted) + " used in the tree, in " +
           std::to_string(s.level_sets) + " level" + (s.level_sets == 1 ? "" : "s") +
           " of detail; time: plane analysis " + strf("%.1f", s.t_ioview) + " s, tree " +
           strf("%.1f", s.t_tree) + " s, models " + strf("%.1f", s.t_traversal) + " s");
  if (finest) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "lod: finest model: %zu triangles, volume %.1f m3, e1 %.3f %%, e2 %.3f %% of the "
                  "bbox diagonal",
                  finest->mesh.triangles.size(), finest->volume, finest->e1, finest->e2);
    log_info(line);
  }
  for (const auto& n : s.notes) log_info("lod: note: " + n);
}

}  // namespace

int cmd_lod(ArgParser& args) {
  args.usage("INPUT | WORK")
      .describe(
          "Build the LOD-Tree of one building (a point cloud with or without normals, or a\n"
          "triangle mesh) and write its candidate LOD models (anchor and interpolation) as\n"
          "OBJ (merged polygons) and PLY (triangles) in the input frame, with report.json.\n"
          "Given a work directory made by 'citylod split', process all its buildings\n"
          "(in parallel, resumable, a fallback model for any building that fails).");
  args.option("out", 'o', "DIR", "output directory (single building)");
  args.option("shard", 0, "I/N",
              "work directory: process only shard I of N (0-based), e.g. for Slurm arrays");
  args.option("building", 'b', "ID", "work directory: recompute only this building");
  const lod::LodParams city = city_lod_params();
  declare_lod_param_options(args, lod::LodParams{}, &city);
  declare_threads_option(args,
                         "threads (single building: inside it; work directory: buildings at once)");
  args.flag("dump-planes", 0, "write planes.ply: plane inliers coloured by level set");
  args.flag("baseline", 0,
            "also build the plain BSP-Tree (area order, binary) and report its cuts");
  args.flag("print-params", 0, "print every parameter with its value and exit");
  args.positional("INPUT", "building: PLY/OBJ/OFF/XYZ/LAS", Arity::optional_one);
  if (!args.parse()) return 0;

  const bool work_dir =
      !args.positionals().empty() && std::filesystem::is_directory(args.positionals()[0]);
  lod::LodParams params = parse_lod_params(args, work_dir ? city_lod_params() : lod::LodParams{});
  const int threads = tiler::resolve_threads(parse_threads(args));
  if (args.has("baseline")) params.bsp.baseline = true;
  usage_errors([&] { params.validate(); });
  if (args.has("print-params")) {
    for (const auto& [k, v] : params.items()) std::printf("%s = %s\n", k.c_str(), v.c_str());
    return 0;
  }
  if (args.positionals().empty()) throw UsageError("missing INPUT");
  const std::string input = args.positionals()[0];

  ProgressDisplay bars;
  if (work_dir) {
    tiler::LodStageOptions o;
    o.work_dir = input;
    o.threads = threads;
    o.params = params;
    if (args.has("shard"))
      usage_errors([&] { parse_shard(args.get("shard"), o.shard_index, o.shard_count); });
    if (args.has("building")) o.only = {args.get("building")};
    tiler::run_lod_supervised(o, bars.fn());  // logs its summary
    return 0;
  }
  if (!args.has("out")) throw UsageError("missing --out DIR");
  tiler::BuildingLodOptions o;
  o.input = input;
  o.out_dir = args.get("out");
  o.params = params;
  o.threads = threads;
  o.dump_planes = args.has("dump-planes");
  const tiler::BuildingLodResult r = tiler::build_building_lod(o, bars.fn());
  bars.finish();
  print_summary(r, o.out_dir);
  return 0;
}

}  // namespace citylod::app
