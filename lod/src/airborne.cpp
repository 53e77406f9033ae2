// (ours) Airborne LiDAR as 2.5D: roof height field, refitted roof planes, step
// walls, labels by height, the LoD1.2 block. See airborne.hpp.
#include "airborne.hpp"

#include "closure.hpp"
#include "fallback.hpp"

#include "citylod/lod/polygon2d.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace citylod::lod::detail {
namespace {

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return poly2::cross(o, a, b);
}

/// The ring without repeated and collinear vertices, CCW.
std::vector<Vec2> clean_ring(std::vector<Vec2> r) {
  if (r.size() >= 2 && (r.front() - r.back()).norm() < 1e-9) r.pop_back();
  double a = 0;
  for (std::size_t i = 0; i < r.size(); ++i) a += cross2(Vec2::Zero(), r[i], r[(i + 1) % r.size()]);
  if (a < 0) std::reverse(r.begin(), r.end());
  bool changed = true;
  while (changed && r.size() > 3) {
    changed = false;
    for (std::size_t i = 0; i < r.size() && r.size() > 3; ++i) {
      const Vec2& p = r[(i + r.size() - 1) % r.size()];
      const Vec2& q = r[i];
      const Vec2& n = r[(i + 1) % r.size()];
      const double l = (n - p).norm();
      if ((q - p).norm() < 1e-6 || std::abs(cross2(p, q, n)) <= 1e-9 * std::max(1.0, l * l)) {
        r.erase(r.begin() + long(i));
        changed = true;
        break;
      }
    }
  }
  return r;
}

/// Ear clipping of a simple CCW polygon without collinear vertices.
std::vector<std::array<int, 3>> ear_clip(const std::vector<Vec2>& poly) {
  std::vector<int> idx(poly.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = int(i);
  std::vector<std::array<int, 3>> out;
  auto in_tri = [](const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
    return cross2(a, b, p) >= 0 && cross2(b, c, p) >= 0 && cross2(c, a, p) >= 0;
  };
  while (idx.size() > 3) {
    bool clipped = false;
    const std::size_t m = idx.size();
    for (std::size_t i = 0; i < m && !clipped; ++i) {
      const int ip = idx[(i + m - 1) % m], ic = idx[i], in = idx[(i + 1) % m];
      const Vec2 &a = poly[size_t(ip)], &b = poly[size_t(ic)], &c = poly[size_t(in)];
      if (cross2(a, b, c) <= 1e-12) continue;  // reflex or flat
      bool empty = true;
      for (std::size_t k = 0; k < m && empty; ++k) {
        const int j = idx[k];
        if (j == ip || j == ic || j == in) continue;
        const Vec2& q = poly[size_t(j)];
        if ((q - a).norm() < 1e-12 || (q - b).norm() < 1e-12 || (q - c).norm() < 1e-12) continue;
        if (in_tri(q, a, b, c)) empty = false;
      }
      if (!empty) continue;
      out.push_back({ip, ic, in});
      idx.erase(idx.begin() + long(i));
      clipped = true;
    }
    if (!clipped) throw LodError("block", "the outline is not a simple polygon");
  }
  if (cross2(poly[size_t(idx[0])], poly[size_t(idx[1])], poly[size_t(idx[2])]) <= 1e-12)
    throw LodError("block", "the outline is not a simple polygon");
  out.push_back({idx[0], idx[1], idx[2]});
  return out;
}

/// The 98th percentile of the samples' heights above `ground_z`.
double top_height(const Samples& s, double ground_z) {
  if (s.points.empty()) return 0;
  std::vector<double> h;
  h.reserve(s.points.size());
  for (const auto& q : s.points) h.push_back(q.z() - ground_z);
  const auto at = h.begin() + long(0.98 * double(h.size() - 1));
  std::nth_element(h.begin(), at, h.end());
  return *at;
}

}  // namespace

