// CityJSON 2.0 output of a work directory (docs/cityjson.md): every building
// with its whole LOD chain, as a CityJSONSeq file (CityJSON Text Sequence,
// one JSON object per line).
//
//   line 1:  {"type":"CityJSON","version":"2.0","transform":{...},
//             "metadata":{"referenceSystem":"https://www.opengis.net/def/crs/EPSG/0/28992",...},
//             "CityObjects":{},"vertices":[]}
//   line 2+: {"type":"CityJSONFeature","id":ID,"CityObjects":{ID:{"type":"Building",
//             "attributes":{...,"citylod_models":[...]},"geometry":[Solid, ...]}},
//             "vertices":[[x,y,z],...]}   one per building, in chunk id order
//
// The Building holds one Solid per LoD (1.2 the coarsest block, 1.3 the finest
// flat step model, 2.2 the finest model); the rest of the kept chain (coarse ->
// fine, the chain the tileset shows; or every model with `all_models`) are
// "+LodTreeModel" CityObjects of the same feature (docs/extensions). Each Solid
// is the model's merged polygons in the input's CRS, integer vertices through
// `transform`, semantic surfaces from the face normals, made valid for
// val3dity at its tolerances as written (lod::check_solid: welded, spikes out,
// rejected polygons as their triangles, cavities as inner shells) or left out.
// The work directory is read through workdir.hpp's records only; the models are
// the files report.json names (the merged polygons come from the OBJ of the
// same stem when it matches the PLY).
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/progress.hpp"

namespace citylod::tiler {

struct CityJsonOptions {
  /// transform.scale: the size of one integer step of the vertices, in CRS
  /// units (metres for EPSG:28992). 0.0001 = 0.1 mm (as roofer writes; at 1 mm
  /// rounding turns sub-millimetre slivers of some models inside out).
  double scale = 0.0001;
  /// The kept chain, as assemble chooses it (AssembleParams of the same names).
  double min_change_m = 0.1;
  double hausdorff_tolerance_m = 0.1;
  /// Every model of report.json instead of the kept chain.
  bool all_models = false;
  /// The kept chains assemble chose from the same work directory with the same
  /// min_change_m and hausdorff_tolerance_m (AssembleStats::chains): a building
  /// found here is not chosen again (a city run; the CityJSON then shows the
  /// tileset's chain by construction). Not owned; null: chosen here.
  const std::map<std::string, ModelChoice>* chains = nullptr;
  /// Buildings without models: skip with a warning instead of failing.
  bool skip_missing = false;
  int threads = 0;  ///< 0 = all cores; the output does not depend on it
  /// Throws std::invalid_argument naming the bad option.
  void validate() const;
};

struct CityJsonStats {
  std::size_t buildings = 0;   ///< features written
  std::size_t skipped = 0;     ///< manifest records skipped by split or without models
  std::size_t geometries = 0;  ///< Solids written
  std::size_t invalid = 0;  ///< kept models left out: no valid solid as written (lod::check_solid)
  std::size_t chain_objects = 0;   ///< +LodTreeModel objects (the chain beyond LoD 1.2 / 1.3 / 2.2)
  std::size_t multi_lod = 0;       ///< buildings with >= 2 geometries
  std::size_t full_semantics = 0;  ///< buildings whose every geometry has roof, wall and ground
  std::size_t triangulated =
      0;  ///< geometries written from the PLY's triangles (no usable OBJ, or welding needed them)
  std::size_t coloured = 0;  ///< geometries with the input's colours (material theme "rgb")
  std::size_t vertices = 0;  ///< written, over all features (deduplicated per feature)
  std::size_t bytes = 0;     ///< file size
  std::string
      reference_system;  ///< metadata.referenceSystem ("" when unknown: no CRS / no EPSG code)
  double seconds = 0;
  std::vector<std::string> warnings;  ///< skipped buildings, invalid solids
};

/// Writes `out_path` (CityJSONSeq) from the work directory `work_dir`. The file
/// is staged next to it and renamed when complete. Throws io::IoError /
/// std::runtime_error with a one-line message (missing manifest, building
/// without models unless skip_missing, unreadable model, georeferencing that
/// cannot be reproduced). Progress: task "cityjson".
CityJsonStats write_cityjson(const std::string& work_dir, const std::string& out_path,
                             const CityJsonOptions& options = {}, const ProgressFn& progress = {});

// ------------------------------------------------------------ building blocks (tested)

/// The `lod` of a kept model (docs/cityjson.md): "1.2" for a fallback and for
/// a model whose roof faces are all horizontal at one height (the LoD1.2 block
/// of airborne runs), "1.3" for horizontal roofs at several heights, "2.2" for
/// the finest model of the chain, "2.1" for a coarser model with a sloped roof.
/// `roof_heights`: the distinct heights of its horizontal roof faces (0 when a
/// roof face is sloped).
std::string cityjson_lod(bool fallback, bool finest, bool sloped_roof, std::size_t roof_heights);

/// "https://www.opengis.net/def/crs/EPSG/0/<code>" for a CRS with an EPSG code
/// ("EPSG:28992", "EPSG:7415", a compound "EPSG:28992+5709" PROJ identifies
/// as 7415), "" otherwise (WKT without a code, local --origin scenes).
std::string cityjson_reference_system(const std::string& crs_spec);

}  // namespace citylod::tiler
