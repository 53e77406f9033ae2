// The work directory of a city run and its records: the contract between the
// stages (split -> lod -> assemble, eval, rebuild). This header and
// tiler/src/workdir.cpp are the ONLY code that reads or writes these JSON
// files; every stage goes through the typed records below.
//
//   WORK/manifest.json            Manifest: scene georeferencing + one ChunkRecord per building
//   WORK/chunks/<id>.ply          a building's points (or triangles), binary PLY,
//                                 double xyz relative to the chunk origin (metres, scene ENU axes)
//   WORK/lod/<id>/report.json     LodReport: the LOD engine's outcome for that building
//   WORK/lod/<id>/model_*.ply     its candidate models (triangles), relative to the chunk origin
//   WORK/overrides.json           Overrides: per-building choices of `citylod rebuild`
//   DIR/run_report.json           RunReport: what a `citylod tile` run did (DIR = WORK/..)
//
// Coordinates: the scene frame is ENU metres at the scene origin (SceneInfo);
// each chunk has its own origin in that frame so its numbers stay small.
// Everything is written atomically (temp file + fsync + rename).
//
// A work directory is untrusted input: every building id read from its records
// (manifest.json, report.json, overrides.json, run_report.json) must be a safe
// file name (is_safe_id), a model's "file" a plain file name in the report's
// folder, and WORK/chunks and WORK/lod real folders (not symbolic links); a
// record breaking this is malformed (io::IoError naming it). So every path
// derived from a work directory stays inside it.
//
// Defaults when a field is absent (one rule for every reader):
//   - report.json without "status": Status::failed (a report that does not say
//     it succeeded is not trusted; citylod always writes the status);
//   - a model without "kind": anchor; without "step": its index; without "level": 0;
//   - an unknown kind or status: the file is malformed (io::IoError naming it).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "citylod/io/gltf.hpp"
#include "citylod/lod/kinds.hpp"
#include "citylod/tiler/assemble.hpp"