HeightField::HeightField(const Samples& s, const std::vector<Vec2>& outline, double ground_z,
                         const AirborneParams& p)
    : outline_(outline), ground_(ground_z), top_(top_height(s, ground_z)), cell_(p.cell) {
  // (ours) Returns lower than 0.5 m above the ground are ground or low
  // clutter, not roof; for an object lower than 1 m (a flat shed, a covered
  // parking deck 0.1-0.5 m above the ground) half its height.
  constexpr double kLowClutter = 0.5;  // metres
  roof_floor_ = ground_ + (top_ > 0 ? std::min(kLowClutter, 0.5 * top_) : kLowClutter);
  if (outline_.size() < 3) return;
  Vec2 lo = outline_.front(), hi = lo;
  for (const auto& q : outline_) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  lo_ = lo - Vec2::Constant(cell_);
  nx_ = int(std::ceil((hi.x() - lo_.x()) / cell_)) + 2;
  ny_ = int(std::ceil((hi.y() - lo_.y()) / cell_)) + 2;
  std::vector<std::vector<float>> bucket(size_t(nx_) * size_t(ny_));
  for (const auto& q : s.points) {
    if (q.z() < roof_floor_) continue;  // ground or low clutter, not roof
    const int ix = int(std::floor((q.x() - lo_.x()) / cell_)),
              iy = int(std::floor((q.y() - lo_.y()) / cell_));
    if (ix < 0 || iy < 0 || ix >= nx_ || iy >= ny_) continue;
    bucket[size_t(iy) * size_t(nx_) + size_t(ix)].push_back(float(q.z()));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  z_.assign(bucket.size(), nan);
  for (std::size_t i = 0; i < bucket.size(); ++i) {
    auto& b = bucket[i];
    if (b.empty()) continue;
    std::nth_element(b.begin(), b.begin() + long(b.size() / 2), b.end());
    z_[i] = b[b.size() / 2];  // median: a few outliers do not lift the roof
  }
  int cells_in = 0, seen = 0;
  for (int iy = 0; iy < ny_; ++iy)
    for (int ix = 0; ix < nx_; ++ix)
      if (inside(lo_ + Vec2((ix + 0.5) * cell_, (iy + 0.5) * cell_))) {
        ++cells_in;
        seen += !std::isnan(z_[size_t(iy) * size_t(nx_) + size_t(ix)]);
      }
  roof_coverage_ = cells_in > 0 ? double(seen) / cells_in : 0.0;
  // Gaps (dark roofs, occlusion) filled from their neighbours, one ring of
  // cells per pass, up to the fill radius.
  const int passes = int(std::ceil(p.fill_radius / cell_));
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<float> next = z_;
    bool any = false;
    for (int iy = 0; iy < ny_; ++iy)
      for (int ix = 0; ix < nx_; ++ix) {
        const std::size_t i = size_t(iy) * size_t(nx_) + size_t(ix);
        if (!std::isnan(z_[i])) continue;
        double sum = 0;
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int jx = ix + dx, jy = iy + dy;
            if (jx < 0 || jy < 0 || jx >= nx_ || jy >= ny_) continue;
            const float v = z_[size_t(jy) * size_t(nx_) + size_t(jx)];
            if (!std::isnan(v)) {
              sum += v;
              ++n;
            }
          }
        if (n > 0) {
          next[i] = float(sum / n);
          any = true;
        }
      }
    z_.swap(next);
    if (!any) break;
  }
}

double HeightField::at(const Vec2& p) const {
  if (z_.empty()) return std::numeric_limits<double>::quiet_NaN();
  const int ix = int(std::floor((p.x() - lo_.x()) / cell_)),
            iy = int(std::floor((p.y() - lo_.y()) / cell_));
  if (ix < 0 || iy < 0 || ix >= nx_ || iy >= ny_) return std::numeric_limits<double>::quiet_NaN();
  return z_[size_t(iy) * size_t(nx_) + size_t(ix)];
}

bool HeightField::inside(const Vec2& p) const {
  return outline_.size() >= 3 && poly2::point_in_ring(outline_, p);
}

