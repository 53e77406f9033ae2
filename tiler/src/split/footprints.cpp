// GeoJSON footprint reader and 2D polygon helpers.
#include "citylod/tiler/footprints.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "citylod/io/error.hpp"
#include "citylod/lod/polygon2d.hpp"

namespace citylod::tiler {

using nlohmann::json;

// ------------------------------------------------------------------ 2D geometry
// (citylod/lod/polygon2d.hpp)
double signed_area(const Ring& r) {
  return poly2::signed_area(r);
}

double polygon_area(const Polygon2& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.rings.size(); ++i) {
    const double ai = std::abs(signed_area(p.rings[i]));
    a += i == 0 ? ai : -ai;
  }
  return a;
}

bool point_in_ring(const Ring& r, const Vec2& p) {
  return poly2::point_in_ring(r, p);
}

bool point_in_polygon(const Polygon2& p, const Vec2& q) {
  if (p.rings.empty() || !point_in_ring(p.rings[0], q)) return false;
  for (std::size_t i = 1; i < p.rings.size(); ++i)
    if (point_in_ring(p.rings[i], q)) return false;
  return true;
}

bool point_in_footprint(const Footprint& f, const Vec2& q) {
  if (q[0] < f.bbox[0] || q[0] > f.bbox[2] || q[1] < f.bbox[1] || q[1] > f.bbox[3]) return false;
  for (const auto& p : f.polygons)
    if (point_in_polygon(p, q)) return true;
  return false;
}

double distance_to_ring(const Ring& r, const Vec2& p) {
  return poly2::distance_to_ring(r, p);
}

double distance_to_footprint(const Footprint& f, const Vec2& p) {
  if (point_in_footprint(f, p)) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (const auto& poly : f.polygons)
    for (const auto& r : poly.rings) best = std::min(best, distance_to_ring(r, p));
  return best;
}

void normalise(Polygon2& p) {
  for (std::size_t i = 0; i < p.rings.size(); ++i) {
    Ring& r = p.rings[i];
    while (r.size() > 1 && r.front() == r.back()) r.pop_back();
    const bool ccw = signed_area(r) > 0;
    if ((i == 0) != ccw) std::reverse(r.begin(), r.end());
  }
}

Ring convex_hull(std::vector<Vec2> pts) {
  return poly2::convex_hull(std::move(pts));
}

// ------------------------------------------------------------------ Footprint
void Footprint::update_bbox() {
  const double inf = std::numeric_limits<double>::infinity();
  bbox = {inf, inf, -inf, -inf};
  for (const auto& p : polygons)
    for (const auto& r : p.rings)
      for (const auto& v : r) {
        bbox[0] = std::min(bbox[0], v[0]);
        bbox[1] = std::min(bbox[1], v[1]);
        bbox[2] = std::max(bbox[2], v[0]);
        bbox[3] = std::max(bbox[3], v[1]);
      }
}

const Ring& Footprint::main_ring() const {
  static const Ring kEmpty;
  const Ring* best = &kEmpty;
  double best_a = -1;
  for (const auto& p : polygons) {
    if (p.rings.empty()) continue;
    const double a = std::abs(signed_area(p.rings[0]));
    if (a > best_a) {
      best_a = a;
      best = &p.rings[0];
    }
  }
  return *best;
}

double Footprint::area() const {
  double a = 0;
  for (const auto& p : polygons) a += polygon_area(p);
  return a;
}

Vec2 Footprint::centroid() const {
  double sx = 0, sy = 0, sa = 0;
  for (const auto& p : polygons) {
    if (p.rings.empty()) continue;
    const Ring& r = p.rings[0];
    const std::size_t n = r.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2& a = r[i];
      const Vec2& b = r[(i + 1) % n];
      const double c = a[0] * b[1] - b[0] * a[1];
      sx += (a[0] + b[0]) * c;
      sy += (a[1] + b[1]) * c;
      sa += c;
    }
  }
  if (std::abs(sa) < 1e-12) return {0.5 * (bbox[0] + bbox[2]), 0.5 * (bbox[1] + bbox[3])};
  return {sx / (3 * sa), sy / (3 * sa)};
}

// ------------------------------------------------------------------ GeoJSON
namespace {

Ring parse_ring(const std::string& path, const json& j) {
  if (!j.is_array())
    throw io::IoError(path, "malformed GeoJSON: a ring is not an array of positions");
  Ring r;
  r.reserve(j.size());
  for (const auto& pos : j) {
    if (!pos.is_array() || pos.size() < 2 || !pos[0].is_number() || !pos[1].is_number())
      throw io::IoError(path, "malformed GeoJSON: a position is not [x, y]");
    const Vec2 v{pos[0].get<double>(), pos[1].get<double>()};
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]))
      throw io::IoError(path, "malformed GeoJSON: non-finite coordinate");
    r.push_back(v);
  }
  while (r.size() > 1 && r.front() == r.back()) r.pop_back();
  return r;
}

