// Part of the split stage: building footprints (GeoJSON Polygon/MultiPolygon)
// and their geometry (area, containment, distance, convex hull; the ring
// primitives are citylod/lod/polygon2d.hpp, shared with the LOD engine). Coordinates are whatever
// the caller puts in: the reader returns them in the file's CRS units; split.cpp converts them to
// scene ENU metres.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace citylod::tiler {

using Vec2 = std::array<double, 2>;
using Ring = std::vector<Vec2>;  ///< closed implicitly (last != first)

/// One polygon: exterior ring first (CCW after normalise()), then holes (CW).
struct Polygon2 {
  std::vector<Ring> rings;
};

struct Footprint {
  std::string id;                  ///< "id" property (or feature id, or 1-based feature index)
  std::vector<Polygon2> polygons;  ///< one for Polygon, several for MultiPolygon
  std::array<double, 4> bbox{0, 0, 0, 0};  ///< xmin, ymin, xmax, ymax (update_bbox())

  void update_bbox();
  /// Exterior ring of the largest polygon (for ChunkRecord::outline).
  const Ring& main_ring() const;
  double area() const;    ///< sum of polygon areas (holes subtracted)
  Vec2 centroid() const;  ///< area-weighted centroid of the exterior rings
};

struct FootprintSet {
  std::string crs;  ///< "EPSG:nnnn" from the legacy GeoJSON "crs" member, "" if absent
  std::vector<Footprint> footprints;
};

/// Reads a GeoJSON FeatureCollection (or a single Feature / geometry) of
/// Polygon/MultiPolygon features. Other geometry types are skipped (counted in
/// `skipped`). Throws IoError("<path>: <reason>") for unreadable or malformed files.
FootprintSet read_footprints_geojson(const std::string& path, int* skipped = nullptr);

// ------------------------------------------------------------------ 2D geometry
double signed_area(const Ring& r);                        ///< > 0 when CCW
double polygon_area(const Polygon2& p);                   ///< exterior minus holes
bool point_in_ring(const Ring& r, const Vec2& p);         ///< even-odd rule
bool point_in_polygon(const Polygon2& p, const Vec2& q);  ///< inside exterior, outside holes
bool point_in_footprint(const Footprint& f, const Vec2& q);
double distance_to_ring(const Ring& r, const Vec2& p);  ///< to the boundary
double distance_to_footprint(const Footprint& f,
                             const Vec2& p);  ///< 0 inside, else to the boundary
/// Orients exterior rings CCW and holes CW, drops repeated closing vertices.
void normalise(Polygon2& p);
/// 2D convex hull, CCW, no collinear points (Andrew's monotone chain).
Ring convex_hull(std::vector<Vec2> pts);

}  // namespace citylod::tiler
