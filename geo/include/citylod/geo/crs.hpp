// citylod::geo::Crs — a parsed coordinate reference system and what citylod needs to know about it.
#pragma once

#include "citylod/geo/types.hpp"

#include <optional>
#include <string>
#include <vector>

namespace citylod::geo {

/// A unit of measure. `to_si` converts one unit to metres (linear) or radians (angular).
struct Unit {
  std::string name;      ///< e.g. "metre", "foot", "US survey foot", "degree"
  double to_si = 1.0;    ///< metre: 1, foot: 0.3048, US survey foot: 1200/3937
  bool angular = false;  ///< true for the degree axes of a geographic CRS
};

/// Area of use of a CRS, in degrees (WGS84 longitude/latitude), as recorded by PROJ/EPSG.
struct AreaOfUse {
  double west = 0, south = 0, east = 0, north = 0;  ///< degrees
  std::string name;                                 ///< e.g. "Netherlands - onshore, ..."
};

/// A UTM zone (from the projection parameters, whatever the datum).
struct UtmZone {
  int zone = 0;       ///< 1..60
  bool north = true;  ///< hemisphere (false: false northing 10,000 km)
};

/// GeoTIFF GeoKeys (as in the LASF_Projection 34735 VLR). 0 = key absent.
struct GeoTiffKeys {
  int model_type = 0;      ///< GTModelTypeGeoKey 1024: 1 projected, 2 geographic
  int projected_cs = 0;    ///< ProjectedCSTypeGeoKey 3072 (EPSG code; 32767 = user-defined)
  int geographic_cs = 0;   ///< GeographicTypeGeoKey 2048 (EPSG code)
  int linear_units = 0;    ///< ProjLinearUnitsGeoKey 3076: 9001 m, 9002 ft, 9003 US survey ft
  int vertical_cs = 0;     ///< VerticalCSTypeGeoKey 4096 (EPSG code of a vertical CRS)
  int vertical_units = 0;  ///< VerticalUnitsGeoKey 4099 (EPSG unit code)
};

/// A coordinate reference system, parsed once by PROJ. A plain, copyable value: it holds no
/// PROJ objects, only the definition and the facts queried from it, so it is safe to share
/// between threads. Transformations live in `Transformer`.
class Crs {
 public:
  /// Parses "EPSG:28992", "epsg:32631", "EPSG:28992+5709" (compound), a bare code "2056",
  /// OGC WKT 1/2 (as in LAS WKT VLRs), PROJJSON or a PROJ string ("+proj=utm +zone=31 ...").
  /// Throws GeoError, e.g. "unknown CRS 'EPSG:99999': PROJ has no such code".
  static Crs parse(const std::string& spec);

  /// Builds a CRS from GeoTIFF keys: the projected (or geographic) EPSG code, plus the vertical
  /// CRS when present. If the linear-unit key disagrees with the EPSG definition, the unit key
  /// wins (coordinates are read in that unit) and a warning is recorded. The vertical-unit key
  /// sets vertical_unit(). Throws GeoError for user-defined (32767) or missing codes.
  static Crs from_geotiff(const GeoTiffKeys& keys);

  const std::string& name() const { return name_; }              ///< e.g. "Amersfoort / RD New"
  const std::string& definition() const { return definition_; }  ///< what PROJ is given
  std::optional<int> epsg() const { return epsg_; }  ///< EPSG code of the whole CRS, if known
  /// "EPSG:28992" when the code is known, else the name; for messages.
  std::string label() const;

  bool is_projected() const { return projected_; }
  bool is_geographic() const { return geographic_; }
  /// True when heights have a datum of their own (compound CRS such as EPSG:7415 = RD + NAP).
  bool has_vertical_datum() const { return has_vertical_; }
  /// Name of the vertical CRS when has_vertical_datum(), e.g. "NAP height".
  const std::string& vertical_name() const { return vertical_name_; }

  /// Unit of the horizontal axes (x, y). Linear for projected CRSes, angular for geographic.
  const Unit& horizontal_unit() const { return horizontal_unit_; }
  /// Unit of z. From the vertical CRS or GeoTIFF key when given; otherwise the horizontal linear
  /// unit for projected CRSes (feet CRSes usually carry feet heights) and metre for geographic.
  const Unit& vertical_unit() const { return vertical_unit_; }
  /// Copy with z interpreted in another unit (e.g. a CLI override).
  Crs with_vertical_unit(const Unit& unit) const;

  /// Area of use from PROJ; for CRSes without an authority code it is taken from an identified
  /// EPSG equivalent or from the base geographic CRS, if any.
  const std::optional<AreaOfUse>& area_of_use() const { return area_; }
  /// UTM zone when the projection is UTM (any datum, metres).
  std::optional<UtmZone> utm() const { return utm_; }
  /// True for UTM on the WGS 84 datum (EPSG:326xx/327xx): eligible for the GeographicLib path.
  bool is_wgs84_utm() const { return utm_ && wgs84_datum_; }

  /// Throws GeoError ("CRS 'EPSG:4326' (WGS 84) is geographic; a projected CRS is needed ...")
  /// when the CRS is not projected. `what` names the caller's need, for the message.
  void require_projected(const std::string& what = "here") const;

  /// Non-fatal remarks made while building the CRS (unit overrides, ...). Never printed.
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  friend class CrsBuilder;
  std::string spec_, definition_, name_, vertical_name_;
  std::optional<int> epsg_;
  bool projected_ = false, geographic_ = false, has_vertical_ = false, wgs84_datum_ = false;
  Unit horizontal_unit_, vertical_unit_;
  std::optional<AreaOfUse> area_;
  std::optional<UtmZone> utm_;
  std::vector<std::string> warnings_;
};

/// Unit factors of GeoTIFF/EPSG unit codes (9001 -> metre 1, 9002 -> foot 0.3048,
/// 9003 -> US survey foot 1200/3937, any other EPSG length unit via PROJ's database).
/// Throws GeoError for an unknown code.
Unit unit_from_epsg(int code);

}  // namespace citylod::geo
