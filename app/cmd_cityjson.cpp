// `citylod cityjson WORK --out FILE`: every building's LOD chain as CityJSON 2.0 (CityJSONSeq).
#include <string>

#include "citylod/tiler/cityjson.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

int cmd_cityjson(ArgParser& args) {
  args.usage("WORK --out FILE")
      .describe(
          "Write the buildings of a work directory as a CityJSON 2.0 text sequence\n"
          "(CityJSONSeq, one CityJSONFeature per line): one Building per building, its\n"
          "geometries the kept LOD models coarse to fine (the chain the tileset shows), each\n"
          "a Solid with RoofSurface / WallSurface / GroundSurface semantics and a 'lod', in\n"
          "the input's CRS; per-model quality (kind, level, step, RMSE, validity) in the\n"
          "attribute citylod_models. `citylod tile` writes DIR/buildings.city.jsonl itself.\n"
          "See docs/cityjson.md.");
  args.option("out", 'o', "FILE", "output file (conventionally *.city.jsonl)");
  args.option("scale", 0, "S", "transform scale: one vertex integer step, CRS units", "0.0001");
  args.option("min-change", 0, "M", "as assemble: the kept chain's interpolation threshold", "0.1");
  args.option("hausdorff-tolerance", 0, "M", "as assemble: accuracy of the Hausdorff distances",
              "0.1");
  args.flag("all-models", 0, "every model of report.json instead of the kept chain");
  args.flag("skip-missing", 0, "skip buildings without LOD models (warning) instead of failing");
  declare_threads_option(args, "threads");
  args.positional("WORK", "work directory (manifest.json, lod/<id>/)", Arity::one);
  if (!args.parse()) return 0;
  if (!args.has("out")) throw UsageError("missing --out FILE");

  tiler::CityJsonOptions o;
  o.scale = args.get_double("scale");
  o.min_change_m = args.get_double("min-change");
  o.hausdorff_tolerance_m = args.get_double("hausdorff-tolerance");
  o.all_models = args.has("all-models");
  o.skip_missing = args.has("skip-missing");
  o.threads = parse_threads(args);
  usage_errors([&] { o.validate(); });

  ProgressDisplay bars;
  const tiler::CityJsonStats st =
      tiler::write_cityjson(args.positionals().at(0), args.get("out"), o, bars.fn());
  bars.finish();
  for (const auto& w : st.warnings) log_warn(w);
  log_info(
      "wrote " + args.get("out") + ": " + std::to_string(st.buildings) + " buildings, " +
      std::to_string(st.geometries) + " solids (" + std::to_string(st.chain_objects) +
      " of them chain models beyond LoD 1.2/1.3/2.2; " + std::to_string(st.invalid) +
      " models left out as invalid), " + std::to_string(st.multi_lod) + " with >= 2 LODs, " +
      std::to_string(st.full_semantics) + " with roof/wall/ground on every solid" +
      (st.coloured ? ", " + std::to_string(st.coloured) + " with the input's colours"
                   : std::string()) +
      (st.skipped ? ", " + std::to_string(st.skipped) + " skipped" : std::string()) + "; " +
      (st.reference_system.empty() ? std::string("no reference system") : st.reference_system) +
      "; " + strf("%.1f", st.seconds) + " s");
  return 0;
}

}  // namespace citylod::app
