// Planar primitives: region growing (CGAL Shape_detection) on points or mesh
// faces, least-squares plane fits, alpha-shapes and convex hulls.
#include "planes.hpp"

#include "epick.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing_on_point_set.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing_on_polygon_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/convex_hull_2.h>
#include <CGAL/property_map.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <tuple>

namespace citylod::lod::detail {

namespace {

using namespace epick;

/// Weighted least-squares plane of the inliers; normal oriented like their mean normal.
void fit_plane(Primitive& prim, const Samples& s) {
  if (prim.inliers.empty()) return;
  double wsum = 0;
  Vec3 c = Vec3::Zero(), mn = Vec3::Zero();
  for (int i : prim.inliers) {
    const double w = s.weights.empty() ? 1.0 : s.weights[i];
    c += w * s.points[i];
    mn += w * s.normals[i];
    wsum += w;
  }
  c /= wsum;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i : prim.inliers) {
    const double w = s.weights.empty() ? 1.0 : s.weights[i];
    const Vec3 d = s.points[i] - c;
    cov += w * d * d.transpose();
  }
  Vec3 n;
  if (prim.inliers.size() >= 3) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    n = es.eigenvectors().col(0);
    // Degenerate (collinear) support: fall back to the mean normal.
    if (!(es.eigenvalues()(1) > 1e-18) && mn.norm() > 1e-12) n = mn.normalized();
  } else {
    n = mn.norm() > 1e-12 ? mn.normalized() : Vec3::UnitZ();
  }
  if (n.dot(mn) < 0) n = -n;
  n.normalize();
  prim.normal = n;
  prim.d = -n.dot(c);
  prim.centroid = c;
}

using Pwn = std::pair<P3, V3>;
using PwnVec = std::vector<Pwn>;
using PMap = CGAL::First_of_pair_property_map<Pwn>;
using NMap = CGAL::Second_of_pair_property_map<Pwn>;
namespace SD = CGAL::Shape_detection;

/// CGAL's k-nearest-neighbour query, answered from lists computed once for
/// every point (on `threads` threads): the seed sorting and the region
/// growing both query each point, and get the same lists.
class Cached_neighbor_query {
 public:
  template <class Query>
  Cached_neighbor_query(const Query& q, std::size_t n, int threads) : lists_(n) {
    const long nl = long(n);
#pragma omp parallel for schedule(static) num_threads(std::max(1, threads)) if (threads > 1)
    for (long i = 0; i < nl; ++i) q(std::size_t(i), lists_[std::size_t(i)]);
  }
  /// The first k of each of the normal estimation's neighbour lists (itself,
  /// then by distance: the k a k-nearest search gives), read in place.
  Cached_neighbor_query(const Samples& s, std::size_t k)
      : flat_(&s.neighbours), each_(s.neighbours_each), k_(std::min(k, s.neighbours_each)) {}
  void operator()(std::size_t i, std::vector<std::size_t>& neighbors) const {
    if (flat_) {
      const auto first = flat_->begin() + long(i * each_);
      neighbors.assign(first, first + long(k_));
    } else {
      neighbors = lists_[i];
    }
  }

 private:
  std::vector<std::vector<std::size_t>> lists_;
  const std::vector<std::uint32_t>* flat_ = nullptr;  // Samples::neighbours
  std::size_t each_ = 0, k_ = 0;
};

std::vector<std::vector<std::size_t>> regions_on_points(const Samples& s, const PlaneParams& p,
                                                        int threads) {
  PwnVec pts;
  pts.reserve(s.points.size());
  for (std::size_t i = 0; i < s.points.size(); ++i)
    pts.emplace_back(toP(s.points[i]), V3(s.normals[i].x(), s.normals[i].y(), s.normals[i].z()));
  using KNQ = SD::Point_set::K_neighbor_query<K, PwnVec, PMap>;
  using NQ = Cached_neighbor_query;
  using RT = SD::Point_set::Least_squares_plane_fit_region<K, PwnVec, PMap, NMap>;
  using Sorting = SD::Point_set::Least_squares_plane_fit_sorting<K, PwnVec, NQ, PMap>;
  using RG = SD::Region_growing<PwnVec, NQ, RT, Sorting::Seed_map>;
  const std::size_t k = static_cast<std::size_t>(std::max(3, p.k_neighbors));
  // The normal estimation's lists hold k + 1 when its k is this one.
  const bool reuse = s.neighbours_each > 0 &&
                     s.neighbours.size() == s.points.size() * s.neighbours_each &&
                     s.neighbours_each >= std::min(k, s.points.size());
  NQ nq = reuse ? NQ(s, k) : NQ(KNQ(pts, k), pts.size(), threads);
  RT rt(pts, p.epsilon, std::min(90.0, p.max_angle_deg),
        static_cast<std::size_t>(std::max(3, p.min_region_size)));
  Sorting sorting(pts, nq);
  sorting.sort();
  RG rg(pts, nq, rt, sorting.seed_map());
  std::vector<std::vector<std::size_t>> regions;
  rg.detect(std::back_inserter(regions));
  return regions;
}

