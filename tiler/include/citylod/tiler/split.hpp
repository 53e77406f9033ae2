// The split stage (`citylod split`) as a library function.
//
//   SplitOptions o;
//   o.inputs = {"tile.las"}; o.crs = "EPSG:28992"; o.work_dir = "work";
//   SplitReport r = split_scene(o, progress);   // ProgressFn, task "split"
//
// Streams the inputs (any size) into per-building chunks in WORK/chunks/<id>.ply
// and writes WORK/manifest.json (workdir.hpp), with memory bounded by
// o.memory_limit rather than by the input size:
//   pass 1  headers (LAS: header bbox; others: streamed bbox), CRS, area-of-use
//           check, scene origin (bbox centre) -> local ENU frame;
//   pass 2  points -> ENU float64 -> grid cells spilled to disk in batches;
//   pass 3  per cell + halo: ground (class 2 or grid-minimum opening), vegetation
//           (classes, or PCA scatter/planarity), buildings (footprints, or 2D
//           Euclidean clusters owned by the cell holding their centroid; the halo
//           grows while an owned cluster touches its edge), chunk files.
// Mesh inputs are streamed too: each mesh file (a tile) is read whole, its triangles
// are sampled (centroid + ~4 per m^2) into the point spill and written themselves
// (positions, vertex ids) to per-cell face files, then it is dropped; a region loads
// the faces of its cells with its samples, and the chunks' claims on triangles are
// spilled and resolved per cell at the end. A folder input stands for the PLY / OBJ /
// OFF / LAS / LAZ / XYZ files under it (sorted), read as one scene. Sidecars: a
// ContextCapture metadata.xml in a file's folder or the two above it gives the CRS
// (<SRS>: EPSG:n, WKT or ENU:lat,lon) and an offset (<SRSOrigin>) added to the
// coordinates; FILE.prj beside a file gives its CRS. --crs / --origin / --offset win.
// Memory: a region that exceeds the budget is processed as four quarter cells (halved
// while larger than kMinSplitCell, 10 m, in split_internal.hpp); only a smallest cell whose
// region (+ halo) still exceeds it fails, with one line saying so: a run that passes at one
// --memory-limit passes at every higher one.
// The samples are segmented like points. Without footprints each triangle goes to the
// cluster holding most of its samples, and a cluster with less than 20 % of its area in
// planar faces of >= 6 m^2 (its triangles grown into planar regions) is vegetation. With footprints
// each triangle is judged whole, by its geometry, and never by a foliage test: a face no steeper
// than 60 degrees goes to the footprint holding the largest share (>= 0.5) of its xy projection,
// else to the nearest footprint within footprint_buffer (eaves); a steeper face (wall) to the
// footprint it bounds (holding the point footprint_buffer behind it, against its
// outward normal; on a shared footprint edge not the one it faces); faces all on the
// ground (DTM) are not claimed (see mesh_footprint_of() in split_footprints.cpp).
// Everything is staged in WORK/.split.tmp.<pid>/ and published by rename; a
// failed run leaves WORK as it was. Re-running with identical inputs (paths,
// sizes, mtimes) and options returns up_to_date without touching WORK.
// Errors: io::IoError("<file>: <reason>") for inputs / work dir (CRS problems
// included), std::invalid_argument for bad options, Cancelled when the
// progress function returned false.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "citylod/geo/vertical.hpp"
#include "citylod/io/types.hpp"
#include "citylod/tiler/progress.hpp"
#include "citylod/tiler/segment.hpp"

