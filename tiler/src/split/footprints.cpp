// Footprints from OGR sources (through io::read_footprints) and 2D polygon helpers.
#include "citylod/tiler/footprints.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "citylod/io/footprints.hpp"
#include "citylod/lod/polygon2d.hpp"

namespace citylod::tiler {

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

double area_inside(const Footprint& f, const Ring& convex) {
  if (convex.size() < 3) return 0;
  double total = 0;
  Ring cur, next;
  for (const auto& poly : f.polygons)
    for (const auto& ring : poly.rings) {
      cur = ring;
      // Clip by each edge a->b of the convex ring: keep the left side (CCW interior).
      for (std::size_t e = 0; e < convex.size() && !cur.empty(); ++e) {
        const Vec2& a = convex[e];
        const Vec2& b = convex[(e + 1) % convex.size()];
        const auto side = [&](const Vec2& q) {
          return (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]);
        };
        next.clear();
        for (std::size_t i = 0; i < cur.size(); ++i) {
          const Vec2& p = cur[i];
          const Vec2& q = cur[(i + 1) % cur.size()];
          const double sp = side(p), sq = side(q);
          if (sp >= 0) next.push_back(p);
          if ((sp >= 0) != (sq >= 0)) {
            const double t = sp / (sp - sq);
            next.push_back({p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])});
          }
        }
        cur.swap(next);
      }
      if (cur.size() >= 3) total += signed_area(cur);
    }
  return total;
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
  // A bowtie's lobes cancel (issue 13: its "centroid" landed km away): the bbox centre.
  const Vec2 mid{0.5 * (bbox[0] + bbox[2]), 0.5 * (bbox[1] + bbox[3])};
  const double box_area = (bbox[2] - bbox[0]) * (bbox[3] - bbox[1]);
  if (!(std::abs(sa) > 1e-9 * std::max(box_area, 1e-300))) return mid;
  const Vec2 c{sx / (3 * sa), sy / (3 * sa)};
  if (!(c[0] >= bbox[0] && c[0] <= bbox[2] && c[1] >= bbox[1] && c[1] <= bbox[3])) return mid;
  return c;
}

// ------------------------------------------------------------------ OGR sources
namespace {

/// The id a feature gets without --footprints-id (the keys the GeoJSON reader
/// used, then BGT's gml_id).
std::string default_id(const nlohmann::json& attrs, const std::string& fid) {
  for (const char* key : {"id", "ID", "identificatie", "gml_id", "fid"}) {
    const auto it = attrs.find(key);
    if (it == attrs.end() || it->is_null()) continue;
    std::string s;
    if (it->is_string())
      s = it->get<std::string>();
    else if (it->is_number_integer())
      s = std::to_string(it->get<long long>());
    else if (it->is_number_unsigned())
      s = std::to_string(it->get<unsigned long long>());
    else if (it->is_number())
      s = it->dump();
    if (!s.empty()) return s;
  }
  return fid;
}

}  // namespace

FootprintSet read_footprint_source(const std::string& source,
                                   const FootprintSourceOptions& options) {
  io::FootprintReadOptions ro;
  ro.layer = options.layer;
  ro.id_attribute = options.id_attribute;
  ro.repair = options.repair;
  io::FootprintLayer layer = io::read_footprints(source, ro);
  FootprintSet set;
  set.source = layer.source;
  set.layer = layer.layer;
  set.driver = layer.driver;
  set.crs = layer.crs;
  set.problems = std::move(layer.problems);
  set.source_features = layer.source_features;
  set.skipped = layer.skipped;
  set.repaired = layer.repaired;
  // io gives one feature per polygon part, parts of a source feature in a row.
  for (auto& f : layer.features) {
    Polygon2 p;
    p.rings = std::move(f.rings);
    normalise(p);
    if (f.part > 0 && !set.footprints.empty()) {
      set.footprints.back().polygons.push_back(std::move(p));
      continue;
    }
    Footprint fp;
    fp.id = options.id_attribute.empty() ? default_id(f.attributes, f.source_id) : f.source_id;
    fp.attributes = std::move(f.attributes);
    fp.repaired = f.repaired;
    fp.polygons.push_back(std::move(p));
    set.footprints.push_back(std::move(fp));
  }
  for (auto& fp : set.footprints) fp.update_bbox();
  return set;
}

}  // namespace citylod::tiler