/// Region type on mesh faces: CGAL's, but a region is valid with >= sigma faces
/// OR an area >= sigma * 0.25 m^2 (coarse meshes: a few big triangles per plane).
template <class Base>
class Mesh_region {
 public:
  Mesh_region(Base& b, const std::vector<double>& area, std::size_t sigma)
      : base_(b), area_(area), sigma_(sigma) {}
  bool is_part_of_region(std::size_t a, std::size_t q, const std::vector<std::size_t>& r) const {
    return base_.is_part_of_region(a, q, r);
  }
  bool is_valid_region(const std::vector<std::size_t>& r) const {
    if (r.size() >= sigma_) return true;
    double a = 0;
    for (std::size_t f : r) a += area_[f];
    return a >= 0.25 * static_cast<double>(sigma_);
  }
  void update(const std::vector<std::size_t>& r) { base_.update(r); }

 private:
  Base& base_;
  const std::vector<double>& area_;
  std::size_t sigma_;
};

/// Region growing over the faces of the input mesh. Returns regions as lists of
/// input triangle indices; false when the soup cannot be made a polygon mesh.
bool regions_on_mesh(const BuildingInput& in, const PlaneParams& p,
                     std::vector<std::vector<int>>& out) {
  namespace PMP = CGAL::Polygon_mesh_processing;
  std::vector<P3> pts;
  pts.reserve(in.points.size());
  for (const auto& v : in.points) pts.push_back(toP(v));
  std::vector<std::vector<std::size_t>> polys;
  std::vector<int> tri_of;  // soup polygon -> input triangle
  const int nv = static_cast<int>(in.points.size());
  for (std::size_t t = 0; t < in.triangles.size(); ++t) {
    const auto& tr = in.triangles[t];
    if (tr[0] < 0 || tr[1] < 0 || tr[2] < 0 || tr[0] >= nv || tr[1] >= nv || tr[2] >= nv) continue;
    if (tr[0] == tr[1] || tr[1] == tr[2] || tr[0] == tr[2]) continue;
    if (CGAL::collinear(pts[tr[0]], pts[tr[1]], pts[tr[2]])) continue;
    polys.push_back({std::size_t(tr[0]), std::size_t(tr[1]), std::size_t(tr[2])});
    tri_of.push_back(static_cast<int>(t));
  }
  if (polys.empty()) return false;
  const std::size_t npoly = polys.size();
  PMP::orient_polygon_soup(pts, polys);
  if (polys.size() != npoly || !PMP::is_polygon_soup_a_polygon_mesh(polys)) return false;
  using SM = CGAL::Surface_mesh<P3>;
  SM sm;
  PMP::polygon_soup_to_polygon_mesh(pts, polys, sm);
  if (sm.number_of_faces() != npoly) return false;
  std::vector<double> area(npoly);
  for (auto f : sm.faces()) {
    auto h = sm.halfedge(f);
    const P3& a = sm.point(sm.source(h));
    const P3& b = sm.point(sm.target(h));
    const P3& c = sm.point(sm.target(sm.next(h)));
    area[f.idx()] = std::sqrt(CGAL::squared_area(a, b, c));
  }
  using NQ = SD::Polygon_mesh::One_ring_neighbor_query<SM>;
  using RTb = SD::Polygon_mesh::Least_squares_plane_fit_region<K, SM>;
  using RT = Mesh_region<RTb>;
  using Sorting = SD::Polygon_mesh::Least_squares_plane_fit_sorting<K, SM, NQ>;
  using RG = SD::Region_growing<SM::Face_range, NQ, RT, Sorting::Seed_map>;
  NQ nq(sm);
  const auto vpm = get(CGAL::vertex_point, sm);
  RTb rtb(sm, p.epsilon, std::min(90.0, p.max_angle_deg), 1, vpm);
  RT rt(rtb, area, static_cast<std::size_t>(std::max(1, p.min_region_size)));
  Sorting sorting(sm, nq, vpm);
  sorting.sort();
  const auto fr = sm.faces();
  RG rg(fr, nq, rt, sorting.seed_map());
  std::vector<std::vector<std::size_t>> regions;
  rg.detect(std::back_inserter(regions));
  out.clear();
  for (const auto& r : regions) {
    std::vector<int> tris;
    tris.reserve(r.size());
    for (std::size_t f : r) tris.push_back(tri_of[f]);
    out.push_back(std::move(tris));
  }
  return true;
}

}  // namespace

