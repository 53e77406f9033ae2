// The shared option declarations / parsing of the split, lod and assemble
// stages (see stage_options.hpp).
#include "stage_options.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace citylod::app {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return std::string(b);
}
}  // namespace

// ------------------------------------------------------------ split
void declare_split_options(ArgParser& args) {
  const SplitOptions d;
  args.option("crs", 0, "CRS",
              "CRS of the input: EPSG:nnnn, WKT or PROJ string (default: from the LAS file)")
      .option("origin", 0, "LAT,LON,H",
              "data in local ENU metres at this origin (degrees, ellipsoidal m)")
      .option("geoid", 0, "MODEL", "input heights are orthometric on MODEL (egm96)")
      .option("vertical", 0, "MODE",
              "input heights: auto (from the CRS; RD New -> NAP), ellipsoidal or orthometric",
              "auto")
      .option("footprints", 0, "SOURCE",
              "building footprints: any OGR source (GeoPackage, SQLite, Shapefile, GeoJSON, "
              "FlatGeobuf, PG:...), reprojected to the scene CRS")
      .option("footprints-layer", 0, "NAME",
              "layer (table) of --footprints (default: the only one)")
      .option("footprints-id", 0, "ATTRIBUTE",
              "attribute holding the building id (default: id, ID, identificatie, gml_id, fid, "
              "else the feature id)")
      .option("unmatched", 0, "drop|segment",
              "building points outside every footprint: dropped (counted) or clustered into "
              "buildings without footprint",
              "drop")
      .option("footprint-buffer", 0, "M", "points this close outside a footprint belong to it",
              num(d.footprint_buffer))
      .option("offset", 0, "X,Y[,Z]",
              "added to every input coordinate before --crs (tiles in a shifted frame; default: "
              "a metadata.xml <SRSOrigin>)")
      .option("memory-limit", 'm', "SIZE", "memory budget, e.g. 512M, 2G", "2G")
      .option("cell-size", 0, "M", "grid cell size", num(d.cell_size))
      .option("halo", 0, "M", "margin loaded around each cell", num(d.halo))
      .option("max-halo", 0, "M", "halo growth limit for buildings larger than the halo",
              num(d.max_halo))
      .option("min-height", 0, "M", "building points lie this high above the ground",
              num(d.seg.min_height))
      .option("min-area", 0, "M2", "smaller clusters are not buildings", num(d.seg.min_area))
      .option("cluster-tolerance", 0, "M", "clustering distance", num(d.seg.cluster_tolerance))
      .option("dtm-window", 0, "M", "ground filter window (without a ground class)",
              num(d.seg.dtm_window))
      .flag("ignore-classes", 0, "segment as if the input had no LAS classes");
}

SplitOptions parse_split_options(const ArgParser& args, const std::vector<std::string>& inputs,
                                 const std::string& work_dir) {
  SplitOptions o;
  o.inputs = inputs;
  o.work_dir = work_dir;
  o.crs = args.get("crs");
  o.origin = args.get("origin");
  o.offset = args.get("offset");
  o.footprints = args.get("footprints");
  o.footprints_layer = args.get("footprints-layer");
  o.footprints_id = args.get("footprints-id");
  const std::string um = args.get("unmatched");
  if (um == "segment")
    o.unmatched = SplitOptions::Unmatched::segment;
  else if (um != "drop")
    throw UsageError("--unmatched: expected drop or segment, got '" + um + "'");
  o.footprint_buffer = args.get_double("footprint-buffer");
  o.cell_size = args.get_double("cell-size");
  o.halo = args.get_double("halo");
  o.max_halo = std::max(args.get_double("max-halo"), o.halo);
  o.seg.min_height = args.get_double("min-height");
  o.seg.min_area = args.get_double("min-area");
  o.seg.cluster_tolerance = args.get_double("cluster-tolerance");
  o.seg.dtm_window = args.get_double("dtm-window");
  o.ignore_classes = args.has("ignore-classes");
  usage_errors([&] {
    o.geoid = parse_geoid(args.get("geoid"));
    o.vertical = parse_vertical(args.get("vertical"));
    o.memory_limit = parse_memory_size(args.get("memory-limit"));
    // a lower bound: tiny cells multiply the grid (and split's work) without end
    if (!(o.cell_size >= 10))
      throw std::invalid_argument(
          "--cell-size must be at least 10 m (the size split's automatic reduction stops at)");
    o.validate();
  });
  return o;
}