Polygon2 parse_polygon(const std::string& path, const json& coords) {
  if (!coords.is_array())
    throw io::IoError(path, "malformed GeoJSON: Polygon coordinates are not an array");
  Polygon2 p;
  for (const auto& ring : coords) {
    Ring r = parse_ring(path, ring);
    if (r.size() >= 3)
      p.rings.push_back(std::move(r));
    else if (p.rings.empty())
      return {};  // degenerate exterior: drop the polygon
  }
  normalise(p);
  return p;
}

std::string crs_from_member(const json& root) {
  if (!root.contains("crs") || !root["crs"].is_object()) return {};
  const json& c = root["crs"];
  if (!c.contains("properties") || !c["properties"].contains("name")) return {};
  std::string name = c["properties"]["name"].get<std::string>();
  // urn:ogc:def:crs:EPSG::28992 -> EPSG:28992; urn:ogc:def:crs:OGC:1.3:CRS84 -> OGC:CRS84
  const std::string urn = "urn:ogc:def:crs:";
  if (name.rfind(urn, 0) == 0) {
    std::string rest = name.substr(urn.size());  // "EPSG::28992" or "OGC:1.3:CRS84"
    const auto first = rest.find(':');
    const auto last = rest.rfind(':');
    if (first != std::string::npos) return rest.substr(0, first) + ":" + rest.substr(last + 1);
  }
  return name;
}

std::string id_of(const json& feature, std::size_t index) {
  auto str = [](const json& v) -> std::string {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    if (v.is_number_unsigned()) return std::to_string(v.get<unsigned long long>());
    if (v.is_number()) return v.dump();
    return {};
  };
  if (feature.contains("properties") && feature["properties"].is_object()) {
    const json& p = feature["properties"];
    for (const char* key : {"id", "ID", "identificatie", "fid"})
      if (p.contains(key)) {
        std::string s = str(p[key]);
        if (!s.empty()) return s;
      }
  }
  if (feature.contains("id")) {
    std::string s = str(feature["id"]);
    if (!s.empty()) return s;
  }
  return std::to_string(index + 1);
}

}  // namespace

FootprintSet read_footprints_geojson(const std::string& path, int* skipped) {
  std::ifstream in(path);
  if (!in) throw io::IoError(path, "cannot open footprint file");
  json root;
  try {
    in >> root;
  } catch (const std::exception& e) {
    throw io::IoError(path, std::string("not valid JSON: ") + e.what());
  }
  if (!root.is_object() || !root.contains("type"))
    throw io::IoError(path, "not a GeoJSON object (no \"type\")");
  FootprintSet set;
  set.crs = crs_from_member(root);

  std::vector<json> features;
  const std::string type = root["type"].is_string() ? root["type"].get<std::string>() : "";
  if (type == "FeatureCollection") {
    if (!root.contains("features") || !root["features"].is_array())
      throw io::IoError(path, "GeoJSON FeatureCollection without a \"features\" array");
    for (const auto& f : root["features"]) features.push_back(f);
  } else if (type == "Feature") {
    features.push_back(root);
  } else if (type == "Polygon" || type == "MultiPolygon") {
    features.push_back(json{{"type", "Feature"}, {"geometry", root}});
  } else {
    throw io::IoError(path,
                      "unsupported GeoJSON type '" + type + "' (expected a FeatureCollection)");
  }

  int n_skipped = 0;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const json& f = features[i];
    if (!f.is_object() || !f.contains("geometry") || !f["geometry"].is_object()) {
      ++n_skipped;
      continue;
    }
    const json& g = f["geometry"];
    const std::string gt = g.value("type", "");
    if (!g.contains("coordinates")) {
      ++n_skipped;
      continue;
    }
    Footprint fp;
    fp.id = id_of(f, i);
    if (gt == "Polygon") {
      Polygon2 p = parse_polygon(path, g["coordinates"]);
      if (!p.rings.empty()) fp.polygons.push_back(std::move(p));
    } else if (gt == "MultiPolygon") {
      if (!g["coordinates"].is_array())
        throw io::IoError(path, "malformed GeoJSON: MultiPolygon coordinates are not an array");
      for (const auto& pc : g["coordinates"]) {
        Polygon2 p = parse_polygon(path, pc);
        if (!p.rings.empty()) fp.polygons.push_back(std::move(p));
      }
    } else {
      ++n_skipped;
      continue;
    }
    if (fp.polygons.empty()) {
      ++n_skipped;
      continue;
    }
    fp.update_bbox();
    set.footprints.push_back(std::move(fp));
  }
  if (skipped) *skipped = n_skipped;
  return set;
}

}  // namespace citylod::tiler
