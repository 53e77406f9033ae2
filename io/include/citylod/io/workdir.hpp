// The work directory shared by the stages of a city run:
//
//   WORK/manifest.json            scene georeferencing + one record per building chunk
//   WORK/chunks/<id>.ply          a building's points (or triangles), binary PLY,
//                                 double xyz relative to the chunk origin (metres, scene ENU axes)
//   WORK/lod/<id>/report.json     the LOD engine's report for that building (models, status)
//   WORK/lod/<id>/model_*.ply     its candidate models (triangles), relative to the chunk origin
//
// Coordinates: the scene frame is ENU metres at the scene origin (SceneInfo);
// each chunk has its own origin in that frame so its numbers stay small.
// Everything is written atomically (temp file + rename).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace citylod::io {

struct SceneInfo {
  std::string crs;                        ///< CRS spec as given ("EPSG:28992", WKT, or "" for --origin)
  std::array<double, 3> origin_crs{0, 0, 0};  ///< scene origin in CRS units
  double origin_lon = 0, origin_lat = 0;  ///< degrees (WGS84)
  double origin_h = 0;                    ///< metres, ellipsoidal (WGS84)
  std::vector<std::string> inputs;        ///< input files
  std::string options;                    ///< split options as a canonical string
  std::vector<std::string> notes;         ///< e.g. "heights NAP -> ellipsoidal via EGM96"
};

struct ChunkRecord {
  std::string id;                          ///< stable id ("fp-<footprint id>" or "b-<position hash>")
  std::array<double, 3> origin{0, 0, 0};   ///< chunk origin, scene ENU metres
  std::array<double, 3> bbox_min{0, 0, 0}; ///< scene ENU metres
  std::array<double, 3> bbox_max{0, 0, 0};
  std::uint64_t points = 0;
  std::uint64_t triangles = 0;
  std::vector<std::array<double, 2>> outline;  ///< footprint/outline, scene ENU xy, CCW
  double ground_z = 0;                     ///< ground height, scene ENU z
  std::string source;                      ///< "footprint:<id>", "cluster", ...
  std::string status = "pending";          ///< pending | ok | fallback | failed | skipped
  std::string reason;                      ///< why fallback/failed/skipped
  std::string content_hash;                ///< hash of the chunk file (hex)
};

struct Manifest {
  int version = 1;
  SceneInfo scene;
  std::vector<ChunkRecord> chunks;  ///< sorted by id
};

/// Throws IoError("<WORK>/manifest.json: ...") when missing or malformed.
Manifest read_manifest(const std::string& work_dir);
/// Atomic; chunks are written sorted by id.
void write_manifest(const std::string& work_dir, const Manifest& m);

std::string manifest_path(const std::string& work_dir);
std::string chunk_path(const std::string& work_dir, const std::string& id);
std::string lod_dir(const std::string& work_dir, const std::string& id);

/// 64-bit FNV-1a of bytes / of a file's content, as 16 hex digits.
std::string hash_hex(const void* data, std::size_t size, std::uint64_t seed = 0xcbf29ce484222325ULL);
std::string hash_file(const std::string& path);

}  // namespace citylod::io
