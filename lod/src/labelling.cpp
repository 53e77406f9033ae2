// Ray-casting in/out labelling (Appendix C of the paper).
#include "labelling.hpp"

#include <CGAL/Cartesian_converter.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace citylod::lod::detail {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using Ray = K::Ray_3;
using EK = CGAL::Exact_predicates_exact_constructions_kernel;

/// Uniform directions on the sphere (Fibonacci lattice), slightly rotated so
/// no direction is exactly parallel to an axis-aligned plane.
std::vector<Vec3> sphere_directions(int n) {
  std::vector<Vec3> dirs;
  dirs.reserve(static_cast<size_t>(n));
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  const double tilt = 0.1234;  // radians, breaks axis alignment
  const double ct = std::cos(tilt), st = std::sin(tilt);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i + 0.0371;
    Vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    // rotate about x, then about y
    d = Vec3(d.x(), ct * d.y() - st * d.z(), st * d.y() + ct * d.z());
    d = Vec3(ct * d.x() + st * d.z(), d.y(), -st * d.x() + ct * d.z());
    dirs.push_back(d.normalized());
  }
  return dirs;
}

// Bounding volume hierarchy over the triangles.
//
// The first hit of a ray is defined exactly: among the triangles the ray
// (source o, through the double point o + u, as CGAL's Ray_3 stores it)
// meets, by exact predicates, the one whose first common point has the
// smallest exact ray parameter; at an exactly equal parameter (a shared edge
// or vertex, coplanar overlapping triangles, a source on two faces) the
// triangle given first (lowest index) wins. `first_hit_exact` is that
// definition by brute force (Epeck); the BVH finds the same hit faster: a
// flat binary tree of padded boxes traversed near child first, a double
// precision Moller-Trumbore test that only rejects triangles it misses by
// far more than its rounding error, CGAL's exact-predicate Ray_3/Triangle_3
// intersection for every other triangle, and the exact parameters (Epeck)
// whenever two candidates' double parameters are within their error bounds.
// (CGAL's AABB_tree::first_intersection gives an exactly first hit too, but
// breaks exact ties by the order it happens to visit the triangles in.)
struct Bvh {
  struct Node {
    double lo[3], hi[3];
    int first = 0,
        count = 0;  ///< leaf: tris [first, first+count); inner: count = 0, children first, first+1
  };
  std::vector<Node> nodes;
  std::vector<int> order;  ///< triangle ids, leaves' ranges