/// Orthonormal in-plane frame with u x v = n (u horizontal for non-horizontal planes).
void plane_frame(const Vec3& n, Vec3& u, Vec3& v) {
  if (std::abs(n.z()) < 0.9)
    u = Vec3::UnitZ().cross(n).normalized();
  else
    u = n.cross(Vec3::UnitX()).cross(n).normalized();  // X projected on the plane
  v = n.cross(u);
}

// ---------------------------------------------------------------- shapes

namespace {

/// Alpha-shape: the Delaunay faces a REGULARIZED CGAL::Alpha_shape_2 classifies
/// INTERIOR for squared alpha a^2, i.e. those whose circumcircle has a squared
/// radius <= a^2. Computed directly on the triangulation: Alpha_shape_2 first
/// builds the whole alpha spectrum, ~10x slower (3 s for 96k points).
/// The triangles (lifted to 3D about the origin c) go to prim.alpha_tris,
/// their area to prim.alpha_area.
void alpha_shape(Primitive& prim, const std::vector<P2>& pts2, const Vec3& c, double alpha) {
  auto lift = [&](double x, double y) -> Vec3 { return c + x * prim.u + y * prim.v; };
  using DtFb = CGAL::Triangulation_face_base_with_info_2<char, K>;
  using Dt = CGAL::Delaunay_triangulation_2<
      K, CGAL::Triangulation_data_structure_2<CGAL::Triangulation_vertex_base_2<K>, DtFb>>;
  Dt dt(pts2.begin(), pts2.end());
  const double a2 = alpha * alpha;
  if (dt.dimension() == 2) {
    for (auto f = dt.all_faces_begin(); f != dt.all_faces_end(); ++f) f->info() = 0;
    for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
      const P2& a = f->vertex(0)->point();
      const P2& b = f->vertex(1)->point();
      const P2& d = f->vertex(2)->point();
      if (CGAL::squared_radius(a, b, d) > a2) continue;
      const double ar =
          0.5 * ((b.x() - a.x()) * (d.y() - a.y()) - (d.x() - a.x()) * (b.y() - a.y()));
      if (!(ar > 0)) continue;  // Delaunay faces are CCW; skip flat ones
      f->info() = 1;
      prim.alpha_area += ar;
    }
    // The same region with far fewer triangles (the ray labelling casts
    // hundreds of thousands of rays at them): a constrained triangulation of
    // the shape's boundary edges, faces kept at odd nesting levels.
    using Fb = CGAL::Constrained_triangulation_face_base_2<
        K, CGAL::Triangulation_face_base_with_info_2<int, K>>;
    using Tds = CGAL::Triangulation_data_structure_2<CGAL::Triangulation_vertex_base_2<K>, Fb>;
    using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;
    Cdt cdt;
    for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
      if (!f->info()) continue;
      for (int i = 0; i < 3; ++i)
        if (!f->neighbor(i)->info())
          cdt.insert_constraint(f->vertex(Dt::ccw(i))->point(), f->vertex(Dt::cw(i))->point());
    }
    for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -1;
    // Flood fill by nesting level: crossing a constrained edge adds one.
    std::vector<Cdt::Edge> border;
    auto fill = [&](Cdt::Face_handle start, int level) {
      std::vector<Cdt::Face_handle> stack{start};
      while (!stack.empty()) {
        const auto f = stack.back();
        stack.pop_back();
        if (f->info() != -1) continue;
        f->info() = level;
        for (int i = 0; i < 3; ++i) {
          const auto g = f->neighbor(i);
          if (g->info() != -1) continue;
          if (cdt.is_constrained(Cdt::Edge(f, i)))
            border.emplace_back(f, i);
          else
            stack.push_back(g);
        }
      }
    };
    fill(cdt.infinite_face(), 0);
    for (std::size_t b = 0; b < border.size(); ++b) {
      const auto g = border[b].first->neighbor(border[b].second);
      if (g->info() == -1) fill(g, border[b].first->info() + 1);
    }
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
      if (f->info() % 2 != 1) continue;
      const P2& a = f->vertex(0)->point();
      const P2& b = f->vertex(1)->point();
      const P2& d = f->vertex(2)->point();
      prim.alpha_tris.push_back({lift(a.x(), a.y()), lift(b.x(), b.y()), lift(d.x(), d.y())});
    }
  }
}

}  // namespace

