// The assemble stage (`citylod assemble`): per-building LOD models of a work
// directory -> a hierarchical 3D Tiles 1.1 tileset (see docs/3dtiles.md).
//
//   WORK/manifest.json + WORK/lod/<id>/report.json + model PLYs
//     -> (1) per building: read the models, keep the anchors and the
//            interpolations that change the look, error of each kept model =
//            Hausdorff distance to the finest one (made strictly decreasing)
//     -> (2) tile tree: tiles near the root show coarse models of many
//            buildings; each child REPLACEs its parent with the next kept model
//            of fewer buildings (quadrant split by building centre, further
//            splits while a tile is over its triangle / byte budget)
//     -> (3) tiles/<name>.glb (GlbBuilder), buildings/<id>.glb (all kept models
//            of one building, for the viewer), buildings.json, tileset.json,
//            all staged in OUT.partial, fsync'd and switched in by one atomic
//            exchange (io::publish_directory) at the end.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "citylod/io/gltf.hpp"
#include "citylod/io/types.hpp"
#include "citylod/tiler/progress.hpp"

namespace citylod::tiler {

struct AssembleParams {
  std::size_t max_tile_triangles = 250000;  ///< per glb
  std::size_t max_tile_bytes = 4u << 20;    ///< geometry bytes per glb (vertices + indices)
  /// The children of a tile with geometric error e cover at most
  /// tile_extent_factor * e metres (xy diagonal of their buildings) each, so
  /// tiles shrink with their error and a close-up never loads a far-reaching
  /// tile (a tile is loaded from roughly 40 e away at the default SSE of 16).
  /// 0 = no extent limit (only the budgets split).
  double tile_extent_factor = 50;
  /// ... but never less than this many metres: where errors are small (the
  /// last refinements, the leaves) a tile gathers the buildings of a block of
  /// about this size instead of one or two (0 = factor only).
  double min_tile_extent_m = 0;
  /// A tileset JSON file holds at most about this many tiles: larger subtrees
  /// go to external tilesets (tiles/<name>.json), so that no file of a city's
  /// tileset grows beyond a few MB (about 1.5 kB per tile: 10,017 buildings in
  /// 2687 tiles made a 4.0 MB tileset.json).
  std::size_t max_tiles_per_file = 1000;
  /// Buildings that reach their finest model go to leaf tiles of their own
  /// (stored once) when their models total at least this many geometry bytes;
  /// a smaller group stays with the refining buildings and is repeated down
  /// the chain: a separate leaf costs a request and ~6 kB of glb JSON.
  std::size_t min_leaf_bytes = 64u << 10;
  /// An interpolation model is kept only if its Hausdorff distance to the
  /// previous kept model and to the next anchor are both >= this, and it is
  /// this much closer to the finest model than the previous kept one (metres).
  double min_change_m = 0.1;
  /// Tolerance of the Hausdorff distances (metres).
  double hausdorff_tolerance_m = 0.1;
  bool quantize = false;  ///< KHR_mesh_quantization in every glb
  /// EXT_meshopt_compression (quantized positions and normals, meshopt codecs)
  /// or plain accessors; docs/3dtiles.md.
  io::Compression compression = io::Compression::meshopt;
  /// Also write buildings/<id>.glb (every kept model of a building in one
  /// file). Off by default: buildings.json names, for each kept model, the
  /// tile glb that holds it, which is what the viewer's LOD slider loads.
  bool building_models = false;
  bool skip_missing = false;  ///< buildings without models: skip with a warning instead of failing
  bool force = false;         ///< replace an existing OUT that is not a citylod tileset
  int threads = 0;            ///< 0 = OpenMP default; output does not depend on it
  /// Throws std::invalid_argument naming the bad parameter.
  void validate() const;
};

/// Which models of one building are kept, and their errors (metres).
struct ModelChoice {
  std::vector<std::size_t> kept;  ///< indices into the input, coarse -> fine, last = finest anchor
  std::vector<double> error_m;    ///< per kept model: strictly decreasing, 0 for the last
  std::vector<double> hausdorff_m;  ///< raw Hausdorff distance to the finest model
};

struct AssembleStats {
  std::size_t buildings = 0;  ///< in the tileset
  std::size_t skipped = 0;    ///< manifest records without models (skip_missing) or status skipped
  std::size_t models_read = 0;
  std::size_t models_kept = 0;
  std::size_t tiles = 0;          ///< tiles in tileset.json (root included)
  std::size_t content_tiles = 0;  ///< tiles with a glb
  std::size_t tileset_files = 0;  ///< tileset.json + external tilesets (tiles/*.json)
  int depth = 0;                  ///< deepest tile (root = 0)
  std::size_t glb_bytes = 0;      ///< sum over tiles/*.glb
  std::size_t max_glb_bytes = 0;
  std::size_t max_tile_triangles = 0;
  std::size_t building_glb_bytes = 0;
  double root_error_m = 0;
  double seconds_read = 0, seconds_write = 0;
  std::vector<std::string> warnings;
  /// Per building of the tileset (by id): its kept chain, indices into its
  /// report.json's models. A city run hands it to write_cityjson
  /// (CityJsonOptions::chains) instead of choosing the same chain again.
  std::map<std::string, ModelChoice> chains;
};

/// Runs the whole stage. Throws io::IoError / std::runtime_error with a
/// one-line message (missing manifest, empty work dir, building without
/// models, unreadable model, ...). OUT is replaced only after everything was
/// written (OUT.partial <-> OUT, one atomic exchange): killed at any point, OUT
/// is the previous or the new complete tileset. Holds the locks of the work
/// directory and of OUT (dir_lock.hpp). Progress: task "assemble" (not cancellable).
AssembleStats assemble(const std::string& work_dir, const std::string& out_dir,
                       const AssembleParams& params, const ProgressFn& progress = {});

// ------------------------------------------------------------ building blocks (tested)

/// Symmetric Hausdorff distance between two triangle meshes, to within
/// `tolerance` metres: the result is attained by a surface point (never an
/// overestimate) and the true distance is below result + tolerance. Stops
/// early, returning a value >= stop_above, once that is certain. 0 for
/// identical meshes; +inf if one is empty.
double hausdorff_distance(const io::TriangleMesh& a, const io::TriangleMesh& b, double tolerance,
                          double stop_above = std::numeric_limits<double>::infinity());

struct LodReport;  // workdir.hpp (which includes this header)

/// A kept model is never worse (RMSE of the points) than a coarser kept model
/// by more than this (metres): zooming in never makes a building worse.
constexpr double kChainMonotoneTolerance_m = 0.05;

/// Chooses the kept chain (docs/3dtiles.md): the models sorted by step; the
/// finest model is the last anchor; every anchor is kept unless it is the same
/// surface as the next anchor (Hausdorff < 1 mm); an interpolation is kept when
/// it differs by >= min_change_m from the previous kept model and from the next
/// anchor and is >= min_change_m closer to the finest model than the previous
/// kept one. Then the chain is made monotone in RMSE (models with one, within
/// kChainMonotoneTolerance_m): a coarser model better than the finest by more
/// than the tolerance is dropped, and coarse -> fine a model worse than the
/// best kept coarser one by more than the tolerance is dropped.
/// error_m = max(Hausdorff to the finest, next kept error + 1 cm).
/// `meshes[i]` is `report.models[i]` (kind, step and RMSE read from the report).
ModelChoice choose_models(const LodReport& report, const std::vector<io::TriangleMesh>& meshes,
                          double min_change_m, double tolerance_m);

}  // namespace citylod::tiler
