// The LOD stage: one building (`citylod lod INPUT`) or every chunk of a work
// directory through the LOD engine, in parallel, resumable, failure-isolated.
//
//   WORK/lod/<id>/report.json + model_*.{obj,ply} + params.json   (workdir.hpp)
//
// A building is reused when its report.json carries the same key (hash of
// the chunk content, the parameters and the engine version): a killed run
// resumes where it stopped. Each building's output directory is staged and
// renamed into place, so it is either complete or absent. A building that
// throws gets its fallback model and the reason; one that crashed the process
// in an earlier run (its `.crashed` marker, see supervise.hpp) is not retried:
// it gets the fallback with reason "crashed in an earlier run".
// Per-building parameter overrides (WORK/overrides.json) apply wherever the
// stage runs: tile, lod WORK, Slurm shards, rebuild.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "citylod/io/types.hpp"
#include "citylod/lod/lod.hpp"
#include "citylod/lod/params.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/progress.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

// ------------------------------------------------------------ parameters

/// The paper's defaults, except what a city run needs: its chunks hold no
/// ground, and a low plane reaching a chunk's edge (a courtyard, a plaza) is
/// not terrain to keep as a plinth (closure.terrain = cut); every chunk has a
/// footprint, whose walls close what airborne LiDAR scanned in part
/// (closure.footprint_walls), and on it roof steps down to 0.5 m get walls
/// (airborne.step_min).
lod::LodParams city_lod_params();
/// Applies "name=value[,name=value...]"; throws std::invalid_argument naming the item.
void apply_lod_settings(lod::LodParams& p, const std::string& list);
/// Applies a JSON object {"planes.epsilon": 0.2, ...}; throws std::runtime_error naming the file.
void apply_lod_config(lod::LodParams& p, const std::string& path);
/// The global parameters with the building's overrides applied.
lod::LodParams params_for(const lod::LodParams& global, const Overrides& o, const std::string& id);
/// The resume key of a building: chunk content hash + parameters + engine version.
std::string lod_key(const std::string& content_hash, const lod::LodParams& p);
/// Parses "i/N" (0 <= i < N); throws std::invalid_argument.
void parse_shard(const std::string& s, int& index, int& count);

// ------------------------------------------------------------ one building

/// `citylod lod INPUT --out DIR`.
struct BuildingLodOptions {
  std::string input, out_dir;
  lod::LodParams params;
  int threads = 1;  ///< threads inside the building (resolved, >= 1)
  bool dump_planes = false;
};
struct BuildingLodResult {
  LoadedBuilding building;  ///< the input as read (local frame, origin)
  lod::LodResult result;
  std::vector<std::string> files;  ///< written
};
/// Reads the input, builds its LOD-Tree and writes DIR (write_lod_output).
/// Throws io::IoError / std::runtime_error naming the input.
BuildingLodResult build_building_lod(const BuildingLodOptions& o, const ProgressFn& progress = {});

/// Writes DIR/model_<step>_<kind>_L<level>.{obj,ply}, DIR/report.json,
/// DIR/params.json and, when dump_planes, DIR/planes.ply (inliers coloured by
/// level set). All files atomically. Returns the list of files written.
/// `threads` (those inside the building), `id` and `key` (city runs) are
/// recorded in report.json.
std::vector<std::string> write_lod_output(const std::string& dir, const lod::LodResult& r,
                                          const lod::LodParams& p, int threads,
                                          const std::string& input, const io::Vec3d& origin,
                                          bool dump_planes, const std::string& id = "",
                                          const std::string& key = "");

// ------------------------------------------------------------ a work directory

struct LodStageOptions {
  std::string work_dir;
  lod::LodParams params;  ///< per building (each runs on one thread inside a city run)
  int threads = 1;        ///< buildings processed at once (std::threads), >= 1
  int shard_index = 0, shard_count = 1;  ///< process the chunks with (rank % count) == index
  std::vector<std::string> only;  ///< if not empty: these building ids only (and always recomputed)
};

/// What the stage will do, known before it runs (the parent of a supervised
/// run counts reused buildings from it; nothing is read but the manifest and
/// the reports' keys).
struct LodStagePlan {
  struct Item {
    const ChunkRecord* chunk = nullptr;
    lod::LodParams params;  ///< the building's (overrides applied)
    std::string key;
    bool up_to_date = false;  ///< reused: its report.json has this key (never with `only`)
  };
  Manifest manifest;
  std::vector<Item> items;  ///< this shard's non-skipped chunks, largest first
  std::size_t up_to_date() const;
};
LodStagePlan plan_lod_stage(const LodStageOptions& o);

/// Counts of one run of the stage (this process).
struct LodStageReport : StatusCounts {  ///< ok / fallback / failed
  std::size_t total = 0;                ///< chunks in this shard
  std::size_t computed = 0, reused = 0;
  std::vector<std::pair<std::string, std::string>> problems;  ///< (id, reason) for fallback/failed
  double seconds = 0;
};

/// Runs the stage in this process (threads over buildings; call it inside
/// supervise() when crashes must be isolated). Progress: task "lod", one
/// count per building.
LodStageReport run_lod_stage(const LodStageOptions& o, const ProgressFn& progress = {});

/// The locks a LOD stage holds (dir_lock.hpp): WORK exclusively; the shards of
/// one stage (shard_count > 1, no `only`) WORK shared and their shard lock
/// exclusively, so they run at once. Throws DirBusy.
class LodStageLock {
 public:
  explicit LodStageLock(const LodStageOptions& o);

 private:
  DirLock work_;
  std::optional<DirLock> shard_;
};

}  // namespace citylod::tiler
