// The city run as library calls: what `citylod tile`, `citylod lod WORK` and
// `citylod rebuild` do, with no argv and no terminal (progress through a
// ProgressFn, messages through the log sink, log.hpp).
//
//   CityRunOptions o;
//   o.out_dir = "out"; o.split.inputs = {"tile.las"}; o.split.crs = "EPSG:28992";
//   CityRunResult r = run_city(o);     // out/work, out/tileset, out/run_report.json
//   rebuild({"out", "fp-123", "planes.epsilon=0.2"});
//
// The LOD stage runs in a supervised child process (supervise.hpp); these may
// be called repeatedly in one process.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "citylod/lod/params.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/cityjson.hpp"
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/progress.hpp"
#include "citylod/tiler/split.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

// ------------------------------------------------------------ the LOD stage, supervised

/// Outcome of the LOD stage over the buildings it covers (a shard, or all).
struct CityLodSummary : StatusCounts {  ///< ok / fallback / failed
  std::size_t buildings = 0, computed = 0, reused = 0, restarts = 0;
  std::vector<std::pair<std::string, std::string>>
      problems;  ///< (id, reason), fallback/failed, id order
  double seconds = 0;
};

/// run_lod_stage() in a supervised child: a building that crashes the process
/// gets its fallback model, the others go on. Counts come from the plan made
/// before the fork and from the buildings' report.json afterwards. With
/// `o.only`, only those are recomputed and the others count as reused.
/// Throws std::runtime_error when the stage fails. Logs the summary.
CityLodSummary run_lod_supervised(const LodStageOptions& o, const ProgressFn& progress = {});

/// "lod: N buildings (X computed, Y reused): a ok, b fallback, c failed in S s".
std::string describe(const CityLodSummary& s);

// ------------------------------------------------------------ split, checked

/// split_scene() as `citylod split` and `tile` run it: never replaces a
/// WORK/chunks folder it did not make (require_own_chunks), and splits again
/// (force) when the work directory is up to date by its inputs and options
/// but a chunk is missing, truncated or changed (chunk_intact).
SplitReport split_checked(SplitOptions o, const ProgressFn& progress = {});

// ------------------------------------------------------------ tile

struct CityRunOptions {
  std::string out_dir;                     ///< DIR: DIR/work, DIR/tileset, DIR/run_report.json
  SplitOptions split;                      ///< inputs, CRS, ... (work_dir is set to DIR/work)
  lod::LodParams lod = city_lod_params();  ///< global LOD parameters (threads is ignored)
  AssembleParams assemble;                 ///< threads is set from `threads`
  int threads = 0;                         ///< 0 = all cores: buildings at once, assemble's threads
  bool cityjson = true;                    ///< also write DIR/buildings.city.jsonl (cityjson.hpp)
};

struct CityRunResult {
  RunReport report;  ///< as written to DIR/run_report.json
  SplitReport split;
  CityLodSummary lod;
  AssembleStats assemble;
  CityJsonStats cityjson;  ///< when CityRunOptions::cityjson
  /// "id (status): reason" of every fallback / failed building.
  std::vector<std::string> problems;
};

/// split -> LOD stage (supervised) -> model selections -> assemble -> run_report.json.
/// Resumable: an up-to-date split is kept and finished buildings are reused.
/// Throws std::invalid_argument for bad options, io::IoError / std::runtime_error otherwise.
CityRunResult run_city(const CityRunOptions& o, const ProgressFn& progress = {});

// ------------------------------------------------------------ rebuild

struct RebuildOptions {
  std::string dir;                    ///< a `citylod tile` output
  std::string building;               ///< id
  std::optional<std::string> set;     ///< "name=value,..." merged into the building's overrides
  bool reset = false;                 ///< drop its earlier parameter overrides first
  std::optional<std::string> select;  ///< model steps "0,3,5", or "all" / "auto" (automatic again)
  int threads = 0;                    ///< assemble's threads (0 = all cores)
};

struct RebuildResult {
  std::string report;  ///< the building's report.json
  bool report_changed = false;
  std::vector<std::string> changed, added, removed;  ///< tileset files, relative
};

/// Recomputes (--set, --reset, or neither option) and/or re-selects (--select)
/// one building, persists the choice in WORK/overrides.json, assembles the
/// tileset again (switched in atomically: DIR/tileset is at every instant the
/// previous or the new complete tileset) and reports the files whose bytes
/// differ; updates run_report.json. Holds the locks of DIR and DIR/work. Throws
/// std::invalid_argument for bad options, std::runtime_error otherwise.
RebuildResult rebuild(const RebuildOptions& o, const ProgressFn& progress = {});

/// "0,3,5" -> {0,3,5} sorted, unique; "all" / "auto" -> {}. Throws std::invalid_argument.
std::vector<int> parse_select(const std::string& s);

// ------------------------------------------------------------ building blocks

/// Pins the model selections of the overrides in WORK/lod/<id>/report.json:
/// "models" keeps only the selected steps, the full list is kept in
/// "models_all" (restored when the selection is cleared). Assemble then only
/// sees the selected models. Returns warnings "<id>: ..." (selection ignored:
/// no anchor, unknown steps). Files are rewritten only when their content changes.
std::vector<std::string> apply_model_selections(const std::string& work_dir,
                                                const Overrides& overrides);

/// One record per manifest building: id, status, reason, models, overrides.
std::vector<BuildingRecord> building_records(const std::string& work_dir,
                                             const Overrides& overrides);

}  // namespace citylod::tiler
