// Part of the split stage: building footprints from any OGR source (read by
// io::read_footprints: GeoPackage, SQLite, Shapefile, GeoJSON, FlatGeobuf, PG:...)
// and their geometry (area, containment, distance, convex hull; the ring
// primitives are citylod/lod/polygon2d.hpp, shared with the LOD engine). Coordinates are whatever
// the caller puts in: the reader returns them in the source's CRS units; the split converts them
// to scene ENU metres (split/split_footprints.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace citylod::tiler {

using Vec2 = std::array<double, 2>;
using Ring = std::vector<Vec2>;  ///< closed implicitly (last != first)

/// One polygon: exterior ring first (CCW after normalise()), then holes (CW).
struct Polygon2 {
  std::vector<Ring> rings;
};

struct Footprint {
  std::string id;                  ///< see read_footprint_source()
  std::vector<Polygon2> polygons;  ///< one for Polygon, several for MultiPolygon (or a repair)
  std::array<double, 4> bbox{0, 0, 0, 0};  ///< xmin, ymin, xmax, ymax (update_bbox())
  /// The source feature's attributes, typed ({"name": value}; keys sorted).
  nlohmann::json attributes = nlohmann::json::object();
  bool repaired = false;  ///< the source polygon was invalid and repaired (GEOS MakeValid)

  void update_bbox();
  /// Exterior ring of the largest polygon (for ChunkRecord::outline).
  const Ring& main_ring() const;
  double area() const;  ///< sum of polygon areas (holes subtracted)
  /// Area-weighted centroid of the exterior rings; the bbox centre when that is
  /// degenerate (zero net area) or falls outside the bbox.
  Vec2 centroid() const;
};

struct FootprintSet {
  std::string source;  ///< as given ("PG:" password masked)
  std::string layer, driver;
  /// "EPSG:nnnn" when the layer's CRS has an EPSG code, else its WKT; "" without CRS.
  std::string crs;
  std::vector<Footprint> footprints;
  std::vector<std::string> problems;  ///< one line per feature skipped or repaired
  std::size_t source_features = 0, skipped = 0, repaired = 0;
};

struct FootprintSourceOptions {
  std::string layer;         ///< --footprints-layer ("" = the only layer)
  std::string id_attribute;  ///< --footprints-id ("" = see read_footprint_source)
  bool repair = true;        ///< invalid polygons repaired (GEOS), else reported and skipped
};

/// Reads the polygons of one layer of an OGR source through io::read_footprints:
/// one Footprint per source feature (the parts of a MultiPolygon or of a repaired
/// polygon regrouped). The id: the `id_attribute`'s value; without one, the first
/// of the attributes "id", "ID", "identificatie", "gml_id", "fid" that is set, else
/// the OGR feature id. Throws IoError naming the source.
FootprintSet read_footprint_source(const std::string& source,
                                   const FootprintSourceOptions& options = {});

// ------------------------------------------------------------------ 2D geometry
double signed_area(const Ring& r);                        ///< > 0 when CCW
double polygon_area(const Polygon2& p);                   ///< exterior minus holes
bool point_in_ring(const Ring& r, const Vec2& p);         ///< even-odd rule
bool point_in_polygon(const Polygon2& p, const Vec2& q);  ///< inside exterior, outside holes
bool point_in_footprint(const Footprint& f, const Vec2& q);
double distance_to_ring(const Ring& r, const Vec2& p);  ///< to the boundary
double distance_to_footprint(const Footprint& f,
                             const Vec2& p);  ///< 0 inside, else to the boundary
/// Area of the part of the convex CCW ring `convex` (e.g. a triangle's xy projection) that
/// lies inside the footprint: every ring of every polygon is clipped against `convex`
/// (Sutherland-Hodgman; exact for a concave subject since only the clipper must be
/// convex) and the signed areas summed, so holes subtract. Needs normalise()d polygons.
double area_inside(const Footprint& f, const Ring& convex);
/// Orients exterior rings CCW and holes CW, drops repeated closing vertices.
void normalise(Polygon2& p);
/// 2D convex hull, CCW, no collinear points (Andrew's monotone chain).
Ring convex_hull(std::vector<Vec2> pts);

}  // namespace citylod::tiler