int refit_roof_planes(const Samples& s, const std::vector<Vec2>& outline, const AirborneParams& p,
                      const AlphaParams& alpha, std::vector<Primitive>& prims) {
  if (!p.roof_refit || outline.size() < 3) return 0;
  int refitted = 0;
  for (auto& pr : prims) {
    if (pr.inferred || pr.normal.z() < 0.3 || pr.inliers.size() < 4) continue;
    const std::size_t n = pr.inliers.size();
    std::vector<double> w_edge(n);
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3& q = s.points[size_t(pr.inliers[k])];
      const double d = poly2::distance_to_ring(outline, Vec2(q.x(), q.y()));
      w_edge[k] = p.roof_edge_margin > 0 ? std::clamp(d / p.roof_edge_margin, 0.05, 1.0) : 1.0;
    }
    Vec3 normal = pr.normal;
    double off = pr.d;
    std::vector<double> w(n), r(n);
    bool ok = true;
    for (int it = 0; it < 4 && ok; ++it) {
      for (std::size_t k = 0; k < n; ++k)
        r[k] = std::abs(normal.dot(s.points[size_t(pr.inliers[k])]) + off);
      std::vector<double> sorted = r;
      std::nth_element(sorted.begin(), sorted.begin() + long(n / 2), sorted.end());
      const double scale = std::max(0.01, 1.4826 * sorted[n / 2]);
      const double c = 4.685 * scale;
      double wsum = 0;
      Vec3 ctr = Vec3::Zero();
      for (std::size_t k = 0; k < n; ++k) {
        const double t = r[k] / c;
        w[k] = t < 1 ? w_edge[k] * (1 - t * t) * (1 - t * t) : 0.0;
        wsum += w[k];
        ctr += w[k] * s.points[size_t(pr.inliers[k])];
      }
      if (!(wsum > 1e-9)) {
        ok = false;
        break;
      }
      ctr /= wsum;
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (std::size_t k = 0; k < n; ++k) {
        const Vec3 d = s.points[size_t(pr.inliers[k])] - ctr;
        cov += w[k] * d * d.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      if (!(es.eigenvalues()(1) > 1e-12)) {
        ok = false;
        break;
      }
      Vec3 nn = es.eigenvectors().col(0).normalized();
      if (nn.dot(pr.normal) < 0) nn = -nn;
      if (nn.dot(pr.normal) < std::cos(10.0 * M_PI / 180.0)) {
        ok = false;  // a robust fit this far off is not the same plane
        break;
      }
      normal = nn;
      off = -nn.dot(ctr);
    }
    if (!ok) continue;
    pr.normal = normal;
    pr.d = off;
    compute_shape(pr, s, alpha);
    ++refitted;
  }
  return refitted;
}

