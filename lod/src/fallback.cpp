#include "fallback.hpp"

#include "citylod/lod/polygon2d.hpp"

#include <algorithm>
#include <cmath>

namespace citylod::lod::detail {
using poly2::convex_hull;  // citylod/lod/polygon2d.hpp

LodModel extruded_outline(const BuildingInput& in) {
  std::vector<Vec2> xy;
  if (in.footprint.size() >= 3) {
    xy = in.footprint;
  } else {
    xy.reserve(in.points.size());
    for (const auto& p : in.points) xy.emplace_back(p.x(), p.y());
  }
  const std::vector<Vec2> hull = convex_hull(xy);
  double area = 0.0;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Vec2& a = hull[i];
    const Vec2& b = hull[(i + 1) % hull.size()];
    area += a.x() * b.y() - b.x() * a.y();
  }
  if (hull.size() < 3 || area / 2 < 1e-6)
    throw LodError("fallback", "the points span no area in plan view");
  std::vector<double> zs;
  zs.reserve(in.points.size());
  for (const auto& p : in.points) zs.push_back(p.z());
  std::sort(zs.begin(), zs.end());
  const double zmin = in.has_ground_z ? std::min(in.ground_z, zs.front()) : zs.front();
  double ztop = zs[size_t(0.95 * double(zs.size() - 1))];
  if (ztop - zmin < 0.5) ztop = std::max(zs.back(), zmin + 0.5);

  LodModel m;
  m.kind = ModelKind::fallback;
  m.polygons = prism_polygons(hull, zmin, ztop);
  m.mesh.vertices = m.polygons.vertices;
  for (const auto& f : m.polygons.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) m.mesh.triangles.push_back({f[0], f[k], f[k + 1]});
  m.volume = area / 2 * (ztop - zmin);
  return m;
}

PolygonMesh prism_polygons(const std::vector<Vec2>& ring, double z0, double z1) {
  PolygonMesh pm;
  const int n = int(ring.size());
  for (const auto& q : ring) pm.vertices.emplace_back(q.x(), q.y(), z0);
  for (const auto& q : ring) pm.vertices.emplace_back(q.x(), q.y(), z1);
  std::vector<int> bottom, top;
  for (int i = n - 1; i >= 0; --i) bottom.push_back(i);  // CW from above = outward (down)
  for (int i = 0; i < n; ++i) top.push_back(n + i);
  pm.faces.push_back(bottom);
  pm.faces.push_back(top);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    pm.faces.push_back({i, j, n + j, n + i});
  }
  return pm;
}

}  // namespace citylod::lod::detail