  void build(const std::vector<std::array<Vec3, 3>>& t) {
    const int n = int(t.size());
    order.resize(size_t(n));
    std::vector<Vec3> cen(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      order[size_t(i)] = i;
      cen[size_t(i)] = (t[size_t(i)][0] + t[size_t(i)][1] + t[size_t(i)][2]) / 3.0;
    }
    nodes.clear();
    nodes.reserve(size_t(2 * n));
    nodes.emplace_back();
    struct Job {
      int node, lo, hi;
    };
    std::vector<Job> stack{{0, 0, n}};
    while (!stack.empty()) {
      const Job j = stack.back();
      stack.pop_back();
      Node& nd = nodes[size_t(j.node)];
      Vec3 blo = Vec3::Constant(std::numeric_limits<double>::infinity()), bhi = -blo;
      Vec3 clo = blo, chi = bhi;
      for (int k = j.lo; k < j.hi; ++k) {
        const int id = order[size_t(k)];
        for (const auto& v : t[size_t(id)]) {
          blo = blo.cwiseMin(v);
          bhi = bhi.cwiseMax(v);
        }
        clo = clo.cwiseMin(cen[size_t(id)]);
        chi = chi.cwiseMax(cen[size_t(id)]);
      }
      // padded so that rounding in the slab test never drops a triangle on a face
      const double pad = 1e-9 * (1.0 + blo.cwiseAbs().maxCoeff() + bhi.cwiseAbs().maxCoeff());
      for (int a = 0; a < 3; ++a) {
        nd.lo[a] = blo[a] - pad;
        nd.hi[a] = bhi[a] + pad;
      }
      if (j.hi - j.lo <= 4) {
        nd.first = j.lo;
        nd.count = j.hi - j.lo;
        continue;
      }
      // binned surface area heuristic over the centroids (median split when
      // the centroids coincide on every axis)
      int mid = (j.lo + j.hi) / 2;
      int axis = 0;
      const Vec3 ext = chi - clo;
      if (ext[1] > ext[axis]) axis = 1;
      if (ext[2] > ext[axis]) axis = 2;
      if (ext[axis] > 0) {
        constexpr int kBins = 16;
        double best_cost = std::numeric_limits<double>::infinity();
        int best_axis = -1;
        int best_bin = 0;
        for (int ax = 0; ax < 3; ++ax) {
          if (!(ext[ax] > 0)) continue;
          Vec3 bl[kBins], bh[kBins];
          int cnt[kBins] = {};
          for (int q = 0; q < kBins; ++q) {
            bl[q] = Vec3::Constant(std::numeric_limits<double>::infinity());
            bh[q] = -bl[q];
          }
          const double scale = kBins / ext[ax];
          for (int k = j.lo; k < j.hi; ++k) {
            const int id = order[size_t(k)];
            const int q = std::min(kBins - 1, int((cen[size_t(id)][ax] - clo[ax]) * scale));
            ++cnt[q];
            for (const auto& v : t[size_t(id)]) {
              bl[q] = bl[q].cwiseMin(v);
              bh[q] = bh[q].cwiseMax(v);
            }
          }
          auto area = [](const Vec3& l, const Vec3& h) {
            if (!(h.x() >= l.x())) return 0.0;
            const Vec3 d = h - l;
            return d.x() * d.y() + d.y() * d.z() + d.z() * d.x();
          };
          double right_area[kBins];
          int right_cnt[kBins];
          Vec3 rl = Vec3::Constant(std::numeric_limits<double>::infinity()), rh = -rl;
          int rc = 0;
          for (int q = kBins - 1; q > 0; --q) {
            rl = rl.cwiseMin(bl[q]);
            rh = rh.cwiseMax(bh[q]);
            rc += cnt[q];
            right_area[q] = area(rl, rh);
            right_cnt[q] = rc;
          }
          Vec3 ll = Vec3::Constant(std::numeric_limits<double>::infinity()), lh = -ll;
          int lc = 0;
          for (int q = 0; q < kBins - 1; ++q) {
            ll = ll.cwiseMin(bl[q]);
            lh = lh.cwiseMax(bh[q]);
            lc += cnt[q];
            if (lc == 0 || right_cnt[q + 1] == 0) continue;
            const double cost = area(ll, lh) * lc + right_area[q + 1] * right_cnt[q + 1];
            if (cost < best_cost) {
              best_cost = cost;
              best_axis = ax;
              best_bin = q + 1;
            }
          }
        }
        if (best_axis >= 0) {
          const int ax = best_axis;
          const double sc = kBins / ext[ax];
          const double cl = clo[ax];
          const auto it = std::partition(order.begin() + j.lo, order.begin() + j.hi, [&](int id) {
            return std::min(kBins - 1, int((cen[size_t(id)][ax] - cl) * sc)) < best_bin;
          });
          const int m = int(it - order.begin());
          if (m > j.lo && m < j.hi) {
            mid = m;
            axis = -1;  // split done
          }
        }
      }
      if (axis >= 0)
        std::nth_element(order.begin() + j.lo, order.begin() + mid, order.begin() + j.hi,
                         [&](int a, int b) {
                           const double ca = cen[size_t(a)][axis], cb = cen[size_t(b)][axis];
                           return ca < cb || (ca == cb && a < b);
                         });
      const int left = int(nodes.size());
      nodes[size_t(j.node)].first = left;
      nodes[size_t(j.node)].count = 0;
      nodes.emplace_back();
      nodes.emplace_back();
      stack.push_back({left + 1, mid, j.hi});
      stack.push_back({left, j.lo, mid});
    }
  }
};

/// Ray parameter where the ray enters the box (0 if it starts inside), +inf
/// when it misses it.
inline double box_entry(const Bvh::Node& b, const double o[3], const double inv[3]) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    double ta = (b.lo[a] - o[a]) * inv[a], tb = (b.hi[a] - o[a]) * inv[a];
    if (ta > tb) std::swap(ta, tb);
    if (!(ta <= t1) || !(tb >= t0)) {
      if (std::isnan(ta) || std::isnan(tb)) continue;  // parallel, on the slab: keep
      return std::numeric_limits<double>::infinity();
    }
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0;
}