// ------------------------------------------------------------ lod
void declare_lod_param_options(ArgParser& args, const lod::LodParams& defaults,
                               const lod::LodParams* city) {
  args.option("set", 's', "NAME=VALUE[,...]",
              "override parameters, e.g. planes.epsilon=0.2,tree.merge_k=8");
  args.option("config", 'c', "FILE", "JSON object of parameters (as written to params.json)");
  // The parameters' table, from their one declaration (lod/src/params.cpp: visit).
  std::string t = "LOD parameters (--set NAME=VALUE; the paper's defaults";
  t += city ? "; a work directory's buildings start from the city values):\n"
            : ", as this command uses them):\n";
  const std::vector<lod::ParamInfo> d = defaults.describe();
  const std::vector<lod::ParamInfo> c = city ? city->describe() : d;
  // 0.15, not params.json's round-trip 0.14999999999999999
  const auto shown = [](const std::string& v) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || *end != '\0') return v;
    char b[32];
    std::snprintf(b, sizeof b, "%.10g", x);
    return std::string(b);
  };
  for (std::size_t i = 0; i < d.size(); ++i) {
    std::string left = d[i].name + " = " + shown(d[i].value);
    if (!d[i].unit.empty()) left += " " + d[i].unit;
    if (c[i].value != d[i].value) left += " (city: " + shown(c[i].value) + ")";
    left = "  " + left;
    if (left.size() < 50)
      left.resize(50, ' ');
    else
      left += "\n" + std::string(50, ' ');
    t += left + d[i].rule + "\n";
    t += "      " + d[i].doc + "\n";  // what it does, on a line of its own
  }
  args.epilog(t);
}

lod::LodParams parse_lod_params(const ArgParser& args, lod::LodParams params) {
  if (args.has("config")) apply_lod_config(params, args.get("config"));
  if (args.has("set")) usage_errors([&] { apply_lod_settings(params, args.get("set")); });
  return params;
}

// ------------------------------------------------------------ threads
void declare_threads_option(ArgParser& args, const std::string& what) {
  args.option("threads", 't', "N", what + " (0 = all cores); the output does not depend on it",
              "0");
}

int parse_threads(const ArgParser& args) {
  const auto threads = args.get_int("threads");
  if (threads < 0) throw UsageError("--threads must be >= 0 (0 = all cores)");
  return int(threads);
}

// ------------------------------------------------------------ assemble
void declare_assemble_options(ArgParser& args) {
  const AssembleParams d;  // the defaults, declared once (assemble.hpp)
  args.option("max-triangles", 0, "N", "triangle budget of one tile glb",
              std::to_string(d.max_tile_triangles));
  args.option("max-bytes", 0, "BYTES", "geometry byte budget of one tile glb",
              std::to_string(d.max_tile_bytes));
  args.option(
      "extent-factor", 0, "F",
      "children of a tile with error e span at most F*e metres each (0 = only the budgets split)",
      num(d.tile_extent_factor));
  args.option("min-tile-extent", 0, "M",
              "... but at least M metres: leaves gather the buildings of such a block",
              num(d.min_tile_extent_m));
  args.option("max-tiles-per-file", 0, "N",
              "tileset JSON files of at most about N tiles (larger subtrees: external tilesets)",
              std::to_string(d.max_tiles_per_file));
  args.option("min-leaf-bytes", 0, "B",
              "buildings reaching their finest model get leaves of their own (stored once) when "
              "they total >= B bytes of geometry (else they are repeated down the chain)",
              std::to_string(d.min_leaf_bytes));
  args.option("min-change", 0, "M",
              "keep an interpolation model only if it differs by >= M metres (Hausdorff) from its "
              "kept neighbours",
              num(d.min_change_m));
  args.option("hausdorff-tolerance", 0, "M",
              "accuracy of the Hausdorff distances between models, metres",
              num(d.hausdorff_tolerance_m));
  args.flag("quantize", 0, "KHR_mesh_quantization: int16 positions and normals (smaller glbs)");
  args.option("compression", 0, "none|meshopt",
              "glb geometry: EXT_meshopt_compression with quantized positions and normals "
              "(meshopt), or plain accessors (none)",
              io::to_string(d.compression));
  args.flag("building-models", 0,
            "also write buildings/*.glb, every kept model of a building in one file (the viewer's "
            "LOD slider reads the models from the tiles)");
  args.flag("skip-missing", 0, "skip buildings without LOD models (warning) instead of failing");
}

AssembleParams parse_assemble_options(const ArgParser& args) {
  AssembleParams p;
  const auto max_tris = args.get_int("max-triangles");
  const auto max_bytes = args.get_int("max-bytes");
  if (max_tris < 1) throw UsageError("--max-triangles must be >= 1");
  if (max_bytes < 1024) throw UsageError("--max-bytes must be >= 1024");
  p.max_tile_triangles = std::size_t(max_tris);
  p.max_tile_bytes = std::size_t(max_bytes);
  p.tile_extent_factor = args.get_double("extent-factor");
  p.min_tile_extent_m = args.get_double("min-tile-extent");
  const std::int64_t per_file = args.get_int("max-tiles-per-file");
  if (per_file < 1) throw UsageError("--max-tiles-per-file must be >= 1");
  p.max_tiles_per_file = std::size_t(per_file);
  const std::int64_t leaf_bytes = args.get_int("min-leaf-bytes");
  if (leaf_bytes < 0) throw UsageError("--min-leaf-bytes must be >= 0");
  p.min_leaf_bytes = std::size_t(leaf_bytes);
  p.min_change_m = args.get_double("min-change");
  p.hausdorff_tolerance_m = args.get_double("hausdorff-tolerance");
  p.quantize = args.has("quantize");
  usage_errors([&] { p.compression = io::compression_from_string(args.get("compression")); });
  p.building_models = args.has("building-models");
  p.skip_missing = args.has("skip-missing");
  usage_errors([&] { p.validate(); });
  return p;
}

}  // namespace citylod::app
