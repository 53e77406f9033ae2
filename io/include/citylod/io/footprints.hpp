// citylod::io — building footprints from any OGR vector source, read through
// GDAL (GeoPackage, SQLite/SpatiaLite, Shapefile, GeoJSON, FlatGeobuf, a
// PostgreSQL/PostGIS connection string "PG:dbname=... host=..." and whatever
// else the installed GDAL opens). GDAL stays private to io/: nothing here
// includes a GDAL header.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace citylod::io {

/// One footprint polygon.
///
/// MultiPolygons (and the several polygons a repair may produce) become one
/// feature per polygon part: the first part keeps the id "<id>", the parts
/// k >= 1 get "<id>-<k>" (source_id and part say where they came from, so a
/// caller can regroup them). One polygon per feature keeps "a building has a
/// footprint" simple for the splitter; the parts of one building share its
/// attributes.
struct FootprintFeature {
  std::string id;         ///< "<id>" or "<id>-<k>" (see above)
  std::string source_id;  ///< id of the source feature (attribute value or OGR FID)
  int part = 0;           ///< 0-based part of the source feature
  std::int64_t fid = -1;  ///< OGR feature id in the source
  /// Exterior ring first (counter-clockwise), then holes (clockwise). Rings
  /// are closed implicitly (the last vertex is not a copy of the first), have
  /// no repeated consecutive vertices and at least 3 vertices. 2D: Z dropped.
  std::vector<std::vector<std::array<double, 2>>> rings;
  /// The source feature's attributes: {"name": value}, typed (integers,
  /// reals, strings; dates and lists as strings; SQL NULL as null; unset
  /// fields left out).
  nlohmann::json attributes = nlohmann::json::object();
  bool repaired = false;  ///< the source polygon was invalid and repaired
};

struct FootprintLayer {
  std::string source;  ///< the source as given (a "PG:" password is masked)
  std::string layer;   ///< layer (table) name read
  std::string driver;  ///< GDAL driver, e.g. "GPKG", "ESRI Shapefile"
  /// "EPSG:28992" when the layer's CRS has an EPSG code, else its WKT; ""
  /// when the source has no CRS. After reprojection: the target CRS.
  std::string crs;
  std::string crs_wkt;  ///< WKT2 of the coordinates' CRS ("" when unknown)
  int crs_epsg = 0;     ///< EPSG code of the coordinates' CRS, 0 when none
  std::vector<FootprintFeature> features;
  /// One line per feature skipped or repaired, e.g. "feature 12 (b0123):
  /// invalid polygon (Self-intersection at or near point 5 5), repaired into
  /// 2 polygons" or "feature 3 (x): not a polygon (LINESTRING); skipped".
  std::vector<std::string> problems;
  std::size_t source_features = 0;  ///< features in the layer
  std::size_t skipped = 0;          ///< source features that gave no polygon
  std::size_t repaired = 0;         ///< source features repaired
};

struct FootprintReadOptions {
  /// Layer (table) name. Empty: the source's only layer (an error naming the
  /// layers when it has several).
  std::string layer;
  /// Attribute whose value is the feature id (e.g. "gml_id"); empty: the OGR
  /// FID. A feature whose id attribute is NULL gets its FID (and a problem line).
  std::string id_attribute;
  /// When set ("EPSG:28992", "EPSG:4326", a WKT): coordinates are reprojected
  /// into it (x = easting / longitude, y = northing / latitude). The source
  /// must then have a CRS.
  std::string target_crs;
  /// Repair invalid polygons with GEOS (OGRGeometry::MakeValid); when false or
  /// GEOS is missing, invalid polygons are reported and skipped.
  bool repair = true;
};

/// Reads the polygons of one layer of an OGR source. Non-polygon, empty,
/// zero-area and unrepairable features are skipped and reported in
/// problems; the read continues. Throws IoError naming the source when it
/// cannot be opened, the layer or the id attribute does not exist (the
/// message lists the ones that do), or the target CRS is unusable.
FootprintLayer read_footprints(const std::string& source, const FootprintReadOptions& options = {});

/// Layer names of an OGR source (for messages and `citylod info`). Throws IoError.
std::vector<std::string> footprint_layers(const std::string& source);

/// True when the installed GDAL can repair invalid polygons (built with GEOS).
bool footprint_repair_available();

/// "GDAL 3.6.2, GEOS yes" (for run reports).
std::string footprint_reader_version();

}  // namespace citylod::io
