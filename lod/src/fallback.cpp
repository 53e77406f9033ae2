#include "fallback.hpp"

#include <algorithm>
#include <cmath>

namespace citylod::lod::detail {
namespace {

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

/// Andrew's monotone chain; CCW, no collinear points.
std::vector<Vec2> convex_hull(std::vector<Vec2> p) {
  std::sort(p.begin(), p.end(), [](const Vec2& a, const Vec2& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  std::vector<Vec2> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  h.resize(k - 1);
  return h;
}

}  // namespace

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
  m.kind = ModelKind::Fallback;
  const int n = int(hull.size());
  auto& V = m.polygons.vertices;
  for (const auto& q : hull) V.emplace_back(q.x(), q.y(), zmin);
  for (const auto& q : hull) V.emplace_back(q.x(), q.y(), ztop);
  std::vector<int> bottom, top;
  for (int i = n - 1; i >= 0; --i) bottom.push_back(i);  // CW from above = outward (down)
  for (int i = 0; i < n; ++i) top.push_back(n + i);
  m.polygons.faces.push_back(bottom);
  m.polygons.faces.push_back(top);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.polygons.faces.push_back({i, j, n + j, n + i});
  }
  m.mesh.vertices = V;
  for (const auto& f : m.polygons.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) m.mesh.triangles.push_back({f[0], f[k], f[k + 1]});
  m.volume = area / 2 * (ztop - zmin);
  return m;
}

}  // namespace citylod::lod::detail
