// `citylod rebuild DIR --building ID [--set P=V,...] [--select STEPS]`: change one
// building of a `citylod tile` output and update the tileset (tiler::rebuild).
#include <cstdio>

#include "citylod/tiler/city_run.hpp"
#include "cli.hpp"
#include "stage_options.hpp"

namespace citylod::app {

int cmd_rebuild(ArgParser& args) {
  args.usage("DIR --building ID [--set NAME=VALUE,...] [--select STEPS]")
      .describe(
          "Change one building of a 'citylod tile' output directory (DIR/work, DIR/tileset)\n"
          "and update the tileset. --set recomputes the building's LOD-Tree with these\n"
          "parameter overrides; --select pins which of its candidate models are shown\n"
          "(steps as listed in DIR/work/lod/<ID>/report.json, e.g. 0,4,9; 'all' = automatic\n"
          "choice again). Both are kept in DIR/work/overrides.json for later runs. Without\n"
          "either, the building is recomputed. Prints the tileset files that changed.");
  args.option("building", 'b', "ID",
              "the building to change (id from the manifest / run_report.json)");
  args.option("set", 's', "NAME=VALUE[,...]",
              "parameter overrides for this building (merged with earlier ones)");
  args.flag("reset", 0, "drop this building's earlier parameter overrides first");
  args.option("select", 0, "STEPS", "comma-separated model steps to show, or 'all'");
  declare_threads_option(args, "assemble's threads");
  args.positional("DIR", "output directory of 'citylod tile'", Arity::one);
  if (!args.parse()) return 0;
  if (!args.has("building")) throw UsageError("--building ID is required");

  tiler::RebuildOptions o;
  o.dir = args.positionals()[0];
  o.building = args.get("building");
  if (args.has("set")) o.set = args.get("set");
  o.reset = args.has("reset");
  if (args.has("select")) o.select = args.get("select");
  o.threads = parse_threads(args);

  ProgressDisplay bars;
  const tiler::RebuildResult r = usage_errors([&] { return tiler::rebuild(o, bars.fn()); });
  bars.finish();
  std::printf("rebuild %s: %zu tileset files changed, %zu added, %zu removed\n", o.building.c_str(),
              r.changed.size(), r.added.size(), r.removed.size());
  for (const auto& f : r.changed) std::printf("changed %s\n", f.c_str());
  for (const auto& f : r.added) std::printf("added %s\n", f.c_str());
  for (const auto& f : r.removed) std::printf("removed %s\n", f.c_str());
  return 0;
}

}  // namespace citylod::app
