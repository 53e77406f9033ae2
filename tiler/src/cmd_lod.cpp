// `citylod lod INPUT --out DIR`: the LOD-Tree of one building (paper Section 4).
#include "cli_common.hpp"
#include "lod_io.hpp"
#include "lod_stage.hpp"
#include "stage_options.hpp"
#include "supervise.hpp"

#include "citylod/lod/lod.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace citylod::tiler {

namespace {

void print_stage_progress(std::size_t done, std::size_t total, void* self) {
  static_cast<Progress*>(self)->update(double(done) / double(std::max<std::size_t>(1, total)), "buildings");
}

int run_work_dir(ArgParser& args, const std::string& work, lod::LodParams params) {
  LodStageOptions o;
  o.work_dir = work;
  o.threads = std::max(1, int(params.threads));
  o.params = params;
  if (args.has("shard")) {
    try {
      parse_shard(args.get("shard"), o.shard_index, o.shard_count);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }
  if (args.has("building")) o.only = {args.get("building")};
  return supervise(work, [&]() {
    Progress progress("lod");
    const LodStageReport r = run_lod_stage(o, &print_stage_progress, &progress);
    progress.finish();
    std::ostringstream msg;
    msg << "lod: " << r.total << " buildings (" << r.computed << " computed, " << r.reused
        << " reused): " << r.ok << " ok, " << r.fallback << " fallback, " << r.failed << " failed in "
        << r.seconds << " s";
    log_info(msg.str());
    for (const auto& [id, why] : r.problems) log_warn("lod: " + id + ": " + why);
    return 0;
  });
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
  args.option("shard", 0, "I/N", "work directory: process only shard I of N (0-based), e.g. for Slurm arrays");
  args.option("building", 'b', "ID", "work directory: recompute only this building");
  declare_lod_param_options(args);
  args.option("threads", 't', "N", "threads (single building: inside it; work directory: buildings at once)", "1");
  args.flag("dump-planes", 0, "write planes.ply: plane inliers coloured by level set");
  args.flag("baseline", 0, "also build the plain BSP-Tree (area order, binary) and report its cuts");
  args.flag("print-params", 0, "print every parameter with its value and exit");
  args.positional("INPUT", "building: PLY/OBJ/OFF/XYZ/LAS", Arity::optional_one);
  if (!args.parse()) return 0;

  const bool work_dir = !args.positionals().empty() && std::filesystem::is_directory(args.positionals()[0]);
  lod::LodParams params = parse_lod_params(args, work_dir ? city_lod_params() : lod::LodParams{});
  params.threads = int(args.get_int("threads"));
  if (args.has("baseline")) params.bsp.baseline = true;
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (args.has("print-params")) {
    for (const auto& [k, v] : params.items()) std::printf("%s = %s\n", k.c_str(), v.c_str());
    return 0;
  }
  if (args.positionals().empty()) throw UsageError("missing INPUT");
  const std::string input = args.positionals()[0];
  if (work_dir) return run_work_dir(args, input, params);
  if (!args.has("out")) throw UsageError("missing --out DIR");
  const std::string out = args.get("out");

  LoadedBuilding b = load_building(input);
  log_info("lod: " + input + ": " + std::to_string(b.input.points.size()) +
           (b.is_mesh ? " vertices, " + std::to_string(b.input.triangles.size()) + " triangles"
                      : std::string(" points") + (b.input.normals.empty() ? " (no normals)" : " with normals")));
  Progress progress("lod");
  lod::LodResult r;
  try {
    r = lod::build_lod_tree(b.input, params, &Progress::callback, &progress);
  } catch (const lod::LodError& e) {
    throw std::runtime_error(input + ": " + e.what());
  }
  progress.finish();
  const auto files = write_lod_output(out, r, params, input, b.origin, args.has("dump-planes"));
  int anchors = 0, interps = 0;
  const lod::LodModel* finest = nullptr;  // the last anchor
  for (const auto& m : r.models) {
    anchors += m.kind == lod::ModelKind::Anchor;
    interps += m.kind == lod::ModelKind::Interpolation;
    if (m.kind == lod::ModelKind::Anchor) finest = &m;
  }
  const auto& s = r.stats;
  std::ostringstream msg;
  msg << "lod: " << (r.status == "ok" ? "" : "FALLBACK (" + r.reason + "): ") << anchors << " anchor + "
      << interps << " interpolation models; P=" << s.planes_detected << " S=" << s.planes_sorted
      << " level sets=" << s.level_sets << "; T1=" << s.t_ioview << "s T2=" << s.t_tree
      << "s T3=" << s.t_traversal << "s; written to " << out;
  log_info(msg.str());
  if (finest) {
    char line[200];
    std::snprintf(line, sizeof line, "lod: finest model: %zu triangles, volume %.1f m3, e1 %.3f %%, e2 %.3f %% of the bbox diagonal",
                  finest->mesh.triangles.size(), finest->volume, finest->e1, finest->e2);
    log_info(line);
  }
  for (const auto& n : s.notes) log_info("lod: note: " + n);
  return 0;
}

}  // namespace citylod::tiler