int infer_step_walls(const Samples& s, const HeightField& hf, const AirborneParams& p,
                     std::vector<Primitive>& prims) {
  const auto& fp = hf.outline();
  if (fp.size() < 3) return 0;
  std::vector<double> fp_dirs;  // outline edge directions in [0, pi)
  for (std::size_t i = 0; i < fp.size(); ++i) {
    const Vec2 e = fp[(i + 1) % fp.size()] - fp[i];
    if (e.norm() < 1.0) continue;
    fp_dirs.push_back(std::fmod(std::atan2(e.y(), e.x()) + 2 * M_PI, M_PI));
  }
  const double snap = 15.0 * M_PI / 180.0;
  const double gz = hf.ground();
  std::vector<Primitive> walls;
  for (const auto& pr : prims) {
    if (pr.inferred || pr.normal.z() < 0.3 || pr.inliers.size() < 20) continue;
    auto plane_z = [&](const Vec2& q) {
      return -(pr.normal.x() * q.x() + pr.normal.y() * q.y() + pr.d) / pr.normal.z();
    };
    std::vector<Vec2> xy;
    xy.reserve(pr.inliers.size());
    for (int i : pr.inliers) xy.emplace_back(s.points[size_t(i)].x(), s.points[size_t(i)].y());
    std::vector<Vec2> ol = alpha_outline(xy, p.step_alpha);
    if (ol.size() < 3) continue;
    ol = simplify_closed(ol, 0.3, 10.0);
    for (std::size_t i = 0; i < ol.size(); ++i) {
      Vec2 a = ol[i], b = ol[(i + 1) % ol.size()];
      Vec2 e = b - a;
      const double len = e.norm();
      if (len < p.step_min_edge) continue;
      const Vec2 out(e.y() / len, -e.x() / len);  // right of a CCW edge
      const int k = std::max(2, int(std::ceil(len / 0.5)));
      int valid = 0, steps = 0;
      for (int j = 0; j < k; ++j) {
        const Vec2 q = a + (j + 0.5) / k * e;
        const Vec2 probe = q + p.step_probe * out;
        if (!hf.inside(probe)) continue;
        const double r = hf.at(probe);
        if (std::isnan(r)) continue;
        ++valid;
        // The lower side extrapolated back to the edge from a second probe
        // 1 m farther: a roof sloping down from the edge meets it (no step),
        // a flat lower roof keeps its height. Only ever raised: a lower side
        // rising away from the edge is taken flat.
        const Vec2 far = probe + 1.0 * out;
        const double r2 = hf.inside(far) ? hf.at(far) : std::numeric_limits<double>::quiet_NaN();
        const double at_edge = !std::isnan(r2) && r2 < r ? r + (r - r2) * p.step_probe : r;
        steps += plane_z(q) - r > p.step_min_raw || plane_z(q) - at_edge > p.step_min;
      }
      if (2 * valid < k || 10 * steps < 6 * valid) continue;
      // Snap to the nearest outline direction (buildings are mostly rectilinear).
      const double ang = std::fmod(std::atan2(e.y(), e.x()) + 2 * M_PI, M_PI);
      double best = snap;
      double to = ang;
      for (double d : fp_dirs) {
        double diff = std::abs(d - ang);
        diff = std::min(diff, M_PI - diff);
        if (diff < best) {
          best = diff;
          to = d;
        }
      }
      Vec2 dir = e / len;
      if (to != ang) {
        Vec2 nd(std::cos(to), std::sin(to));
        if (nd.dot(dir) < 0) nd = -nd;
        dir = nd;
      }
      const Vec2 mid = 0.5 * (a + b);
      const double half = 0.5 * len + 0.5;  // a little past the corners, to meet the next wall
      a = mid - half * dir;
      b = mid + half * dir;
      const double top = std::max(plane_z(a), plane_z(b));
      if (!(top > gz + 1.0)) continue;
      Primitive w;
      w.inferred = true;
      w.normal = Vec3(dir.y(), -dir.x(), 0.0);
      w.d = -(w.normal.x() * a.x() + w.normal.y() * a.y());
      w.u = Vec3::UnitZ().cross(w.normal).normalized();
      w.v = w.normal.cross(w.u);
      const Vec3 A0(a.x(), a.y(), gz), B0(b.x(), b.y(), gz), A1(a.x(), a.y(), top),
          B1(b.x(), b.y(), top);
      w.hull = {A0, B0, B1, A1};
      w.alpha_tris = {{A0, B0, B1}, {A0, B1, A1}};
      w.hull_area = w.alpha_area = (b - a).norm() * (top - gz);
      w.centroid = 0.25 * (A0 + B0 + A1 + B1);
      walls.push_back(std::move(w));
    }
  }
  const int n = int(walls.size());
  for (auto& w : walls) prims.push_back(std::move(w));
  return n;
}

std::vector<char> label_by_height(const std::vector<std::vector<Vec3>>& origins,
                                  const HeightField& hf) {
  std::vector<char> out(origins.size(), 0);
  for (std::size_t i = 0; i < origins.size(); ++i) {
    int in = 0;
    for (const auto& o : origins[i]) {
      const Vec2 xy(o.x(), o.y());
      if (o.z() <= hf.ground() || !hf.inside(xy)) continue;
      const double roof = hf.at(xy);
      in += !std::isnan(roof) && o.z() < roof;
    }
    out[i] = 2 * in > int(origins[i].size());
  }
  return out;
}

OutlineDistances outline_distances(const Samples& s, const HeightField& hf) {
  OutlineDistances od;
  od.ring = clean_ring(hf.outline());
  if (od.ring.size() < 3) return od;
  od.dist.reserve(s.points.size());
  od.inside.reserve(s.points.size());
  for (const auto& q : s.points) {
    const Vec2 xy(q.x(), q.y());
    od.dist.push_back(poly2::distance_to_ring(od.ring, xy));
    od.inside.push_back(poly2::point_in_ring(od.ring, xy));
  }
  return od;
}

