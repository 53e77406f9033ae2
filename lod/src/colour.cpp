// Input colours onto the faces of the models (colour.hpp).
#include "colour.hpp"

#include "citylod/lod/polygon2d.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

namespace citylod::lod::detail {

namespace {

constexpr long long kCellBits = 21;
constexpr long long kCellMax = (1LL << kCellBits) - 1;

/// A face's plane and its polygon in plane coordinates.
struct FacePlane {
  Vec3 n = Vec3::Zero();  ///< unit normal (zero: degenerate face)
  double d = 0;           ///< n.x + d = 0
  Vec3 u, v;              ///< in-plane basis
  std::vector<Vec2> ring;
  Vec3 lo, hi;  ///< bounding box of the face
};

FacePlane face_plane(const std::vector<Vec3>& vs, const std::vector<int>& f) {
  FacePlane P;
  Vec3 n = Vec3::Zero(), c = Vec3::Zero();
  for (size_t i = 0; i < f.size(); ++i) {  // Newell normal
    const Vec3& a = vs[size_t(f[i])];
    const Vec3& b = vs[size_t(f[(i + 1) % f.size()])];
    n += Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()),
              (a.x() - b.x()) * (a.y() + b.y()));
    c += a;
  }
  if (f.size() < 3 || !(n.norm() > 1e-12)) return P;
  P.n = n.normalized();
  c /= double(f.size());
  P.d = -P.n.dot(c);
  P.u = (std::fabs(P.n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(P.n).normalized();
  P.v = P.n.cross(P.u);
  P.lo = P.hi = vs[size_t(f[0])];
  for (int i : f) {
    const Vec3& a = vs[size_t(i)];
    P.ring.emplace_back(a.dot(P.u), a.dot(P.v));
    P.lo = P.lo.cwiseMin(a);
    P.hi = P.hi.cwiseMax(a);
  }
  return P;
}

/// Union-find root.
int root(std::vector<int>& up, int i) {
  while (up[size_t(i)] != i) i = up[size_t(i)] = up[size_t(up[size_t(i)])];
  return i;
}

/// Plane regions: faces on one plane sharing an edge (by vertex position).
std::vector<int> plane_regions(const std::vector<Vec3>& vs, const std::vector<std::vector<int>>& fs,
                               const std::vector<FacePlane>& planes) {
  std::vector<int> up(fs.size());
  std::iota(up.begin(), up.end(), 0);
  using Pt = std::array<double, 3>;
  std::map<std::pair<Pt, Pt>, int> first;  // edge -> first face
  for (size_t i = 0; i < fs.size(); ++i) {
    if (planes[i].n.isZero()) continue;
    const auto& f = fs[i];
    for (size_t k = 0; k < f.size(); ++k) {
      const Vec3& a = vs[size_t(f[k])];
      const Vec3& b = vs[size_t(f[(k + 1) % f.size()])];
      Pt pa{a.x(), a.y(), a.z()}, pb{b.x(), b.y(), b.z()};
      if (pb < pa) std::swap(pa, pb);
      const auto [it, fresh] = first.emplace(std::make_pair(pa, pb), int(i));
      if (fresh) continue;
      const FacePlane &p = planes[size_t(it->second)], &q = planes[i];
      if (p.n.dot(q.n) > 1 - 1e-6 && std::fabs(p.d - q.d) < 1e-3)
        up[size_t(root(up, int(i)))] = root(up, it->second);
    }
  }
  std::vector<int> region(fs.size());
  for (size_t i = 0; i < fs.size(); ++i) region[i] = root(up, int(i));
  return region;
}

}  // namespace

ColourSource::ColourSource(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                           const std::vector<Rgb8>& colours, const ColourParams& p)
    : p_(p) {
  if (!p.enabled || colours.size() != points.size() || normals.size() != points.size() ||
      points.empty())
    return;
  points_ = points;
  normals_ = normals;
  colours_ = colours;
  cell_ = std::max(1.0, 4 * p.distance);
  lo_ = points_.front();
  for (const auto& q : points_) lo_ = lo_.cwiseMin(q);
  std::map<long long, std::vector<int>> grid;
  for (size_t i = 0; i < points_.size(); ++i) {
    const Vec3 g = (points_[i] - lo_) / cell_;
    grid[key((long long)g.x(), (long long)g.y(), (long long)g.z())].push_back(int(i));
  }
  cells_.assign(grid.begin(), grid.end());
}

long long ColourSource::key(long long ix, long long iy, long long iz) const {
  return std::min(ix, kCellMax) | std::min(iy, kCellMax) << kCellBits |
         std::min(iz, kCellMax) << (2 * kCellBits);
}

const std::vector<int>* ColourSource::cell(long long k) const {
  const auto it = std::lower_bound(cells_.begin(), cells_.end(), k,
                                   [](const auto& c, long long x) { return c.first < x; });
  return it != cells_.end() && it->first == k ? &it->second : nullptr;
}

std::vector<Rgba8> ColourSource::faces(const std::vector<Vec3>& vertices,
                                       const std::vector<std::vector<int>>& faces) const {
  std::vector<Rgba8> out(faces.size(), Rgba8{0, 0, 0, 0});
  if (points_.empty() || faces.empty()) return out;
  std::vector<FacePlane> planes;
  planes.reserve(faces.size());
  for (const auto& f : faces) planes.push_back(face_plane(vertices, f));
  // Each point's face: the nearest face within the distance (to the polygon:
  // the plane distance when the point projects inside it); at equal
  // distances (a point beyond an edge two faces share) the face whose plane
  // is nearer, then the lower index.
  std::vector<double> best(points_.size(), std::numeric_limits<double>::infinity());
  std::vector<double> best_plane(points_.size(), std::numeric_limits<double>::infinity());
  std::vector<int> owner(points_.size(), -1);
  const double eps = p_.distance;
  const double min_cos = std::cos(p_.max_angle_deg * M_PI / 180.0) - 1e-12;
  for (size_t fi = 0; fi < faces.size(); ++fi) {
    const FacePlane& P = planes[fi];
    if (P.n.isZero()) continue;
    const Vec3 a = ((P.lo - lo_).array() - eps).matrix() / cell_;
    const Vec3 b = ((P.hi - lo_).array() + eps).matrix() / cell_;
    const long long x0 = std::max(0LL, (long long)std::floor(a.x())),
                    y0 = std::max(0LL, (long long)std::floor(a.y())),
                    z0 = std::max(0LL, (long long)std::floor(a.z()));
    const long long x1 = std::min(kCellMax, (long long)std::floor(b.x())),
                    y1 = std::min(kCellMax, (long long)std::floor(b.y())),
                    z1 = std::min(kCellMax, (long long)std::floor(b.z()));
    for (long long x = x0; x <= x1; ++x)
      for (long long y = y0; y <= y1; ++y)
        for (long long z = z0; z <= z1; ++z) {
          const std::vector<int>* c = cell(key(x, y, z));
          if (!c) continue;
          for (int i : *c) {
            const Vec3& q = points_[size_t(i)];
            const double plane = std::fabs(P.n.dot(q) + P.d);
            if (plane > eps || plane > best[size_t(i)]) continue;
            if (normals_[size_t(i)].dot(P.n) < min_cos) continue;
            const Vec2 q2(q.dot(P.u), q.dot(P.v));
            double dist = plane;
            if (!poly2::point_in_ring(P.ring, q2)) {
              const double e = poly2::distance_to_ring(P.ring, q2);
              dist = std::sqrt(plane * plane + e * e);
            }
            const size_t k = size_t(i);
            if (dist > eps || dist > best[k] || (dist == best[k] && plane >= best_plane[k]))
              continue;
            best[k] = dist;
            best_plane[k] = plane;
            owner[k] = int(fi);
          }
        }
  }
  // Per plane region: the per-channel median of its points.
  const std::vector<int> region = plane_regions(vertices, faces, planes);
  std::map<int, std::array<std::vector<std::uint8_t>, 3>> values;
  for (size_t i = 0; i < points_.size(); ++i)
    if (owner[i] >= 0) {
      auto& v = values[region[size_t(owner[i])]];
      for (size_t k = 0; k < 3; ++k) v[k].push_back(colours_[i][k]);
    }
  std::map<int, Rgba8> colour;
  for (auto& [r, v] : values) {
    if (v[0].size() < size_t(p_.min_points)) continue;
    Rgba8 c{0, 0, 0, 255};
    for (size_t k = 0; k < 3; ++k) {
      auto mid = v[k].begin() + long(v[k].size() / 2);
      std::nth_element(v[k].begin(), mid, v[k].end());
      c[k] = *mid;
    }
    colour[r] = c;
  }
  for (size_t fi = 0; fi < faces.size(); ++fi) {
    const auto it = colour.find(region[fi]);
    if (it != colour.end()) out[fi] = it->second;
  }
  return out;
}

std::vector<Vec3> vertex_normals(const BuildingInput& in) {
  std::vector<Vec3> n(in.points.size(), Vec3::Zero());
  for (const auto& t : in.triangles) {
    const Vec3& a = in.points[size_t(t[0])];
    const Vec3 f = (in.points[size_t(t[1])] - a).cross(in.points[size_t(t[2])] - a);  // 2 x area
    for (int v : t) n[size_t(v)] += f;
  }
  for (auto& x : n) x = x.norm() > 0 ? Vec3(x.normalized()) : Vec3::Zero();
  return n;
}

void colour_models(const BuildingInput& in, const Samples& samples, const ColourParams& p,
                   std::vector<LodModel>& models, int threads) {
  if (!p.enabled || in.colors.size() != in.points.size()) return;
  // normals: a mesh's vertex normals (area-weighted), a point cloud's samples'
  // (the input points, normals estimated when missing)
  const bool per_point = !in.is_mesh() && samples.points.size() == in.points.size();
  const ColourSource source(in.points, per_point ? samples.normals : vertex_normals(in), in.colors,
                            p);
  if (source.empty()) return;
  const long nm = long(models.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::max(1, threads))
  for (long i = 0; i < nm; ++i) {
    LodModel& m = models[size_t(i)];
    m.polygon_colours = source.faces(m.polygons.vertices, m.polygons.faces);
    std::vector<std::vector<int>> tris;
    tris.reserve(m.mesh.triangles.size());
    for (const auto& t : m.mesh.triangles) tris.push_back({t[0], t[1], t[2]});
    m.triangle_colours = source.faces(m.mesh.vertices, tris);
  }
}

}  // namespace citylod::lod::detail
