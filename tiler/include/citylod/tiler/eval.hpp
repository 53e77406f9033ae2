// `citylod eval` as library calls: models against a reference, a whole work
// directory, or a tileset. They return data; the text and JSON forms are the
// program's (app/eval_format.*).
//
//   evaluate_models(MODELS, REF) each model against one reference input
//   evaluate_work(WORK)      every building with LOD output: each model of
//                            lod/<id>/report.json against the building's chunk
//                            (validity, volume, e1/e2, Hausdorff) + a summary
//   evaluate_tileset(TS)     every glb of tileset.json, triangles grouped per
//                            building (EXT_mesh_features feature id ->
//                            building_id), per tile depth ("level"): triangles,
//                            closed / edge-manifold / self-intersections; with
//                            a work directory also e1/e2/Hausdorff against the
//                            building's chunk (positions taken back to the
//                            chunk frame through the tile transforms, ECEF and
//                            the manifest's scene origin)
//
// Both run OpenMP over buildings; results are stored per building in id
// order, so they do not depend on the thread count. Progress: tasks "eval"
// and "reading tiles", one count per building / tile.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "citylod/lod/lod.hpp"
#include "citylod/tiler/progress.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

struct EvalOptions {
  int samples = 20000;  ///< samples per surface for e1/e2
  int threads = 0;      ///< 0 = all cores
};

// ------------------------------------------------------------ model files
struct ModelFileEval {
  std::string model, reference;  ///< paths
  lod::ModelEvaluation e;
};
/// Every model (PLY/OBJ/OFF) against the reference (point cloud or mesh); both
/// are moved by the reference's rounded bbox centre. Throws io::IoError naming
/// the file (unreadable, or a model without triangles).
std::vector<ModelFileEval> evaluate_models(const std::vector<std::string>& models,
                                           const std::string& reference, int samples);

// ------------------------------------------------------------ work directory
struct WorkModelEval {
  std::string file;  ///< as listed in report.json
  ModelKind kind = ModelKind::anchor;
  int level = 0, step = 0;
  bool empty = false;  ///< no triangles: nothing measured
  lod::ModelEvaluation e;
};

struct WorkBuildingEval {
  std::string id;
  Status status = Status::pending;  ///< report.json's, else the manifest's
  std::string reason;
  bool has_lod = false;  ///< report.json lists at least one model
  std::string chunk;     ///< reference file
  std::size_t reference_points = 0, reference_triangles = 0;
  double diagonal = 0;                ///< of the reference's bbox, metres
  std::vector<WorkModelEval> models;  ///< sorted by step
  int finest = -1;  ///< index in models: the last anchor (or fallback), else the last model
};

struct WorkEval {
  std::string work;
  int samples = 0;
  std::size_t manifest_buildings = 0;
  std::vector<WorkBuildingEval> buildings;  ///< every manifest record, id order
};

/// Throws io::IoError naming the file (missing/empty manifest, no building
/// with LOD output, unreadable chunk or model, malformed report.json).
WorkEval evaluate_work(const std::string& work_dir, const EvalOptions& o,
                       const ProgressFn& progress = {});

struct Stat {
  double mean = 0, median = 0, max = 0;
  std::string argmax;  ///< id of the max
};
struct WorkSummary {
  std::size_t buildings = 0, models = 0, closed = 0, edge_manifold = 0, oriented = 0,
              self_intersecting = 0, empty = 0;
  std::size_t pinched = 0;        ///< models with a pinched vertex
  std::size_t not_one_shell = 0;  ///< models with other than one outer shell
  std::size_t valid = 0;          ///< valid solids (lod::MeshCheck::valid)
  Stat finest_e1, finest_e2;      ///< of each building's finest model
  std::vector<std::pair<std::string, std::string>> fallbacks, without_lod;  ///< id, reason
};
WorkSummary summarize(const WorkEval& w);

// ------------------------------------------------------------ tileset
struct TileMeshEval {
  std::string building;  ///< building_id of the feature ("feature-<n>" without a property table)
  int level = 0;         ///< depth of the tile (root = 0)
  std::string tile;      ///< content file, relative to the tileset directory
  int model_index = -1, step = -1;
  /// The feature's lod_kind; none without a property table or with a spelling
  /// citylod does not write (a tileset from elsewhere).
  std::optional<lod::ModelKind> kind;
  std::size_t triangles = 0, vertices = 0;  ///< after welding equal stored positions
  lod::MeshCheck check;
  /// lod::check_solid at val3dity's tolerances of the mesh as decoded (triangles as
  /// faces, shells by lod::make_solid): 0 valid, else the validator's error code.
  int val3dity_error = -1;
  double volume = 0;
  bool evaluated = false;  ///< e1/e2/Hausdorff computed (a work directory was given)
  double e1 = 0, e2 = 0, hausdorff = 0;
};

struct TileInfo {
  std::string uri;  ///< relative to the tileset directory
  int level = 0;
  double geometric_error = 0;
  std::size_t triangles = 0, buildings = 0;
};

struct LevelSummary {
  int level = 0;
  std::size_t tiles = 0, meshes = 0, buildings = 0, triangles = 0;
  std::size_t closed = 0, edge_manifold = 0, self_intersecting = 0;
  std::size_t pinched = 0, not_one_shell = 0, valid = 0;  ///< building meshes
  std::size_t valid_tolerant = 0;  ///< valid at val3dity's tolerances (val3dity_error == 0)
  std::size_t evaluated = 0;
  double mean_e1 = 0, mean_e2 = 0, max_e2 = 0;
  std::string max_e2_building;
};

struct TilesetEval {
  std::string tileset;  ///< tileset.json path
  std::string work;     ///< "" without references
  int samples = 0;
  std::size_t tiles = 0;  ///< in tileset.json (external tilesets included)
  int depth = 0;
  std::vector<TileInfo> contents;    ///< glb contents, tree order
  std::vector<TileMeshEval> meshes;  ///< sorted by level, building, tile
  std::vector<LevelSummary> levels;  ///< levels with content
};

/// `path`: a tileset.json or a directory holding one. `work_dir`: "" or the
/// work directory the tileset was assembled from. Throws io::IoError naming
/// the file (missing or malformed tileset.json, missing or corrupt glb,
/// unsupported content, building not in the manifest, ...).
TilesetEval evaluate_tileset(const std::string& path, const std::string& work_dir,
                             const EvalOptions& o, const ProgressFn& progress = {});

}  // namespace citylod::tiler