namespace citylod::tiler {

// ------------------------------------------------------------ enums

// A building's outcome (Status: in the manifest, report.json and run_report.json)
// and a model's kind (ModelKind: in report.json, buildings.json and the glb
// features) are the LOD engine's words, spelled once (lod/kinds.hpp). In the
// records a fallback counts as an anchor (is_anchor).
using lod::is_anchor;
using lod::model_kind_from_string;
using lod::ModelKind;
using lod::Status;
using lod::status_from_string;

/// How many buildings ended how: the one tally of the LOD stage, its supervised
/// summary and the run report. `pending` (never written) counts as failed.
struct StatusCounts {
  std::size_t ok = 0, fallback = 0, failed = 0, skipped = 0;
  void add(Status s);
  /// A LOD outcome (report.json's status): the stage skips no building, so a
  /// skipped or pending status there is a failure.
  void add_lod_outcome(Status s) {
    add(s == Status::ok || s == Status::fallback ? s : Status::failed);
  }
};

// ------------------------------------------------------------ manifest.json

struct SceneInfo {
  std::string crs;  ///< CRS spec as given ("EPSG:28992", WKT, or "" for --origin)
  std::array<double, 3> origin_crs{0, 0, 0};  ///< scene origin in CRS units
  /// The scene frame (geo::SceneFrame): true: chunk coordinates are the CRS's axes in
  /// metres from origin_crs, heights the input's ("frame": "projected"); false: ENU metres
  /// at the origin ("enu": --origin scenes, and work directories of earlier versions).
  bool projected_frame = false;
  double origin_lon = 0, origin_lat = 0;  ///< degrees (WGS84)
  double origin_h = 0;                    ///< metres, ellipsoidal (WGS84)
  std::vector<std::string> inputs;        ///< input files
  std::string options;                    ///< split options as a canonical string
  std::vector<std::string> notes;         ///< e.g. "heights NAP -> ellipsoidal via EGM96"
  std::string vertical;  ///< the height assumption of the split ("" when not recorded)
  /// Building (class 6) points read, and those outside every footprint; -1 = not counted.
  std::int64_t building_points = -1, unmatched_points = -1;
};

struct ChunkRecord {
  std::string id;  ///< stable id ("fp-<footprint id>" or "b-<position hash>")
  std::array<double, 3> origin{0, 0, 0};    ///< chunk origin, scene ENU metres
  std::array<double, 3> bbox_min{0, 0, 0};  ///< scene ENU metres
  std::array<double, 3> bbox_max{0, 0, 0};
  std::uint64_t points = 0;
  std::uint64_t triangles = 0;
  std::vector<std::array<double, 2>> outline;  ///< footprint/outline, scene ENU xy, CCW
  double ground_z = 0;                         ///< ground height, scene ENU z
  std::string source;                          ///< "footprint:<id>", "cluster", ...
  Status status = Status::pending;             ///< split writes pending or skipped
  std::string reason;                          ///< why skipped
  std::string content_hash;                    ///< hash of the chunk file (hex)
  /// The footprint's attributes from its source, typed, keys sorted ({} without footprint).
  nlohmann::json attributes = nlohmann::json::object();
  bool skipped() const { return status == Status::skipped; }
};

struct Manifest {
  int version = 1;
  SceneInfo scene;
  std::vector<ChunkRecord> chunks;  ///< sorted by id
};

/// Throws io::IoError("<WORK>/manifest.json: ...") when missing or malformed.
Manifest read_manifest(const std::string& work_dir);

/// The manifest's buildings that have a chunk (not skipped by split), sorted by
/// id; `*skipped` (when given) receives how many were skipped. An id listed
/// twice is an IoError naming the manifest.
std::vector<const ChunkRecord*> buildings_to_model(const Manifest& m, const std::string& work_dir,
                                                   std::size_t* skipped = nullptr);
/// Throws io::IoError naming the manifest when the scene origin is not a valid
/// longitude / latitude / height (assemble and eval need it; split writes it).
void require_valid_origin(const Manifest& m, const std::string& work_dir);
/// Atomic; chunks are written sorted by id.
void write_manifest(const std::string& work_dir, const Manifest& m);
/// True when WORK/chunks/<id>.ply is a regular file whose hash is the record's
/// content_hash (a record without a hash: when the file exists). A chunk
/// truncated or changed since split is not intact.
bool chunk_intact(const std::string& work_dir, const ChunkRecord& c);
/// Throws io::IoError("<WORK>/chunks: ...") when WORK/chunks exists, is not
/// empty and WORK has no manifest.json: split never replaces a folder it did not make.
void require_own_chunks(const std::string& work_dir);

/// Longest building id accepted (split writes at most 120 + a few characters).
constexpr std::size_t kMaxIdLength = 200;
/// True when `id` is safe as a file name inside the work directory: 1..kMaxIdLength
/// characters of [A-Za-z0-9._-], not starting with '.', without "..".
bool is_safe_id(const std::string& id);
/// Throws io::IoError(file, "building id '<id>' is not a safe name ...") unless is_safe_id(id).
void require_safe_id(const std::string& id, const std::string& file);

// ------------------------------------------------------------ paths
// Every file and folder name of a run is spelled here, in workdir.cpp, alone:
//   DIR/work  DIR/tileset  DIR/buildings.city.jsonl  DIR/run_report.json   (`citylod tile -o DIR`)
//   TILESET/tileset.json  TILESET/buildings.json                              (assemble)
//   WORK/manifest.json  WORK/chunks/<id>.ply  WORK/overrides.json
//   WORK/lod/<id>/report.json  WORK/lod/<id>/params.json
//   WORK/lod/<id>.running | .suspect | .crashed                      (LodMarker)
//   WORK/.split.tmp.<pid>/{spill,faces,chunks,chunks.old}               (split's staging)
//   DIR/.citylod.lock  DIR/.citylod.shard-<i>-of-<n>.lock  PARENT/.<name>.citylod.lock

std::string run_work_dir(const std::string& out_dir);       ///< DIR/work
std::string run_tileset_dir(const std::string& out_dir);    ///< DIR/tileset
std::string run_cityjson_path(const std::string& out_dir);  ///< DIR/buildings.city.jsonl
/// A tileset folder's root file (DIR/tileset/tileset.json; its buildings.json beside it).
std::string tileset_json_path(const std::string& tileset_dir);
std::string buildings_json_path(const std::string& tileset_dir);
std::string manifest_path(const std::string& work_dir);
std::string chunks_dir(const std::string& work_dir);  ///< WORK/chunks
std::string lod_root(const std::string& work_dir);    ///< WORK/lod
// The paths of one building; throw std::invalid_argument when !is_safe_id(id).
std::string chunk_path(const std::string& work_dir, const std::string& id);
std::string lod_dir(const std::string& work_dir, const std::string& id);
std::string lod_report_path(const std::string& work_dir, const std::string& id);
/// report.json and params.json of a LOD output folder (WORK/lod/<id>, or `citylod lod -o DIR`).
std::string report_file(const std::string& lod_output_dir);
std::string params_file(const std::string& lod_output_dir);

/// The locks of dir_lock.hpp: DIR/.citylod.lock (a directory written in place),
/// DIR/.citylod.shard-<i>-of-<n>.lock (a LOD shard), PARENT/.<name>.citylod.lock
/// (an output switched as a whole, beside it).
std::string dir_lock_path(const std::string& dir);
std::string shard_lock_path(const std::string& dir, int index, int count);
std::string output_lock_path(const std::string& out);

/// The split's staging folder WORK/.split.tmp.<pid> and what it holds: spill/
/// (points by cell), faces/ (mesh triangles by cell), chunks/ (becomes
/// WORK/chunks; chunks_dir of the staging folder) and chunks.old (the previous
/// WORK/chunks while they are swapped).
std::string split_staging_dir(const std::string& work_dir, long pid);
/// The pid of a split staging folder's name (".split.tmp.<pid>"; 0 when the rest is not
/// a number); -1 when `file_name` is not a split staging folder's.
long split_staging_pid(const std::string& file_name);
std::string split_spill_dir(const std::string& staging_dir);
std::string split_faces_dir(const std::string& staging_dir);
std::string split_old_chunks_dir(const std::string& staging_dir);

/// The LOD stage's marker beside WORK/lod/<id>: `running` while the engine works on
/// the building; after a crash the supervisor renames it `crashed` (the only building
/// running: it gets its fallback) or `suspect` (one of several: retried alone).
enum class LodMarker { running, suspect, crashed };
std::string lod_marker_path(const std::string& work_dir, const std::string& id, LodMarker m);
/// The building id of a marker's file name ("<id>.running" -> "<id>"); "" when
/// `file_name` is not a marker of kind `m`.
std::string marker_id(const std::string& file_name, LodMarker m);

// ------------------------------------------------------------ lod/<id>/report.json

/// A face's colour from the input: rgb (sRGB, as the input stores it) + a
/// (255 = coloured, 0 = none: the fixed material).
using FaceColour = io::Rgba8;

/// One candidate model of a building.
struct ModelRecord {
  std::string file;  ///< PLY, a plain file name in the report's directory
  ModelKind kind = ModelKind::anchor;
  int level = 0, step = 0;
  int cuts = 0;
  double diff_sum = 0;
  std::uint64_t polygons = 0, triangles = 0;
  double volume = 0;
  double e1 = -1, e2 = -1;  ///< % of the bbox diagonal (-1: not computed)
  double hausdorff_m = -1;
  double roof_rmse_m = -1;  ///< airborne LiDAR: the vertical roof fit (m); -1: not measured
  /// Input colours (lod colour.cpp): one per face of the OBJ's polygons and one
  /// per triangle of the PLY, in file order, or both empty (no colours). In
  /// report.json as runs: "colours": {"polygons": [[n, r, g, b] | [n], ...],
  /// "triangles": [...]} ([n]: n faces without colour).
  std::vector<FaceColour> polygon_colours, triangle_colours;
};

/// The LOD outcome of one building (written by the LOD stage and `citylod lod`).
struct LodReport {
  std::string input;  ///< the file the models were built from
  Status status = Status::failed;
  std::string reason;   ///< why fallback / failed
  std::string id, key;  ///< city runs: building id and resume key ("" otherwise)
  std::map<std::string, std::string> parameters;  ///< every LOD parameter (LodParams::items())
  int threads = 1;  ///< threads inside the building when it ran (not a parameter; kThreadsKey)
  std::map<std::string, std::int64_t> counts;  ///< input_points, P, S, principal, ..., models
  std::map<std::string, std::int64_t> lod_tree_vs_bsp_tree;
  double bbox_diagonal_m = 0;
  bool normals_estimated = false, walls_inferred = false;
  std::map<std::string, double> timings_s;  ///< T1_ioview, T2_tree, T3_traversal, metrics
  std::vector<std::string> notes;
  std::vector<ModelRecord> models;  ///< what assemble sees (the selection when one is pinned)
  /// With a pinned selection (`rebuild --select`): every model and the steps shown.
  std::optional<std::vector<ModelRecord>> models_all;
  std::vector<int> selected_steps;