void compute_shape(Primitive& prim, const Samples& s, const AlphaParams& p) {
  prim.hull.clear();
  prim.alpha_tris.clear();
  prim.hull_area = prim.alpha_area = 0;
  Vec3 n = prim.normal;
  if (!(n.norm() > 1e-12)) n = Vec3::UnitZ();
  n.normalize();
  prim.normal = n;
  plane_frame(n, prim.u, prim.v);
  // Origin: the inliers' centroid projected on the plane.
  Vec3 c = Vec3::Zero();
  if (!prim.inliers.empty()) {
    for (int i : prim.inliers) c += s.points[i];
    c /= double(prim.inliers.size());
  } else {
    c = prim.centroid;
  }
  c -= (n.dot(c) + prim.d) * n;
  prim.centroid = c;
  if (prim.inliers.size() < 3) return;

  std::vector<P2> pts2;
  pts2.reserve(prim.inliers.size());
  for (int i : prim.inliers) {
    const Vec3 r = s.points[i] - c;
    pts2.emplace_back(r.dot(prim.u), r.dot(prim.v));
  }
  auto lift = [&](double x, double y) -> Vec3 { return c + x * prim.u + y * prim.v; };

  std::vector<P2> hull2;
  CGAL::convex_hull_2(pts2.begin(), pts2.end(), std::back_inserter(hull2));
  if (hull2.size() >= 3) {
    double a = 0;
    for (std::size_t i = 0; i < hull2.size(); ++i) {
      const P2& p0 = hull2[i];
      const P2& p1 = hull2[(i + 1) % hull2.size()];
      a += p0.x() * p1.y() - p1.x() * p0.y();
    }
    prim.hull_area = 0.5 * a;
    for (const auto& q : hull2) prim.hull.push_back(lift(q.x(), q.y()));
  } else {
    return;  // collinear support: no area
  }

  alpha_shape(prim, pts2, c, p.alpha);
  if (prim.alpha_tris.empty()) {
    for (std::size_t i = 1; i + 1 < prim.hull.size(); ++i)
      prim.alpha_tris.push_back({prim.hull[0], prim.hull[i], prim.hull[i + 1]});
    prim.alpha_area = prim.hull_area;
  }
}

// ---------------------------------------------------------------- detection

std::vector<Primitive> detect_planes(const BuildingInput& in, const Samples& s,
                                     const PlaneParams& p, const AlphaParams& alpha, int threads,
                                     int* found) {
  std::vector<Primitive> prims;
  if (s.points.size() < 3) return prims;
  std::vector<std::vector<int>> regions;  // sample indices
  bool done = false;
  if (in.is_mesh() && s.face_of.size() == s.points.size()) {
    std::vector<std::vector<int>> face_regions;
    if (regions_on_mesh(in, p, face_regions)) {
      std::vector<std::vector<int>> samples_of(in.triangles.size());
      for (std::size_t i = 0; i < s.face_of.size(); ++i)
        if (s.face_of[i] >= 0 && s.face_of[i] < int(in.triangles.size()))
          samples_of[s.face_of[i]].push_back(int(i));
      for (const auto& fr : face_regions) {
        std::vector<int> r;
        for (int t : fr) r.insert(r.end(), samples_of[t].begin(), samples_of[t].end());
        if (r.size() < 3) continue;
        std::sort(r.begin(), r.end());
        regions.push_back(std::move(r));
      }
      done = true;
    }
  }
  if (!done) {
    for (auto& r : regions_on_points(s, p, threads)) {
      std::vector<int> ri(r.begin(), r.end());
      std::sort(ri.begin(), ri.end());
      regions.push_back(std::move(ri));
    }
  }
  // Largest first (inlier count; mesh: sample count ~ area), ties by smallest index.
  std::sort(regions.begin(), regions.end(),
            [](const std::vector<int>& a, const std::vector<int>& b) {
              if (a.size() != b.size()) return a.size() > b.size();
              return a.front() < b.front();
            });
  if (found) *found = int(regions.size());
  if (p.max_planes > 0 && regions.size() > std::size_t(p.max_planes)) regions.resize(p.max_planes);
  const AlphaParams& ap = alpha;
  prims.reserve(regions.size());
  for (auto& r : regions) {
    Primitive prim;
    prim.inliers = std::move(r);
    fit_plane(prim, s);
    compute_shape(prim, s, ap);
    prims.push_back(std::move(prim));
  }
  return prims;
}

}  // namespace citylod::lod::detail