/// Exact parameter of the first point the ray shares with triangle t, in
/// units of the ray's stored direction (0 = source, 1 = its second point);
/// false when they do not meet. `point`: false when the ray lies in the
/// triangle's plane (the common part is a segment).
bool exact_param(const Ray& ray, const Triangle& t, EK::FT& param, bool& point) {
  const CGAL::Cartesian_converter<K, EK> to_exact;
  const EK::Ray_3 r = to_exact(ray);
  const auto x = CGAL::intersection(r, to_exact(t));
  if (!x) return false;
  const EK::Vector_3 d = r.to_vector();
  int i = 0;  // a nonzero coordinate of the direction
  while (i < 2 && CGAL::is_zero(d.cartesian(i))) ++i;
  const auto at = [&](const EK::Point_3& p) {
    return (p.cartesian(i) - r.source().cartesian(i)) / d.cartesian(i);
  };
  if (const auto* p = boost::get<EK::Point_3>(&*x)) {
    param = at(*p);
    point = true;
    return true;
  }
  if (const auto* s = boost::get<EK::Segment_3>(&*x)) {
    param = CGAL::min(at(s->source()), at(s->target()));
    point = false;
    return true;
  }
  return false;
}

}  // namespace

struct RayLabeller::Impl {
  std::vector<Triangle> tris;
  std::vector<std::array<Vec3, 3>> dtris;
  std::vector<Vec3> normals;  // unit, outward
  std::vector<int> level;
  std::vector<Vec3> dirs;
  Bvh bvh;
  int max_level = 0;
  bool exact_reference = false;  ///< first_hit_exact instead of the BVH

  struct Hit {
    int id = -1;
    bool point = false;  ///< false: the ray lies in the triangle's plane (a segment)
  };

  struct TriData {
    Vec3 a, e1, e2;
    double n1 = 0, n2 = 0;  ///< |e1|, |e2|
  };
  std::vector<TriData> tdata;

  /// false when the double test proves that the ray (o, u) (|u| = 1) misses
  /// triangle i.
  bool may_hit(int i, const Vec3& o, const Vec3& u) const {
    const TriData& t = tdata[size_t(i)];
    const Vec3 pv = u.cross(t.e2);
    const double det = t.e1.dot(pv);
    const double D = std::abs(det);
    if (!(D > 1e-6 * t.n1 * t.n2)) return true;  // (nearly) parallel: CGAL decides
    const Vec3 tv = o - t.a;
    const double uu = tv.dot(pv) / det;
    const Vec3 qv = tv.cross(t.e1);
    const double vv = u.dot(qv) / det;
    const double tt = t.e2.dot(qv) / det;
    if (uu >= -1e-3 && vv >= -1e-3 && uu + vv <= 1.001 && tt >= -1e-3)
      return true;  // not far outside: no need for the bound
    // Each quantity has an absolute error under ~1e-15 of the bound's scale;
    // the tolerances are 1e5 times that.
    const double ntv = tv.norm();
    const double tol = 1e-10 * (ntv * std::max(t.n1, t.n2) / D + 1.0);
    if (uu < -tol || uu > 1.0 + tol) return false;
    if (vv < -tol || uu + vv > 1.0 + 2 * tol) return false;
    if (tt < -1e-10 * (ntv * t.n1 * t.n2 / D + 1.0) * (1.0 + ntv)) return false;
    return true;
  }

