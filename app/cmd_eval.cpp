// `citylod eval`: validity and fidelity of LOD models, in three forms:
//   eval MODEL... --ref INPUT     any triangle meshes (ours, QEM, City3D, ...) against one input
//   eval WORK                     every model of every building of a work directory vs its chunk
//   eval TILESET [--work WORK]    what a 3D Tiles tileset holds, per tile depth and building mesh
#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/tiler/eval.hpp"
#include "citylod/tiler/workdir.hpp"
#include "cli.hpp"
#include "eval_format.hpp"
#include "stage_options.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>

namespace citylod::app {

namespace fs = std::filesystem;

int cmd_eval(ArgParser& args) {
  args.usage("MODEL... --ref INPUT | WORK | TILESET [--work WORK]")
      .describe(
          "Validity and fidelity of LOD models: closed, edge-manifold, oriented, "
          "self-intersections,\n"
          "volume, e1 (model -> reference) and e2 (reference -> model) RMSE in % of the "
          "reference's\n"
          "bbox diagonal, Hausdorff distance (m, sampled). Three forms:\n"
          "\n"
          "  eval MODEL... --ref INPUT   triangle meshes (PLY/OBJ/OFF: ours, QEM, City3D, ...) "
          "against\n"
          "                              the input they represent.\n"
          "  eval WORK                   a work directory of 'citylod split' + 'lod' (or DIR/work "
          "of\n"
          "                              'citylod tile'): every model listed in "
          "lod/<id>/report.json\n"
          "                              against the building's chunk (chunks/<id>.ply); one row "
          "per\n"
          "                              model, then a summary: buildings, models, how many are "
          "closed /\n"
          "                              edge-manifold / self-intersecting, mean / median / max e1 "
          "and e2\n"
          "                              of each building's finest model (its last anchor), "
          "fallbacks\n"
          "                              with their reasons, buildings without LOD output.\n"
          "  eval TILESET                a tileset directory or tileset.json (DIR/tileset of "
          "'citylod\n"
          "                              tile'): every glb content, its triangles grouped per "
          "building\n"
          "                              (EXT_mesh_features feature id -> building_id), vertices "
          "welded\n"
          "                              by stored position; per level (tile depth, root = 0): "
          "tiles,\n"
          "                              buildings, triangles, closed / manifold / "
          "self-intersecting\n"
          "                              building meshes; one row per building mesh and level.\n"
          "                              With --work WORK (the work directory the tileset was "
          "assembled\n"
          "                              from) also e1/e2/Hausdorff of each mesh against the "
          "building's\n"
          "                              chunk: positions go through the node and tile transforms "
          "to\n"
          "                              ECEF, then to the manifest's scene frame and the chunk "
          "origin.\n"
          "\n"
          "Buildings are evaluated in parallel (--threads); the output does not depend on it.\n"
          "Text by default; --json prints JSON instead, --json-file FILE writes it as well.");
  args.option("ref", 'r', "INPUT",
              "MODEL form: reference point cloud or mesh (PLY/OBJ/OFF/XYZ/LAS)");
  args.option("work", 'w', "WORK",
              "TILESET form: work directory holding the buildings' chunks (enables e1/e2)");
  args.option("samples", 0, "N", "samples per surface for e1/e2", "20000");
  declare_threads_option(args, "WORK/TILESET forms: buildings evaluated at once");
  args.flag("json", 'j', "print JSON instead of text");
  args.option("json-file", 0, "FILE", "also write the JSON to FILE");
  args.positional("MODEL|WORK|TILESET", "model mesh file(s), a work directory, or a tileset",
                  Arity::one_or_more);
  if (!args.parse()) return 0;
  const int samples = int(args.get_int("samples"));
  if (samples < 1) throw UsageError("--samples must be >= 1");
  EvalOptions o;
  o.samples = samples;
  o.threads = parse_threads(args);
  const auto& pos = args.positionals();

  nlohmann::ordered_json json;
  std::string text;
  if (args.has("ref")) {
    if (args.has("work")) throw UsageError("--work is for the TILESET form, not with --ref");
    const auto models = evaluate_models(pos, args.get("ref"), samples);
    json = to_json(models);
    text = to_text(models);
  } else {
    const std::string p = pos.front();
    const std::string ext = "." + io::extension_of(p);
    enum { work, tileset } form;
    if (fs::is_directory(p)) {
      const bool has_manifest = fs::exists(tiler::manifest_path(p));
      const bool has_tileset = fs::exists(tiler::tileset_json_path(p));
      if (has_manifest)
        form = work;
      else if (has_tileset)
        form = tileset;
      else {
        std::string hint;
        if (fs::exists(tiler::manifest_path(tiler::run_work_dir(p))) ||
            fs::exists(tiler::tileset_json_path(tiler::run_tileset_dir(p))))
          hint = " (a 'citylod tile' output: give " + tiler::run_work_dir(p) + " or " +
                 tiler::run_tileset_dir(p) + ")";
        throw io::IoError(
            p,
            "neither a work directory (no manifest.json) nor a tileset (no tileset.json)" + hint);
      }
    } else if (ext == ".json") {
      form = tileset;
    } else if (ext == ".ply" || ext == ".obj" || ext == ".off") {
      throw UsageError("missing --ref INPUT (needed to evaluate model files)");
    } else if (!fs::exists(p)) {
      throw io::IoError(p, "no such file or directory");
    } else {
      throw UsageError("missing --ref INPUT (a model file), or give a work directory or a tileset");
    }
    if (pos.size() > 1)
      throw UsageError("a work directory or a tileset is evaluated alone (got " +
                       std::to_string(pos.size()) + " arguments)");
    if (form == work) {
      if (args.has("work"))
        throw UsageError("--work is for the TILESET form (" + p + " is a work directory)");
      ProgressDisplay bars;
      const WorkEval w = evaluate_work(p, o, bars.fn());
      bars.finish();
      json = to_json(w);
      text = to_text(w);
    } else {
      ProgressDisplay bars;
      const TilesetEval t =
          evaluate_tileset(p, args.has("work") ? args.get("work") : "", o, bars.fn());
      bars.finish();
      json = to_json(t);
      text = to_text(t);
    }
  }
  const std::string dumped = json.dump(2) + "\n";
  if (args.has("json-file")) io::atomic_write_file(args.get("json-file"), dumped);
  std::fputs(args.has("json") ? dumped.c_str() : text.c_str(), stdout);
  return 0;
}

}  // namespace citylod::app
