// Private to tiler/: the LOD stage of a city run — every chunk of a work
// directory through the LOD engine, in parallel, resumable, failure-isolated.
//
//   WORK/lod/<id>/report.json + model_*.ply     (io/workdir.hpp)
//
// A building is skipped when its report.json carries the same key (hash of
// the chunk content, the parameters and the engine version): a killed run
// resumes where it stopped. Each building's output directory is staged and
// renamed into place, so it is either complete or absent. A building that
// throws gets its fallback model and the reason; one that crashed the process
// in an earlier run (its `.running` marker is still there) is not retried: it
// gets the fallback with reason "crashed in an earlier run".
#pragma once

#include "citylod/lod/params.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace citylod::tiler {

struct LodStageOptions {
  std::string work_dir;
  lod::LodParams params;            ///< per building (params.threads is forced to 1 inside a city run)
  int threads = 1;                  ///< buildings processed at once (OpenMP)
  int shard_index = 0, shard_count = 1;  ///< process the chunks with (rank % count) == index
  std::vector<std::string> only;    ///< if not empty: these building ids only (and always recomputed)
};

struct LodStageReport {
  std::size_t total = 0;            ///< chunks in this shard
  std::size_t computed = 0, reused = 0;
  std::size_t ok = 0, fallback = 0, failed = 0;
  std::vector<std::pair<std::string, std::string>> problems;  ///< (id, reason) for fallback/failed
  double seconds = 0;
};

/// Progress: called (from one thread at a time) after each building with the
/// number done and the total.
using LodStageProgress = void (*)(std::size_t done, std::size_t total, void* user);

LodStageReport run_lod_stage(const LodStageOptions& o, LodStageProgress progress = nullptr, void* user = nullptr);

/// The resume key of a building: chunk content hash + parameters + engine version.
std::string lod_key(const std::string& content_hash, const lod::LodParams& p);

/// Parses "i/N" (0 <= i < N); throws std::invalid_argument.
void parse_shard(const std::string& s, int& index, int& count);

}  // namespace citylod::tiler