  /// The first hit (see the comment on Bvh) of the ray (o, u) among the
  /// triangles that `skip` does not skip, through the BVH.
  template <class Skip>
  Hit first_hit(const Vec3& o, const Vec3& u, const Skip& skip) const {
    Hit best;
    if (exact_reference) return first_hit_exact(o, u, skip);
    if (nodes_empty()) return best;
    const Ray ray(Point(o.x(), o.y(), o.z()), K::Vector_3(u.x(), u.y(), u.z()));
    int max_i = 0;  // the parameter from the direction's largest coordinate
    for (int i = 1; i < 3; ++i)
      if (std::abs(u[i]) > std::abs(u[max_i])) max_i = i;
    const double od[3] = {o.x(), o.y(), o.z()};
    const double inv[3] = {1.0 / u.x(), 1.0 / u.y(), 1.0 / u.z()};
    const double inf = std::numeric_limits<double>::infinity();
    double bt = std::numeric_limits<double>::max();
    double btol = 0.0;  // error bound of bt
    bool best_exact_known = false;
    EK::FT best_exact;
    auto prune = [&](double entry) { return entry > bt + btol + 1e-9 * (1.0 + std::abs(bt)); };
    int stack[128];
    int sp = 0;
    if (box_entry(bvh.nodes[0], od, inv) < inf) stack[sp++] = 0;
    while (sp > 0) {
      const Bvh::Node& nd = bvh.nodes[size_t(stack[--sp])];
      if (nd.count > 0) {
        for (int k = nd.first; k < nd.first + nd.count; ++k) {
          const int id = bvh.order[size_t(k)];
          if (skip(id) || !may_hit(id, o, u)) continue;
          const auto x = CGAL::intersection(ray, tris[size_t(id)]);
          if (!x) continue;
          double param;
          double tol;
          bool point;
          if (const Point* p = boost::get<Point>(&*x)) {
            param = (p->cartesian(max_i) - od[max_i]) / u[max_i];
            point = true;
            // CGAL constructs the point as the ray's line meets the
            // triangle's plane, in double: its error grows with the
            // coordinates' size and as the ray grazes the plane. 1e-11 is
            // ~5e4 times the double rounding unit.
            const double c = std::abs(normals[size_t(id)].dot(u));
            tol = 1e-11 * (1.0 + o.norm() + tdata[size_t(id)].a.norm() + std::abs(param)) /
                  std::max(c, 1e-300);
          } else if (const auto* s = boost::get<K::Segment_3>(&*x)) {
            const double r1 = (s->source().cartesian(max_i) - od[max_i]) / u[max_i];
            const double r2 = (s->target().cartesian(max_i) - od[max_i]) / u[max_i];
            param = std::min(r1, r2);
            point = false;
            tol = inf;  // in the plane: always decided exactly
          } else {
            continue;
          }
          bool take = best.id < 0 || param < bt - (tol + btol);
          if (!take && !(param > bt + tol + btol)) {  // too close to call in double
            EK::FT e;
            bool e_point = false;
            if (!best_exact_known) {
              exact_param(ray, tris[size_t(best.id)], best_exact, e_point);
              best_exact_known = true;
            }
            if (exact_param(ray, tris[size_t(id)], e, e_point) &&
                (e < best_exact || (e == best_exact && id < best.id))) {
              take = true;
              best_exact = e;
            }
            if (take) {
              bt = param;
              btol = tol;
              best.id = id;
              best.point = point;
            }
            continue;
          }
          if (take) {
            bt = param;
            btol = tol;
            best.id = id;
            best.point = point;
            best_exact_known = false;
          }
        }
        continue;
      }
      const int a = nd.first, b = nd.first + 1;
      const double ta = box_entry(bvh.nodes[size_t(a)], od, inv);
      const double tb = box_entry(bvh.nodes[size_t(b)], od, inv);
      const bool ha = ta < inf && !prune(ta);
      const bool hb = tb < inf && !prune(tb);
      if (sp + 2 > 128) throw std::logic_error("RayLabeller: tree too deep");
      if (ha && hb) {  // near child on top
        if (ta <= tb) {
          stack[sp++] = b;
          stack[sp++] = a;
        } else {
          stack[sp++] = a;
          stack[sp++] = b;
        }
      } else if (ha) {
        stack[sp++] = a;
      } else if (hb) {
        stack[sp++] = b;
      }
    }
    return best;
  }

  /// The first hit by its definition: every triangle, exact predicates and
  /// exact parameters, the lowest index at an exact tie (the tests' reference).
  template <class Skip>
  Hit first_hit_exact(const Vec3& o, const Vec3& u, const Skip& skip) const {
    Hit best;
    const Ray ray(Point(o.x(), o.y(), o.z()), K::Vector_3(u.x(), u.y(), u.z()));
    EK::FT bt;
    for (int id = 0; id < static_cast<int>(tris.size()); ++id) {
      if (skip(id) || !CGAL::do_intersect(ray, tris[size_t(id)])) continue;
      EK::FT e;
      bool point = false;
      if (!exact_param(ray, tris[size_t(id)], e, point)) continue;
      if (best.id < 0 || e < bt) {
        bt = e;
        best.id = id;
        best.point = point;
      }
    }
    return best;
  }
  bool nodes_empty() const { return bvh.nodes.empty(); }
};

