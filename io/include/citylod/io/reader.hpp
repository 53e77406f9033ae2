// Streaming readers for point clouds and meshes.
//
//   auto reader = citylod::io::PointReader::open("scene.las");   // header only
//   citylod::io::PointSet batch;
//   while (reader->read(batch, 1 << 20) > 0) { ... }             // bounded memory
//
// Formats: PLY (ascii, binary little/big endian), OBJ, OFF (NOFF/COFF), XYZ/PTS
// text, LAS 1.0-1.4 (point formats 0-10), LAZ and COPC (our own LASzip decoder:
// point formats 0-3 and 6-8 plus extra bytes; waveform packets are refused;
// FileInfo::compressed = true). The format is detected from the magic bytes,
// falling back to the extension. Every failure throws IoError("<file>: <reason>").
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "citylod/io/error.hpp"
#include "citylod/io/types.hpp"

namespace citylod::io {

enum class Format { unknown, ply, obj, off, xyz, las, laz };

/// Lower-case short name: "PLY", "OBJ", "OFF", "XYZ", "LAS", "LAZ", "unknown".
const char* format_name(Format f);

/// Detects the format of an existing file (magic bytes first, then extension).
/// Returns Format::unknown when neither matches; throws IoError if the file
/// cannot be opened.
Format detect_format(const std::string& path);

/// The path's extension, lower-case, without the dot ("" when none).
std::string extension_of(const std::string& path);

/// What a file says about itself (from the header) and, after scan_file(),
/// what streaming all of it found.
struct FileInfo {
  std::string path;
  Format format = Format::unknown;
  std::string format_name;  ///< "PLY", "LAS", ...
  std::string version;      ///< "1.2" for LAS, "1.0" for PLY, "" if none
  std::string encoding;     ///< PLY: "ascii", "binary_little_endian", ...; text/binary otherwise
  std::uint64_t point_count = 0;       ///< points (point clouds) or vertices (meshes)
  std::uint64_t face_count = 0;        ///< faces as stored (polygons, not triangles)
  bool has_faces = false;              ///< the file has a face element / face records
  std::uint32_t max_face_corners = 0;  ///< most vertices of a face (once the faces were read)

  BBox3 bbox;                     ///< computed by streaming (scan_file) or taken from the header
  bool bbox_from_header = false;  ///< true when bbox comes from the LAS header (not scanned)
  bool scanned = false;           ///< true after scan_file() streamed every point

  bool has_normals = false;
  bool has_colors = false;
  bool has_classes = false;
  std::vector<std::string>
      extra_attributes;  ///< attributes read but not kept (intensity, label, ...)

  // LAS / LAZ
  int las_point_format = -1;  ///< 0..10, -1 if not LAS
  std::uint32_t las_record_length = 0;
  Vec3d scale{0, 0, 0};
  Vec3d offset{0, 0, 0};
  bool compressed = false;                    ///< LASzip
  std::map<int, std::uint64_t> class_counts;  ///< class code -> points (LAS, after scan)
  std::string system_id;
  std::string generating_software;

  // CRS, if the file carries one (LAS VLR/EVLR)
  std::string crs_wkt;   ///< OGC WKT (record 2112), verbatim
  std::string crs_name;  ///< PROJCS/GEOGCS name from WKT, or GeoTIFF citation
  int epsg = 0;  ///< from GeoTIFF keys (3072 projected, else 2048 geographic) or WKT AUTHORITY
  int vertical_epsg = 0;       ///< GeoTIFF VerticalCSTypeGeoKey 4096
  std::string linear_unit;     ///< "metre", "foot", "US survey foot", ... ("" = unknown)
  double linear_unit_m = 0;    ///< metres per unit (0 = unknown)
  std::string vertical_unit;   ///< GeoTIFF VerticalUnitsGeoKey 4099
  double vertical_unit_m = 0;  ///< metres per vertical unit (0 = unknown)
  bool has_crs() const { return !crs_wkt.empty() || epsg != 0 || !crs_name.empty(); }
};

/// Human name of an ASPRS LAS class ("ground", "building", ...) or "" if unknown.
const char* las_class_name(int code);

/// Progress callback: fraction in [0,1], stage name; return false to cancel
/// (the reader then throws IoError "cancelled").
using ProgressFn = bool (*)(double fraction, const char* stage, void* user);

/// Streaming point reader. For mesh formats the points are the vertices.
class PointReader {
 public:
  virtual ~PointReader() = default;