LodModel block_model(const Samples& s, const HeightField& hf, const OutlineDistances& od) {
  const std::vector<Vec2>& ring = od.ring;
  if (ring.size() < 3) throw LodError("block", "the outline has fewer than 3 vertices");
  const double g = hf.ground(), floor = hf.roof_floor();
  // The height that fits the samples best, among their roof height quantiles.
  const std::vector<double>& d_edge = od.dist;
  const std::vector<char>& inside = od.inside;
  std::vector<double> roof_z;
  for (const auto& q : s.points)
    if (q.z() > floor) roof_z.push_back(q.z());
  if (roof_z.empty()) throw LodError("block", "no point above the ground");
  std::sort(roof_z.begin(), roof_z.end());
  auto sq_dist = [&](std::size_t i, double h) {
    const double z = s.points[i].z();
    if (inside[i]) {
      if (z > h) return (z - h) * (z - h);
      if (z < g) return (g - z) * (g - z);
      const double d = std::min({h - z, z - g, d_edge[i]});
      return d * d;
    }
    const double dz = std::max({0.0, z - h, g - z});
    return d_edge[i] * d_edge[i] + dz * dz;
  };
  double best_h = roof_z.back(), best = std::numeric_limits<double>::infinity();
  for (int k = 0; k <= 100; ++k) {
    const double h = roof_z[size_t(std::lround(k / 100.0 * double(roof_z.size() - 1)))];
    if (h < floor) continue;
    double sum = 0;
    for (std::size_t i = 0; i < s.points.size(); ++i) sum += sq_dist(i, h);
    if (sum < best) {
      best = sum;
      best_h = h;
    }
  }
  const double h = std::max(best_h, floor);
  const auto top_tris = ear_clip(ring);
  LodModel m;
  m.kind = ModelKind::anchor;
  m.level = 0;
  const int n = int(ring.size());
  m.polygons = prism_polygons(ring, g, h);
  m.mesh.vertices = m.polygons.vertices;
  for (const auto& t : top_tris) {
    m.mesh.triangles.push_back({n + t[0], n + t[1], n + t[2]});
    m.mesh.triangles.push_back({t[0], t[2], t[1]});
  }
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.mesh.triangles.push_back({i, j, n + j});
    m.mesh.triangles.push_back({i, n + j, n + i});
  }
  return m;
}

std::vector<Vec3> roof_returns(const Samples& s, const OutlineDistances& od, double edge_margin) {
  double deepest = 0;
  for (std::size_t k = 0; k < od.dist.size(); ++k)
    if (od.inside[k]) deepest = std::max(deepest, od.dist[k]);
  const double margin = std::min(edge_margin, 0.5 * deepest);
  std::vector<Vec3> out;
  for (std::size_t k = 0; k < od.dist.size(); ++k)
    if (od.inside[k] && od.dist[k] > margin) out.push_back(s.points[k]);
  return out;
}

double roof_rmse(const TriangleMesh& m, const std::vector<Vec3>& returns, double ground) {
  const double g = ground;
  // The model's non-vertical triangles above the ground, bucketed on a grid.
  struct Tri {
    Vec3 a, b, c;
  };
  std::vector<Tri> tris;
  Vec2 lo(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity());
  Vec2 hi = -lo;
  for (const auto& t : m.triangles) {
    const Vec3 &a = m.vertices[size_t(t[0])], &b = m.vertices[size_t(t[1])],
               &c = m.vertices[size_t(t[2])];
    if (std::abs((b - a).cross(c - a).z()) < 1e-9) continue;    // vertical
    if (std::max({a.z(), b.z(), c.z()}) <= g + 1e-6) continue;  // the base
    tris.push_back({a, b, c});
    for (const Vec3* v : {&a, &b, &c}) {
      lo = lo.cwiseMin(Vec2(v->x(), v->y()));
      hi = hi.cwiseMax(Vec2(v->x(), v->y()));
    }
  }
  // 1 m cells, coarser over a model larger than 256 x 256 m (at most ~65,536
  // cells): the grid only finds the triangles over a point.
  const double cell =
      tris.empty() ? 1.0
                   : std::max(1.0, std::sqrt((hi.x() - lo.x()) * (hi.y() - lo.y()) / 65536.0));
  const int nx = tris.empty() ? 1 : std::max(1, int((hi.x() - lo.x()) / cell) + 1);
  const int ny = tris.empty() ? 1 : std::max(1, int((hi.y() - lo.y()) / cell) + 1);
  const auto cx = [&](double x) { return std::clamp(int((x - lo.x()) / cell), 0, nx - 1); };
  const auto cy = [&](double y) { return std::clamp(int((y - lo.y()) / cell), 0, ny - 1); };
  std::vector<std::vector<int>> grid(size_t(nx) * size_t(ny));
  for (size_t i = 0; i < tris.size(); ++i) {
    const Tri& t = tris[i];
    const int x0 = cx(std::min({t.a.x(), t.b.x(), t.c.x()}));
    const int x1 = cx(std::max({t.a.x(), t.b.x(), t.c.x()}));
    const int y0 = cy(std::min({t.a.y(), t.b.y(), t.c.y()}));
    const int y1 = cy(std::max({t.a.y(), t.b.y(), t.c.y()}));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) grid[size_t(y) * size_t(nx) + size_t(x)].push_back(int(i));
  }
  double sum = 0;
  std::size_t n = 0, covered = 0;
  for (const Vec3& q : returns) {
    const Vec2 xy(q.x(), q.y());
    double top = -std::numeric_limits<double>::infinity();
    if (!tris.empty())
      for (int i : grid[size_t(cy(xy.y())) * size_t(nx) + size_t(cx(xy.x()))]) {
        const Tri& t = tris[size_t(i)];
        const double d =
            (t.b.y() - t.c.y()) * (t.a.x() - t.c.x()) + (t.c.x() - t.b.x()) * (t.a.y() - t.c.y());
        const double l1 =
            ((t.b.y() - t.c.y()) * (xy.x() - t.c.x()) + (t.c.x() - t.b.x()) * (xy.y() - t.c.y())) /
            d;
        const double l2 =
            ((t.c.y() - t.a.y()) * (xy.x() - t.c.x()) + (t.a.x() - t.c.x()) * (xy.y() - t.c.y())) /
            d;
        const double l3 = 1 - l1 - l2;
        if (l1 < -1e-9 || l2 < -1e-9 || l3 < -1e-9) continue;
        top = std::max(top, l1 * t.a.z() + l2 * t.b.z() + l3 * t.c.z());
      }
    covered += top > g;
    top = std::max(top, g);
    sum += (q.z() - top) * (q.z() - top);
    ++n;
  }
  // A model over less than half of the returns (a fragment, a sliver) is
  // not judged by them: over a patch at the ground's level it would fit.
  if (2 * covered < n || n == 0) return std::numeric_limits<double>::quiet_NaN();
  return std::sqrt(sum / double(n));
}

