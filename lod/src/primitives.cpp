// Samples, plane detection (CGAL region growing), alpha-shapes / convex hulls,
// regularization of the principal planes.
#include "primitives.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing_on_point_set.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing_on_polygon_mesh.h>
#include <CGAL/Shape_regularization/regularize_planes.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/convex_hull_2.h>
#include <CGAL/mst_orient_normals.h>
#include <CGAL/pca_estimate_normals.h>
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

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;
using V3 = K::Vector_3;
using P2 = K::Point_2;

inline P3 toP(const Vec3& v) {
  return P3(v.x(), v.y(), v.z());
}
inline Vec3 toE(const P3& p) {
  return Vec3(p.x(), p.y(), p.z());
}
inline Vec3 toE(const V3& p) {
  return Vec3(p.x(), p.y(), p.z());
}

bool finite(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

/// Orthonormal in-plane frame with u x v = n (u horizontal for non-horizontal planes).
void plane_frame(const Vec3& n, Vec3& u, Vec3& v) {
  if (std::abs(n.z()) < 0.9)
    u = Vec3::UnitZ().cross(n).normalized();
  else
    u = n.cross(Vec3::UnitX()).cross(n).normalized();  // X projected on the plane
  v = n.cross(u);
}

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

std::vector<std::vector<std::size_t>> regions_on_points(const Samples& s, const PlaneParams& p) {
  PwnVec pts;
  pts.reserve(s.points.size());
  for (std::size_t i = 0; i < s.points.size(); ++i)
    pts.emplace_back(toP(s.points[i]), V3(s.normals[i].x(), s.normals[i].y(), s.normals[i].z()));
  using NQ = SD::Point_set::K_neighbor_query<K, PwnVec, PMap>;
  using RT = SD::Point_set::Least_squares_plane_fit_region<K, PwnVec, PMap, NMap>;
  using Sorting = SD::Point_set::Least_squares_plane_fit_sorting<K, PwnVec, NQ, PMap>;
  using RG = SD::Region_growing<PwnVec, NQ, RT, Sorting::Seed_map>;
  NQ nq(pts, static_cast<std::size_t>(std::max(3, p.k_neighbors)));
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

// ---------------------------------------------------------------- samples

Samples make_samples(const BuildingInput& in, const NormalParams& p, bool mst_orientation) {
  Samples s;
  if (in.is_mesh()) {
    const int nv = static_cast<int>(in.points.size());
    struct T {
      int idx;
      Vec3 a, b, c, n;
      double area;
    };
    std::vector<T> tris;
    tris.reserve(in.triangles.size());
    double total = 0;
    for (std::size_t t = 0; t < in.triangles.size(); ++t) {
      const auto& tr = in.triangles[t];
      if (tr[0] < 0 || tr[1] < 0 || tr[2] < 0 || tr[0] >= nv || tr[1] >= nv || tr[2] >= nv)
        continue;
      const Vec3 &a = in.points[tr[0]], &b = in.points[tr[1]], &c = in.points[tr[2]];
      if (!finite(a) || !finite(b) || !finite(c)) continue;
      const Vec3 cr = (b - a).cross(c - a);
      const double area = 0.5 * cr.norm();
      if (!(area > 1e-12)) continue;
      tris.push_back({static_cast<int>(t), a, b, c, cr / (2 * area), area});
      total += area;
    }
    // Target density >= 1 sample / 0.25 m^2, total capped at ~200k.
    const std::size_t cap = 200000;
    double per_m2 = 4.0;
    if (tris.size() >= cap)
      per_m2 = 0.0;
    else if (total * per_m2 + tris.size() > cap)
      per_m2 = (cap - tris.size()) / total;
    Rng rng(0x5EED5EEDULL);
    for (const auto& t : tris) {
      int extra = static_cast<int>(std::floor(t.area * per_m2));
      const double w = t.area / (1 + extra);
      s.points.push_back((t.a + t.b + t.c) / 3.0);
      s.normals.push_back(t.n);
      s.weights.push_back(w);
      s.face_of.push_back(t.idx);
      for (int k = 0; k < extra; ++k) {
        double r1 = rng.next(), r2 = rng.next();
        if (r1 + r2 > 1) {
          r1 = 1 - r1;
          r2 = 1 - r2;
        }
        s.points.push_back(t.a + r1 * (t.b - t.a) + r2 * (t.c - t.a));
        s.normals.push_back(t.n);
        s.weights.push_back(w);
        s.face_of.push_back(t.idx);
      }
    }
    return s;
  }

  // Point cloud.
  const bool has_n = in.normals.size() == in.points.size();
  std::vector<int> need;  // points whose normal must be estimated
  for (std::size_t i = 0; i < in.points.size(); ++i) {
    if (!finite(in.points[i])) continue;
    s.points.push_back(in.points[i]);
    Vec3 n = has_n ? in.normals[i] : Vec3::Zero();
    const double len = finite(n) ? n.norm() : 0.0;
    if (len > 1e-12) {
      s.normals.push_back(n / len);
    } else {
      s.normals.push_back(Vec3::Zero());
      need.push_back(static_cast<int>(s.points.size() - 1));
    }
  }
  s.weights.assign(s.points.size(), 1.0);
  s.face_of.assign(s.points.size(), -1);
  if (need.empty() || s.points.size() < 3) {
    for (auto& n : s.normals)
      if (n.squaredNorm() == 0) n = Vec3::UnitZ();
    return s;
  }
  s.normals_estimated = true;
  const unsigned k =
      static_cast<unsigned>(std::max(3, std::min<int>(p.k_neighbors, int(s.points.size()) - 1)));
  // PCA over all points (neighbourhoods need every point), then keep the given normals.
  using Item = std::tuple<P3, V3, int>;
  std::vector<Item> items;
  items.reserve(s.points.size());
  for (std::size_t i = 0; i < s.points.size(); ++i)
    items.emplace_back(toP(s.points[i]), V3(0, 0, 0), int(i));
  using IPMap = CGAL::Nth_of_tuple_property_map<0, Item>;
  using INMap = CGAL::Nth_of_tuple_property_map<1, Item>;
  CGAL::pca_estimate_normals<CGAL::Sequential_tag>(
      items, k, CGAL::parameters::point_map(IPMap()).normal_map(INMap()));
  // Orientation. mst_orient_normals propagates from the highest point (oriented +z)
  // over a Riemannian graph; it reorders the range, hence the index in the tuple.
  // Without it (airborne city chunks: roofs face up, the few wall hits face
  // away from the building's axis) the rules below orient every normal.
  std::vector<char> oriented(s.points.size(), 0);
  if (mst_orientation) {
    auto first_unoriented = CGAL::mst_orient_normals(
        items, k, CGAL::parameters::point_map(IPMap()).normal_map(INMap()));
    for (auto it = items.begin(); it != first_unoriented; ++it) oriented[std::get<2>(*it)] = 1;
  }
  std::vector<Vec3> est(s.points.size());
  for (const auto& it : items) {
    Vec3 n = toE(std::get<1>(it));
    const double len = n.norm();
    est[std::get<2>(it)] = len > 1e-12 ? Vec3(n / len) : Vec3(Vec3::UnitZ());
  }
  // Whole-set flip when most normals point toward the vertical axis through the centroid.
  Vec3 c = Vec3::Zero();
  for (const auto& q : s.points) c += q;
  c /= double(s.points.size());
  double vote = 0;
  for (std::size_t i = 0; i < est.size(); ++i) {
    const Vec3& n = est[i];
    const Vec3 r = s.points[i] - c;
    if (std::abs(n.z()) < 0.5)
      vote += (n.x() * r.x() + n.y() * r.y() > 0) ? 1 : -1;
    else
      vote += n.z() > 0 ? 1 : -1;
  }
  const bool flip_all = vote < 0;
  for (int i : need) {
    Vec3 n = flip_all ? Vec3(-est[i]) : est[i];
    const Vec3 r = s.points[i] - c;
    // Near-horizontal surfaces (|n.z| >= 0.5: roofs, floors seen from above) face
    // up: scans of buildings see no undersides, and airborne roofs must point up.
    // Walls keep the MST orientation; walls the MST did not reach face away from
    // the vertical axis through the centroid. (On the real data this beats both
    // MST alone and the axis rule alone: cgal_building 82 % / 87 % -> see tests.)
    if (std::abs(n.z()) >= 0.5) {
      if (n.z() < 0) n = -n;
    } else if (!oriented[i] && n.x() * r.x() + n.y() * r.y() < 0) {
      n = -n;
    }
    s.normals[i] = n;
  }
  return s;
}

// ---------------------------------------------------------------- shapes

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

  // Alpha-shape: the Delaunay faces a REGULARIZED CGAL::Alpha_shape_2 classifies
  // INTERIOR for squared alpha a^2, i.e. those whose circumcircle has a squared
  // radius <= a^2. Computed directly on the triangulation: Alpha_shape_2 first
  // builds the whole alpha spectrum, ~10x slower (3 s for 96k points).
  using DtFb = CGAL::Triangulation_face_base_with_info_2<char, K>;
  using Dt = CGAL::Delaunay_triangulation_2<
      K, CGAL::Triangulation_data_structure_2<CGAL::Triangulation_vertex_base_2<K>, DtFb>>;
  Dt dt(pts2.begin(), pts2.end());
  const double a2 = p.alpha * p.alpha;
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
  if (prim.alpha_tris.empty()) {
    for (std::size_t i = 1; i + 1 < prim.hull.size(); ++i)
      prim.alpha_tris.push_back({prim.hull[0], prim.hull[i], prim.hull[i + 1]});
    prim.alpha_area = prim.hull_area;
  }
}

// ---------------------------------------------------------------- detection

std::vector<Primitive> detect_planes(const BuildingInput& in, const Samples& s,
                                     const PlaneParams& p) {
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
    for (auto& r : regions_on_points(s, p)) {
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
  if (p.max_planes > 0 && regions.size() > std::size_t(p.max_planes)) regions.resize(p.max_planes);
  // Shapes with the default alpha radius (the paper's 7 m); a caller with another
  // alpha recomputes them with compute_shape.
  const AlphaParams ap;
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

// ---------------------------------------------------------------- regularization

void regularize_principal(std::vector<Primitive>& prims, const std::vector<int>& which,
                          const Samples& s, const RegularizationParams& p, const AlphaParams& a) {
  std::vector<int> sel;
  for (int w : which)
    if (w >= 0 && w < int(prims.size())) sel.push_back(w);
  std::sort(sel.begin(), sel.end());
  sel.erase(std::unique(sel.begin(), sel.end()), sel.end());
  if (sel.size() < 2) return;
  // Points of the selected planes; inferred planes (no inliers) contribute their hull vertices.
  std::vector<P3> pts;
  std::vector<int> plane_of;
  std::vector<K::Plane_3> planes;
  for (std::size_t j = 0; j < sel.size(); ++j) {
    const Primitive& pr = prims[sel[j]];
    planes.emplace_back(pr.normal.x(), pr.normal.y(), pr.normal.z(), pr.d);
    if (!pr.inliers.empty()) {
      for (int i : pr.inliers) {
        pts.push_back(toP(s.points[i]));
        plane_of.push_back(int(j));
      }
    } else {
      for (const auto& h : pr.hull) {
        pts.push_back(toP(h));
        plane_of.push_back(int(j));
      }
      if (pr.hull.empty()) {
        pts.push_back(toP(pr.centroid));
        plane_of.push_back(int(j));
      }
    }
  }
  const std::vector<Vec3> old_n = [&] {
    std::vector<Vec3> v;
    for (int w : sel) v.push_back(prims[w].normal);
    return v;
  }();
  CGAL::Shape_regularization::Planes::regularize_planes(
      planes, pts,
      CGAL::parameters::plane_index_map(CGAL::make_property_map(plane_of))
          .maximum_angle(p.principal_angle_deg)
          .maximum_offset(p.principal_distance)
          .regularize_parallelism(true)
          .regularize_orthogonality(true)
          .regularize_coplanarity(true)
          .regularize_axis_symmetry(false));
  for (std::size_t j = 0; j < sel.size(); ++j) {
    Primitive& pr = prims[sel[j]];
    Vec3 n(planes[j].a(), planes[j].b(), planes[j].c());
    double d = planes[j].d();
    const double len = n.norm();
    if (!(len > 1e-12) || !std::isfinite(d)) continue;
    n /= len;
    d /= len;
    if (n.dot(old_n[j]) < 0) {
      n = -n;
      d = -d;
    }
    pr.normal = n;
    pr.d = d;
    if (!pr.inliers.empty()) {
      compute_shape(pr, s, a);
    } else {
      // Inferred planes: project their outline onto the new plane.
      auto proj = [&](const Vec3& q) -> Vec3 { return q - (n.dot(q) + d) * n; };
      for (auto& h : pr.hull) h = proj(h);
      for (auto& t : pr.alpha_tris)
        for (auto& q : t) q = proj(q);
      pr.centroid = proj(pr.centroid);
      plane_frame(n, pr.u, pr.v);
    }
  }
}

}  // namespace citylod::lod::detail