  /// Opens `path`, detects the format, reads and validates the header (counts
  /// against the file size, scale factors, ...). Throws IoError.
  static std::unique_ptr<PointReader> open(const std::string& path);

  /// Header information (counts as declared; bbox from the header for LAS).
  const FileInfo& info() const { return info_; }

  /// Clears `batch` and fills it with up to `max_points` (> 0) next points.
  /// Returns the number of points read; 0 means the end of the file.
  /// Attributes that the file has are filled for every point.
  virtual std::size_t read(PointSet& batch, std::size_t max_points) = 0;

  /// Points delivered so far.
  std::uint64_t points_read() const { return points_read_; }
  /// Fraction of the point data consumed, in [0,1].
  virtual double progress() const = 0;

 protected:
  FileInfo info_;
  std::uint64_t points_read_ = 0;
};

/// Reads only the header (cheap): counts as declared, LAS header bbox, CRS.
FileInfo read_header(const std::string& path);

/// Streams the whole file with bounded memory and returns the header info
/// completed with the scanned bbox, point count and LAS class counts. Also
/// validates faces (index range) for mesh files. Throws IoError on any defect.
FileInfo scan_file(const std::string& path, ProgressFn progress = nullptr, void* user = nullptr);

/// Reads all points of a file into memory (convenience for small files).
PointSet read_points(const std::string& path);

/// Reads a mesh (PLY with a face element, OBJ, OFF). Polygons keep all their
/// vertices. Throws IoError if the file has no faces or an index is out of range.
PolygonMesh read_polygon_mesh(const std::string& path);

/// Streams a mesh (PLY with a face element, OFF, OBJ) with bounded memory: its vertices
/// in batches, then its faces in batches, in file order (a caller keeps what it needs):
///
///   auto m = citylod::io::MeshReader::open("scene.ply");
///   while (m->read_vertices(batch, 1 << 16) > 0) { ... }
///   while (m->read_faces(faces, 1 << 16) > 0) { ... }   // triangulate_face() per face
///
/// The same vertices, attributes and faces as read_mesh() before triangulation (OBJ:
/// positions only; its faces come from a second pass over the file). Every defect
/// throws IoError("<file>: <reason>") as the whole-file readers do.
class MeshReader {
 public:
  static std::unique_ptr<MeshReader> open(const std::string& path);
  ~MeshReader();
  MeshReader(const MeshReader&) = delete;
  MeshReader& operator=(const MeshReader&) = delete;

  /// Header information (OBJ: counts known once read_faces() started).
  const FileInfo& info() const { return info_; }
  /// Clears `batch` and fills it with up to `max_vertices` next vertices; 0 at the end.
  std::size_t read_vertices(PointSet& batch, std::size_t max_vertices);
  /// Clears `batch` and fills it with up to `max_faces` next faces (validated 0-based
  /// indices); 0 at the end. Reads (and drops) the vertices not yet read first.
  std::size_t read_faces(FaceBatch& batch, std::size_t max_faces);

 private:
  MeshReader();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  FileInfo info_;
};

/// Like read_polygon_mesh(), with polygons triangulated (triangulate_polygons). Per-vertex
/// normals/colours are kept when the file has them (PLY/OFF vertex attributes; OBJ vn referenced by
/// faces).
TriangleMesh read_mesh(const std::string& path);
/// read_mesh() of a file known to be `format` (not detected: a file of another format
/// is that format's reader's IoError), e.g. the models a program wrote itself.
TriangleMesh read_mesh(const std::string& path, Format format);

}  // namespace citylod::io