RayLabeller::RayLabeller(const LevelTriangles& in, int rays, Method method)
    : impl_(std::make_unique<Impl>()) {
  auto& I = *impl_;
  I.exact_reference = method == Method::exact_brute_force;
  I.dirs = sphere_directions(std::max(1, rays));
  for (size_t i = 0; i < in.triangles.size(); ++i) {
    const auto& t = in.triangles[i];
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
    if (!(n.norm() > 1e-12)) continue;  // degenerate (or NaN)
    I.tris.emplace_back(Point(t[0].x(), t[0].y(), t[0].z()), Point(t[1].x(), t[1].y(), t[1].z()),
                        Point(t[2].x(), t[2].y(), t[2].z()));
    I.dtris.push_back(t);
    const Vec3 e1 = t[1] - t[0], e2 = t[2] - t[0];
    I.tdata.push_back({t[0], e1, e2, e1.norm(), e2.norm()});
    I.normals.push_back(n.normalized());
    I.level.push_back(in.level[i]);
    I.max_level = std::max(I.max_level, in.level[i]);
  }
  if (!I.tris.empty()) I.bvh.build(I.dtris);
}

RayLabeller::~RayLabeller() = default;

std::vector<std::vector<char>> RayLabeller::label(const std::vector<Vec3>& centres, int num_levels,
                                                  int threads) const {
  std::vector<std::vector<Vec3>> origins;
  origins.reserve(centres.size());
  for (const auto& c : centres) origins.push_back({c});
  return label(origins, num_levels, threads);
}

std::vector<std::vector<char>> RayLabeller::label(const std::vector<std::vector<Vec3>>& origins,
                                                  int num_levels, int threads) const {
  const auto& I = *impl_;
  const int L = std::max(1, num_levels);
  std::vector<std::vector<char>> out(origins.size(), std::vector<char>(static_cast<size_t>(L), 0));
  if (I.tris.empty()) return out;
  const int nrays = static_cast<int>(I.dirs.size());
  const long n = static_cast<long>(origins.size());

#pragma omp parallel for schedule(dynamic, 16) num_threads(std::max(1, threads))
  for (long c = 0; c < n; ++c) {
    const auto& cell_origins = origins[static_cast<size_t>(c)];
    std::vector<int> votes_in(static_cast<size_t>(L), 0);
    std::vector<int> grazing;  // triangles a ray lies in: no vote, looked through
    for (int r = 0; r < nrays; ++r) {
      const Vec3& u = I.dirs[static_cast<size_t>(r)];
      const Vec3& o = cell_origins[static_cast<size_t>(r) % cell_origins.size()];
      // First hit per level: triangles of level <= k count for label k. The
      // nearest hit of any level decides the labels from its level up; then the
      // nearest hit among the lower levels only, and so on down to level 0.
      int bound = L;  // levels [bound, L) already decided
      grazing.clear();
      while (bound > 0) {
        const auto skip = [&](int id) {
          return I.level[static_cast<size_t>(id)] >= bound ||
                 std::find(grazing.begin(), grazing.end(), id) != grazing.end();
        };
        const Impl::Hit hit = I.first_hit(o, u, skip);
        if (hit.id < 0) break;
        const int id = hit.id;
        if (!hit.point) {  // the ray lies in the triangle's plane
          grazing.push_back(id);
          continue;
        }
        const int lv = I.level[static_cast<size_t>(id)];
        const bool in = I.normals[static_cast<size_t>(id)].dot(u) > 0.0;
        for (int k = lv; k < bound; ++k) votes_in[static_cast<size_t>(k)] += in ? 1 : 0;
        bound = lv;
      }
    }
    for (int k = 0; k < L; ++k)
      out[static_cast<size_t>(c)][static_cast<size_t>(k)] =
          (2 * votes_in[static_cast<size_t>(k)] > nrays) ? 1 : 0;
  }
  return out;
}

std::pair<int, int> RayLabeller::half_space_votes(const Vec3& origin, const Vec3& side) const {
  const auto& I = *impl_;
  int in = 0, cast = 0;
  if (I.tris.empty()) return {0, 0};
  for (const auto& u : I.dirs) {
    if (!(u.dot(side) > 0)) continue;
    ++cast;
    const Impl::Hit hit =
        I.first_hit(origin, u, [&](int id) { return I.level[static_cast<size_t>(id)] > 0; });
    if (hit.id < 0 || !hit.point) continue;
    if (I.normals[static_cast<size_t>(hit.id)].dot(u) > 0.0) ++in;
  }
  return {in, cast};
}

}  // namespace citylod::lod::detail