namespace {

/// Worse than `ref`: a larger e2, and a roof fit that is not better (or not measured).
bool fits_worse(const LodModel& m, const LodModel& ref) {
  const bool roof_better = m.roof_rmse >= 0 && ref.roof_rmse >= 0 && m.roof_rmse <= ref.roof_rmse;
  return m.e2 > ref.e2 && !roof_better;
}

}  // namespace

int drop_worse_than_block(std::vector<LodModel>& models) {
  if (models.size() < 2) return 0;
  const LodModel& block = models.front();
  const auto worse = [&](const LodModel& m) { return fits_worse(m, block); };
  const auto finest = std::find_if(models.rbegin(), models.rend() - 1,
                                   [](const LodModel& m) { return m.kind == ModelKind::anchor; });
  if (finest == models.rend() - 1 || !worse(*finest)) return 0;  // the tree did its work
  const auto end = std::remove_if(models.begin() + 1, models.end(), worse);
  const int n = int(models.end() - end);
  models.erase(end, models.end());
  for (size_t i = 0; i < models.size(); ++i) models[i].step = int(i);
  return n;
}

int drop_worse_last_levels(std::vector<LodModel>& models) {
  int dropped = 0;
  for (;;) {
    std::size_t last = 0, before = 0;  // the last two anchors after the block
    for (std::size_t i = models.size(); i-- > 1;) {
      if (models[i].kind != ModelKind::anchor) continue;
      if (last == 0) {
        last = i;
      } else {
        before = i;
        break;
      }
    }
    if (before == 0 || !fits_worse(models[last], models[before])) break;
    dropped += int(models.size() - (before + 1));
    models.erase(models.begin() + long(before + 1), models.end());
  }
  for (size_t i = 0; i < models.size(); ++i) models[i].step = int(i);
  return dropped;
}

int drop_low_object_worse_than_block(std::vector<LodModel>& models) {
  if (models.size() < 2) return 0;
  const double block_e2 = models.front().e2;
  const auto end = std::remove_if(models.begin() + 1, models.end(),
                                  [&](const LodModel& m) { return m.e2 > block_e2; });
  const int n = int(models.end() - end);
  models.erase(end, models.end());
  for (size_t i = 0; i < models.size(); ++i) models[i].step = int(i);
  return n;
}

}  // namespace citylod::lod::detail
