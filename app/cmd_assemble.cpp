// `citylod assemble WORK --out TILESET_DIR`: per-building LOD models -> 3D Tiles 1.1.
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "citylod/tiler/assemble.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

int cmd_assemble(ArgParser& args) {
  args.usage("WORK --out TILESET_DIR")
      .describe(
          "Turn the LOD models of every building of a work directory (WORK/manifest.json,\n"
          "WORK/lod/<id>/report.json and model PLYs) into a hierarchical 3D Tiles 1.1\n"
          "tileset: coarse anchor models of many buildings near the root, finer\n"
          "interpolation and anchor models of fewer buildings below (refine REPLACE).\n"
          "Writes TILESET_DIR/tileset.json, tiles/*.glb, buildings/*.glb (every kept model\n"
          "of a building, for the viewer's LOD slider) and buildings.json. The output is\n"
          "staged in TILESET_DIR.partial and swapped in when complete. See docs/3dtiles.md.");
  args.option("out", 'o', "DIR", "output tileset directory");
  declare_assemble_options(args);
  args.flag("force", 0, "replace TILESET_DIR even if it is not a citylod tileset");
  declare_threads_option(args, "threads");
  args.positional("WORK", "work directory (manifest.json, lod/<id>/)", Arity::one);
  if (!args.parse()) return 0;
  if (!args.has("out")) throw UsageError("missing --out TILESET_DIR");

  AssembleParams p = parse_assemble_options(args);
  p.force = args.has("force");
  p.threads = parse_threads(args);

  const std::string work = args.positionals().at(0);
  const std::string out = args.get("out");
  ProgressDisplay bars;
  const AssembleStats st = assemble(work, out, p, bars.fn());
  bars.finish();
  for (const auto& w : st.warnings) log_warn(w);
  std::ostringstream s;
  s << "wrote " << out << "/tileset.json: " << st.buildings << " buildings (" << st.models_kept
    << " of " << st.models_read << " models kept";
  if (st.skipped) s << ", " << st.skipped << " skipped";
  s << "), " << st.tiles << " tiles (" << st.content_tiles << " glb, depth " << st.depth << "), "
    << human_count(double(st.glb_bytes)) << "B of tiles (largest "
    << human_count(double(st.max_glb_bytes)) << "B, " << human_count(double(st.max_tile_triangles))
    << " triangles), root error " << std::fixed << std::setprecision(2) << st.root_error_m << " m, "
    << std::setprecision(1) << st.seconds_read + st.seconds_write << " s";
  log_info(s.str());
  return 0;
}

}  // namespace citylod::app