  /// The models before any selection.
  const std::vector<ModelRecord>& all_models() const { return models_all ? *models_all : models; }
  /// RMSE of the building's points to models[i], metres (its e2 x the bbox
  /// diagonal / 100); -1: not measured.
  double rmse_m(std::size_t i) const {
    const double e2 = models.at(i).e2;
    return e2 >= 0 && bbox_diagonal_m > 0 ? e2 / 100 * bbox_diagonal_m : -1;
  }
};

/// report.json and params.json record the threads a building ran on under this
/// key among its parameters, as the format always had it; it is an execution
/// setting (lod::LodExecution), not a parameter, and the readers take it out.
inline constexpr const char* kThreadsKey = "threads";

/// Throws io::IoError naming the file when it is missing, not JSON, or malformed.
LodReport read_lod_report(const std::string& path);
/// nullopt when WORK/lod/<id>/report.json does not exist; throws like read_lod_report otherwise.
std::optional<LodReport> find_lod_report(const std::string& work_dir, const std::string& id);
/// Atomic. Returns false (and writes nothing) when the file already holds exactly these bytes.
bool write_lod_report(const std::string& path, const LodReport& r);
/// params.json of a LOD output folder: `parameters` (LodParams::items()) and
/// the threads the building ran on (kThreadsKey). Atomic.
void write_params_record(const std::string& lod_output_dir,
                         const std::map<std::string, std::string>& parameters, int threads);

/// A building's LOD output as assemble and the CityJSON writer read it: its
/// report, the files of its models (absolute, in the order of report.models)
/// and their meshes.
struct BuildingModels {
  LodReport report;
  std::string report_path;
  std::vector<std::string> files;
  std::vector<io::TriangleMesh> meshes;
};
/// A model file of a work directory: a .ply (as the LOD stage writes them) read as
/// PLY without detecting its format, any other with io::read_mesh.
io::TriangleMesh read_model_file(const std::string& file);

/// Reads WORK/lod/<id>/report.json and every model it lists, each with `read`
/// (which chooses the frame); with `only`, just the models of those indices
/// (the others are left empty). io::IoError naming the report when it is missing
/// or lists no model (with its status and reason), or naming a listed model
/// file that does not exist.
BuildingModels read_building_models(
    const std::string& work_dir, const std::string& id,
    const std::function<io::TriangleMesh(const std::string& file)>& read,
    const std::vector<std::size_t>* only = nullptr);

// ------------------------------------------------------------ overrides.json

/// Per-building choices made with `citylod rebuild`, persisted in WORK/overrides.json:
/// {"buildings": {"<id>": {"set": {"planes.epsilon": "0.2"}, "select": [0, 3]}}}.
struct BuildingOverride {
  std::map<std::string, std::string> set;  ///< LOD parameter overrides
  std::vector<int> select;                 ///< model steps shown (empty = assemble chooses)
};
using Overrides = std::map<std::string, BuildingOverride>;

std::string overrides_path(const std::string& work_dir);
/// Empty when the file is absent; throws std::runtime_error when it is malformed.
Overrides read_overrides(const std::string& work_dir);
void write_overrides(const std::string& work_dir, const Overrides& o);  ///< atomic

// ------------------------------------------------------------ run_report.json

/// One building of a city run as the run report lists it.
struct BuildingRecord {
  std::string id, source;
  Status status = Status::failed;
  std::string reason;
  std::size_t models = 0;
  std::map<std::string, std::string> set;  ///< its overrides
  std::vector<int> select;
};

/// The counts (StatusCounts) are its "summary".
struct RunReport : StatusCounts {
  std::string command = "tile";
  std::vector<std::string> inputs;
  int threads = 1;
  struct Split {
    double seconds = 0;
    bool up_to_date = false;
    std::size_t chunks = 0;
    std::uint64_t points = 0;
    std::string crs;
    std::string vertical;  ///< the height assumption (printed in the run summary too)
    /// Building (class 6) points, those outside every footprint (-1: not counted), and
    /// the buildings without footprint made of them (--unmatched segment).
    std::int64_t building_points = -1, unmatched_points = -1;
    std::size_t unmatched_chunks = 0;
  } split;
  struct Lod {
    double seconds = 0;
    std::size_t buildings = 0, computed = 0, reused = 0, restarts = 0;
  } lod;
  struct Assemble {
    double seconds = 0;
    std::size_t buildings = 0, tiles = 0, glb_bytes = 0, models_kept = 0;
    int depth = 0;
    std::vector<std::string> warnings;
  } assemble;
  double seconds_total = 0;
  std::uint64_t peak_rss_self = 0, peak_rss_children = 0;  ///< bytes
  std::map<std::string, std::string> lod_params;           ///< LodParams::items()
  AssembleParams assemble_params;                          ///< threads and force are not recorded
  std::vector<BuildingRecord> buildings;
  struct LastRebuild {
    std::string building;
    std::map<std::string, std::string> set;
    std::vector<int> select;
    bool report_changed = false;
    std::vector<std::string> changed, added, removed;
  };
  std::optional<LastRebuild> last_rebuild;
};

// JSON of the stage records: the field names are the keys; absent keys keep the defaults.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(RunReport::Split, seconds, up_to_date, chunks,
                                                points, crs, vertical, building_points,
                                                unmatched_points, unmatched_chunks)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(RunReport::Lod, seconds, buildings, computed,
                                                reused, restarts)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE_WITH_DEFAULT(RunReport::Assemble, seconds, buildings, tiles,
                                                glb_bytes, models_kept, depth, warnings)

std::string run_report_path(const std::string& out_dir);  ///< DIR/run_report.json
/// Throws std::runtime_error naming the file when it is missing or malformed.
RunReport read_run_report(const std::string& out_dir);
void write_run_report(const std::string& out_dir, const RunReport& r);  ///< atomic

}  // namespace citylod::tiler