namespace citylod::tiler {

struct SplitOptions {
  std::vector<std::string> inputs;  ///< point clouds / meshes (PLY, LAS, OBJ, OFF, XYZ)
  std::string work_dir;             ///< WORK
  std::string crs;                  ///< --crs; "" = the CRS inside the (LAS) file
  std::string origin;               ///< --origin "LAT,LON,H": data already in local ENU metres
  /// --geoid: input heights are orthometric on this model (-> ellipsoidal); none: not said.
  enum class Geoid { none, egm96 } geoid = Geoid::none;
  /// --offset "X,Y[,Z]": added to every input coordinate before the CRS (tiles written in
  /// a shifted frame); "" = none, or the <SRSOrigin> of a ContextCapture metadata.xml.
  std::string offset;
  /// --vertical: Auto (from the CRS: geo::choose_vertical; RD New -> NAP), Ellipsoidal,
  /// Orthometric. Tilesets always carry ellipsoidal heights.
  geo::VerticalMode vertical = geo::VerticalMode::Auto;
  /// Footprints: any OGR source (GeoPackage, SQLite, Shapefile, GeoJSON, FlatGeobuf,
  /// "PG:..."); "" = cluster the points. Reprojected from the source's CRS to the scene's.
  std::string footprints;
  std::string footprints_layer;  ///< --footprints-layer ("" = the source's only layer)
  std::string footprints_id;     ///< --footprints-id ATTRIBUTE ("" = id, gml_id, ..., FID)
  /// --unmatched: building points outside every footprint are dropped (counted), or
  /// clustered into buildings without footprint (the no-footprint segmentation).
  enum class Unmatched { drop, segment } unmatched = Unmatched::drop;
  double footprint_buffer =
      0.5;  ///< m, points (mesh faces: centroids) this close outside a footprint belong to it
  std::uint64_t memory_limit = 2ull << 30;  ///< bytes
  /// Bytes for one mesh file's vertices while its faces stream (0: half of memory_limit);
  /// more are paged from a file in the work directory through a cache of this size.
  /// The chunks do not depend on it (a manifest note says when the vertices were paged).
  std::uint64_t mesh_vertex_budget = 0;
  double cell_size = 100;         ///< m (reduced automatically when the density needs it)
  double halo = 20;               ///< m around each cell
  double max_halo = 120;          ///< m, growth limit for buildings larger than the halo
  bool ignore_classes = false;    ///< segment as if the input had no LAS classes
  bool force = false;             ///< re-split even when up to date
  int min_footprint_points = 10;  ///< fewer -> the footprint's record is "skipped"
  SegmentParams seg;
  /// Cells segmented at once (an execution setting: the chunks, the manifest and the
  /// report do not depend on it; not in canonical()). 0 = all cores.
  int threads = 0;

  /// Throws std::invalid_argument naming the option.
  void validate() const;
  /// Canonical "key=value;..." of everything that changes the output (not inputs).
  std::string canonical() const;
};

struct SplitReport {
  bool up_to_date = false;
  std::string crs;  ///< label of the CRS used ("" for --origin)
  double origin_lon = 0, origin_lat = 0, origin_h = 0;
  std::uint64_t points = 0;           ///< points / vertices read
  std::uint64_t triangles = 0;        ///< mesh triangles read
  io::BBox3 bbox;                     ///< scene ENU box of the data (metres)
  std::string class_mode;             ///< how classes were used
  double cell_size = 0;               ///< cell size actually used
  std::size_t cells = 0;              ///< non-empty cells
  std::size_t halo_growths = 0;       ///< cells reprocessed with a larger halo
  std::size_t max_region_points = 0;  ///< largest cell + halo held in memory
  std::uint64_t spill_bytes = 0;
  std::size_t chunks = 0;  ///< chunk files written
  std::size_t clusters_rejected = 0;
  std::map<std::string, std::size_t> rejected_by;  ///< "small", "low", "vegetation" -> count
  std::size_t footprints_total = 0;                ///< in the file
  std::size_t footprints_in_scene = 0;             ///< bbox meets the data bbox
  std::size_t footprints_inside = 0;               ///< entirely inside the data bbox
  std::size_t footprints_with_chunk = 0;           ///< of those in the scene
  std::size_t footprints_inside_with_chunk = 0;
  std::size_t footprints_repaired = 0;  ///< invalid polygons repaired (GEOS)
  std::size_t footprints_skipped = 0;   ///< source features that gave no polygon
  /// With footprints and a building class: class-6 points read, and those outside
  /// every footprint (+ buffer); -1 when not counted.
  std::int64_t building_points = -1, unmatched_points = -1;
  std::size_t unmatched_chunks = 0;  ///< buildings without footprint (--unmatched segment)
  std::string vertical;              ///< the height assumption (geo::VerticalChoice::assumption)
  std::vector<std::string> notes;    ///< also in the manifest's scene notes
  /// One line per owned cluster: centroid, size, features, decision (for --log-level debug).
  std::vector<std::string> cluster_log;
  double seconds = 0;
};

SplitReport split_scene(const SplitOptions& options, const ProgressFn& progress = {});

/// The words of --geoid ("" = none, "egm96") and --vertical ("" or "auto",
/// "ellipsoidal", "orthometric"); std::invalid_argument naming the option and the choices.
SplitOptions::Geoid parse_geoid(const std::string& word);
const char* to_string(SplitOptions::Geoid g);  ///< "" | "egm96"
geo::VerticalMode parse_vertical(const std::string& word);

/// "2G", "512M", "1.5GiB", "1073741824" -> bytes; throws std::invalid_argument.
std::uint64_t parse_memory_size(const std::string& s);

}  // namespace citylod::tiler
