// Private to tiler/: the command-line options of the three stages of a city
// run, declared and parsed in one place so that `citylod split`, `lod`,
// `assemble` and the one-command `citylod tile` share them.
//
//   declare_split_options(args);     // --crs, --origin, --footprints, --memory-limit, ...
//   declare_lod_param_options(args); // --set, --config
//   declare_assemble_options(args);  // --quantize, --max-triangles, ...
//   if (!args.parse()) return 0;
//   SplitOptions s = parse_split_options(args, inputs, work);  // force left to the caller
//   lod::LodParams p = parse_lod_params(args);        // --config then --set
//   AssembleParams a = parse_assemble_options(args);  // threads/force left to the caller
//
// Bad values throw UsageError (exit 2) naming the option.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "assemble.hpp"
#include "cli_common.hpp"
#include "split.hpp"

#include "citylod/lod/params.hpp"

#include <nlohmann/json.hpp>

namespace citylod::tiler {

/// Everything of `citylod split` except --out and --force.
void declare_split_options(ArgParser& args);
/// Fills and validates a SplitOptions (force is left to the caller).
SplitOptions parse_split_options(const ArgParser& args, const std::vector<std::string>& inputs,
                                 const std::string& work_dir);

/// --set NAME=VALUE[,...] and --config FILE.
void declare_lod_param_options(ArgParser& args);
/// `base` + --config + --set (not validated: the caller sets threads etc. first).
lod::LodParams parse_lod_params(const ArgParser& args, lod::LodParams base = {});
/// The paper's defaults, except what a city run needs: its chunks hold no
/// ground, and a low plane reaching a chunk's edge (a courtyard, a plaza) is
/// not terrain to keep as a plinth (closure.terrain = cut); every chunk has a
/// footprint, whose walls close what airborne LiDAR scanned in part
/// (closure.footprint_walls).
lod::LodParams city_lod_params();
/// Applies "name=value[,name=value...]"; throws UsageError.
void apply_lod_settings(lod::LodParams& p, const std::string& list);
/// Applies a JSON object {"planes.epsilon": 0.2, ...}; throws std::runtime_error.
void apply_lod_config(lod::LodParams& p, const std::string& path);

/// Everything of `citylod assemble` except --out, --threads and --force.
void declare_assemble_options(ArgParser& args);
/// Fills an AssembleParams (not threads, force) and validates it.
AssembleParams parse_assemble_options(const ArgParser& args);

// ------------------------------------------------------------ city runs (tile / rebuild)

/// Per-building choices made with `citylod rebuild`, persisted in WORK/overrides.json:
/// {"buildings": {"<id>": {"set": {"planes.epsilon": "0.2"}, "select": [0, 3]}}}.
struct BuildingOverride {
  std::map<std::string, std::string> set;  ///< LOD parameter overrides
  std::vector<int> select;                 ///< model steps shown (empty = assemble chooses)
};
using Overrides = std::map<std::string, BuildingOverride>;

std::string overrides_path(const std::string& work_dir);
Overrides read_overrides(const std::string& work_dir);  ///< empty when absent
void write_overrides(const std::string& work_dir, const Overrides& o);  ///< atomic

/// The global parameters with the building's overrides applied.
lod::LodParams params_for(const lod::LodParams& global, const Overrides& o, const std::string& id);

/// Summary of one LOD stage of a city run (all buildings of the work dir).
struct CityLodReport {
  std::size_t total = 0, computed = 0, reused = 0;
  double seconds = 0;
};

/// The LOD stage of a city run, honouring the per-building overrides: every
/// non-skipped building whose report.json key matches its parameters is
/// reused; the others go through run_lod_stage() (`only` = those ids, one call
/// per distinct parameter set). `force_id` (if not empty) is recomputed even
/// when up to date. Logs "lod: N buildings (X computed, Y reused) ...".
/// Runs OpenMP: call it inside supervise().
CityLodReport run_city_lod(const std::string& work_dir, const lod::LodParams& global, int threads,
                           const std::string& force_id = "");

/// Pins the model selections of the overrides in WORK/lod/<id>/report.json:
/// "models" keeps only the selected steps, the full list is kept in
/// "models_all" (restored when the selection is cleared). Assemble then only
/// sees the selected models. Returns warnings (selection ignored: no anchor,
/// unknown steps). Files are rewritten only when their content changes.
std::vector<std::string> apply_model_selections(const std::string& work_dir, const Overrides& overrides);

/// One JSON record per manifest building: id, status, reason, models, overrides.
nlohmann::json building_records(const std::string& work_dir, const Overrides& overrides);

/// The assemble parameters as JSON and back (run_report.json "assemble_params").
nlohmann::json assemble_params_json(const AssembleParams& p);
AssembleParams assemble_params_from_json(const nlohmann::json& j);

}  // namespace citylod::tiler
