// Closure of buildings whose walls or bottom were not scanned: ground/base
// plane, vertical walls through the (simplified) outline, terrain kept as a
// plinth or cut off; close_building runs the phases in order.
#include "closure.hpp"

#include "citylod/lod/polygon2d.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/convex_hull_2.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace citylod::lod::detail {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P2 = K::Point_2;

double signed_area(const std::vector<Vec2>& poly) {
  double a = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec2& p = poly[i];
    const Vec2& q = poly[(i + 1) % poly.size()];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * a;
}

double seg_dist(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double l2 = ab.squaredNorm();
  double t = l2 > 0 ? (p - a).dot(ab) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

}  // namespace

/// Largest outer boundary loop (CCW) of the 2D alpha-shape of the points.
std::vector<Vec2> alpha_outline(const std::vector<Vec2>& xy, double alpha) {
  // Faces of a REGULARIZED alpha-shape for squared alpha a^2 = Delaunay faces with
  // circumradius^2 <= a^2 (computed directly: Alpha_shape_2 builds the whole
  // spectrum first, ~10x slower).
  using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
  using Tds = CGAL::Triangulation_data_structure_2<Vb>;
  using Dt = CGAL::Delaunay_triangulation_2<K, Tds>;
  std::vector<P2> pts;
  pts.reserve(xy.size());
  for (const auto& p : xy) pts.emplace_back(p.x(), p.y());
  Dt dt(pts.begin(), pts.end());
  if (dt.dimension() != 2) return {};
  const double a2 = alpha * alpha;
  int id = 0;
  for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v) v->info() = id++;
  std::vector<Vec2> vpos(id);
  for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
    vpos[v->info()] = Vec2(v->point().x(), v->point().y());
  auto interior = [&](Dt::Face_handle f) {
    return !dt.is_infinite(f) && CGAL::squared_radius(f->vertex(0)->point(), f->vertex(1)->point(),
                                                      f->vertex(2)->point()) <= a2;
  };
  // Boundary half-edges of the interior region, interior on the left.
  std::multimap<int, int> next;  // from -> to
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
    if (!interior(f)) continue;
    for (int i = 0; i < 3; ++i) {
      if (interior(f->neighbor(i))) continue;
      next.emplace(f->vertex(Dt::ccw(i))->info(), f->vertex(Dt::cw(i))->info());
    }
  }
  std::vector<Vec2> best;
  double best_area = 0;
  while (!next.empty()) {
    auto it = next.begin();
    const int start = it->first;
    std::vector<int> loop{start};
    int cur = it->second;
    next.erase(it);
    int guard = 0;
    while (cur != start && guard++ < 10000000) {
      loop.push_back(cur);
      auto jt = next.find(cur);
      if (jt == next.end()) break;
      cur = jt->second;
      next.erase(jt);
    }
    if (cur != start || loop.size() < 3) continue;
    std::vector<Vec2> poly;
    for (int v : loop) poly.push_back(vpos[v]);
    const double a = signed_area(poly);
    if (a > best_area) {
      best_area = a;
      best = std::move(poly);
    }
  }
  return best;
}

namespace {

void dp_rec(const std::vector<Vec2>& p, std::size_t i, std::size_t j, double tol,
            std::vector<char>& keep) {
  if (j <= i + 1) return;
  double dmax = -1;
  std::size_t k = i;
  for (std::size_t m = i + 1; m < j; ++m) {
    const double d = seg_dist(p[m], p[i], p[j]);
    if (d > dmax) {
      dmax = d;
      k = m;
    }
  }
  if (dmax > tol) {
    keep[k] = 1;
    dp_rec(p, i, k, tol, keep);
    dp_rec(p, k, j, tol, keep);
  }
}

}  // namespace

/// Douglas-Peucker on a closed polygon, then merge of nearly collinear edges.
std::vector<Vec2> simplify_closed(std::vector<Vec2> poly, double tol, double angle_deg) {
  const std::size_t n = poly.size();
  if (n <= 4) return poly;
  // Split at vertex 0 and the vertex farthest from it.
  std::size_t far = 0;
  double dmax = -1;
  for (std::size_t i = 1; i < n; ++i) {
    const double d = (poly[i] - poly[0]).squaredNorm();
    if (d > dmax) {
      dmax = d;
      far = i;
    }
  }
  std::vector<Vec2> ext(poly);
  ext.push_back(poly[0]);
  std::vector<char> keep(ext.size(), 0);
  keep[0] = keep[far] = keep[n] = 1;
  dp_rec(ext, 0, far, tol, keep);
  dp_rec(ext, far, n, tol, keep);
  std::vector<Vec2> out;
  for (std::size_t i = 0; i < n; ++i)
    if (keep[i]) out.push_back(poly[i]);
  // Merge nearly collinear consecutive edges and drop very short ones.
  const double ca = std::cos(angle_deg * M_PI / 180.0);
  bool changed = true;
  while (changed && out.size() > 3) {
    changed = false;
    for (std::size_t i = 0; i < out.size() && out.size() > 3; ++i) {
      const Vec2& a = out[(i + out.size() - 1) % out.size()];
      const Vec2& b = out[i];
      const Vec2& c = out[(i + 1) % out.size()];
      const Vec2 e1 = b - a, e2 = c - b;
      const double l1 = e1.norm(), l2 = e2.norm();
      const bool tiny = l1 < 1e-6 || l2 < 1e-6;
      if (tiny || e1.dot(e2) / (l1 * l2) > ca || seg_dist(b, a, c) < 0.5 * tol) {
        out.erase(out.begin() + i);
        changed = true;
        break;
      }
    }
  }
  if (signed_area(out) <= 0) return poly;
  return out;
}

namespace {

/// Triangles (CCW in xy) of a simple polygon, by a constrained Delaunay triangulation.
std::vector<std::array<Vec2, 3>> triangulate(const std::vector<Vec2>& poly) {
  using CDT = CGAL::Constrained_Delaunay_triangulation_2<K>;
  CDT cdt;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec2& a = poly[i];
    const Vec2& b = poly[(i + 1) % poly.size()];
    cdt.insert_constraint(P2(a.x(), a.y()), P2(b.x(), b.y()));
  }
  std::vector<std::array<Vec2, 3>> out;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    const P2 &a = f->vertex(0)->point(), &b = f->vertex(1)->point(), &c = f->vertex(2)->point();
    const Vec2 g((a.x() + b.x() + c.x()) / 3, (a.y() + b.y() + c.y()) / 3);
    if (!poly2::point_in_ring(poly, g)) continue;
    out.push_back({Vec2(a.x(), a.y()), Vec2(b.x(), b.y()), Vec2(c.x(), c.y())});
  }
  return out;
}

/// Phase 1: the samples' height range, and whether walls are missing: few
/// samples face sideways, or those that do formed no wall planes (airborne
/// LiDAR: noisy roof edges, a few facade hits). False when the samples carry
/// no weight.
struct Coverage {
  double zmin = 0, zmax = 0;
  bool walls_unscanned = false;
  bool walls_missing = false;
};
bool find_missing_walls(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                        const std::vector<Primitive>& prims, Coverage& c) {
  double wall_w = 0, total_w = 0;
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const double w = s.weights.empty() ? 1.0 : s.weights[i];
    total_w += w;
    if (std::abs(s.normals[i].z()) < 0.3) wall_w += w;
    zmin = std::min(zmin, s.points[i].z());
    zmax = std::max(zmax, s.points[i].z());
  }
  c.zmin = zmin;
  c.zmax = zmax;
  if (total_w <= 0) return false;
  double vertical_area = 0, prim_area = 0;
  for (const auto& pr : prims) {
    if (pr.inferred) continue;
    prim_area += pr.alpha_area;
    if (std::abs(pr.normal.z()) < 0.3) vertical_area += pr.alpha_area;
  }
  c.walls_unscanned = wall_w / total_w < p.wall_fraction_min || vertical_area < 0.1 * prim_area;
  c.walls_missing = c.walls_unscanned || (p.footprint_walls && in.footprint.size() >= 3);
  return true;
}

/// Phase 2: floor and terrain. An open bottom (facade scans, meshes standing
/// on a terrain sheet) lets the ray labelling leak as much as missing walls
/// do: close it with a base plane unless a downward-facing horizontal
/// primitive already lies at the bottom. A terrain sheet (a large
/// upward-facing plane at the bottom, as in photogrammetry meshes cut out of a
/// city model) is kept as a plinth or cut off (p.terrain). Terrain reaches the
/// edge of the cut-out scene and lies mostly outside the building; interior
/// floors seen through windows (terrestrial scans) stop at the walls, short of
/// the scene's bounding box (eaves, cornices, scanned ground strips stick out
/// further).
struct Terrain {
  bool has_floor = false, on_terrain = false;
  const Primitive* plane = nullptr;    ///< the largest terrain plane
  std::vector<Vec2> building_outline;  ///< over a terrain
  std::vector<char> on_low_up;         ///< samples of upward planes low down (terrain pieces)
};
Terrain find_terrain(const Samples& s, const ClosureParams& p, const std::vector<Primitive>& prims,
                     const Coverage& cov) {
  const double zmin = cov.zmin, zmax = cov.zmax;
  Terrain t;
  double xy_area = 0;
  Vec2 xy_lo(s.points[0].x(), s.points[0].y()), xy_hi = xy_lo;
  for (const auto& q : s.points) {
    xy_lo = xy_lo.cwiseMin(Vec2(q.x(), q.y()));
    xy_hi = xy_hi.cwiseMax(Vec2(q.x(), q.y()));
  }
  xy_area = (xy_hi - xy_lo).prod();
  const double edge_tol = 0.25;  // m: the crop edge is the bounding box
  auto reaches_edge = [&](const Primitive& pr) {
    for (const auto& h : pr.hull)
      if (h.x() < xy_lo.x() + edge_tol || h.x() > xy_hi.x() - edge_tol ||
          h.y() < xy_lo.y() + edge_tol || h.y() > xy_hi.y() - edge_tol)
        return true;
    return false;
  };
  // Upward planes in the lowest quarter of the height range: terrain pieces
  // (or floors); those reaching the scene's edge are terrain.
  auto low_up = [&](const Primitive& pr) {
    return !pr.inferred && pr.normal.z() > 0.9 && pr.centroid.z() < zmin + 0.25 * (zmax - zmin);
  };
  double low_up_area = 0;
  const Primitive*& terrain = t.plane;
  for (const auto& pr : prims) {
    if (!pr.inferred && pr.normal.z() < -0.95 && pr.centroid.z() < zmin + 0.5) t.has_floor = true;
    if (!low_up(pr) || !reaches_edge(pr)) continue;
    low_up_area += pr.alpha_area;
    if (!terrain || pr.alpha_area > terrain->alpha_area) terrain = &pr;
  }
  t.on_terrain = low_up_area > 0.08 * xy_area && !cov.walls_missing;
  if (!t.on_terrain) return t;
  // The building's outline over a terrain: samples clearly above the terrain
  // (walls, roofs), not those of upward planes low down (terrain pieces).
  std::vector<Vec2>& building_outline = t.building_outline;
  std::vector<char>& on_low_up = t.on_low_up;
  on_low_up.assign(s.points.size(), 0);
  for (const auto& pr : prims)
    if (low_up(pr))
      for (int i : pr.inliers) on_low_up[size_t(i)] = 1;
  const Vec3& tn = terrain->normal;
  std::vector<Vec2> xy;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const Vec3& q = s.points[i];
    if (on_low_up[i] || tn.dot(q) + terrain->d < 1.0) continue;  // terrain, or within 1 m above it
    xy.emplace_back(q.x(), q.y());
  }
  if (xy.size() >= 3) building_outline = alpha_outline(xy, p.outline_alpha);
  if (building_outline.size() >= 3) building_outline = simplify_closed(building_outline, 0.4, 10.0);
  // Terrain lies around the building: most of its samples outside the
  // building's outline. A building's own floor with upward (mis-estimated)
  // normals reaches the scene's edge too, but lies under the building.
  std::size_t outside = 0, total = 0;
  for (const auto& pr : prims) {
    if (!low_up(pr) || !reaches_edge(pr)) continue;
    for (int i : pr.inliers) {
      ++total;
      outside += building_outline.size() < 3 ||
                 !poly2::point_in_ring(building_outline,
                                       Vec2(s.points[size_t(i)].x(), s.points[size_t(i)].y()));
    }
  }
  t.on_terrain = 2 * outside > total;
  return t;
}

/// Phase 3: the outline (CCW in xy) the ground and walls stand on: the
/// building's outline over a terrain that is cut off, else the footprint when
/// given (not for a plinth), else the simplified 2D alpha-shape of the samples.
std::vector<Vec2> closure_outline(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                                  const Terrain& t, const Primitive* terrain, bool plinth) {
  std::vector<Vec2> outline;
  if (terrain) {
    outline = t.building_outline;
  } else if (in.footprint.size() >= 3 && !plinth) {
    outline = in.footprint;
    // Drop a closing duplicate vertex.
    if ((outline.front() - outline.back()).norm() < 1e-9) outline.pop_back();
    if (signed_area(outline) < 0) std::reverse(outline.begin(), outline.end());
  } else {
    std::vector<Vec2> xy;
    xy.reserve(s.points.size());
    for (const auto& q : s.points) xy.emplace_back(q.x(), q.y());
    outline = alpha_outline(xy, p.outline_alpha);
    if (outline.size() >= 3) outline = simplify_closed(outline, 0.4, 10.0);
  }
  return outline;
}

/// A point cloud whose lowest samples are roof, not wall bottoms or ground:
/// half of its samples lie within 1 m (the lowest wall) of the lowest one
/// (roof-only LiDAR of a shed or a flat annex, a large low roof).
bool lowest_samples_are_roof(const Samples& s, double zmin) {
  std::size_t low = 0;
  for (const auto& q : s.points) low += q.z() < zmin + 1.0 ? 1 : 0;
  return 2 * low >= s.points.size();
}

/// Phase 4: the ground's height: the input's ground height when given, else
/// the lowest sample -- p.unknown_ground_depth under it for a point cloud
/// whose lowest samples are roof; a plinth's base p.plinth_depth below the lowest sample; on
/// a terrain that is cut off, the terrain plane's height under the outline's
/// centroid.
double ground_height(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                     const Primitive* terrain, const std::vector<Vec2>& outline, bool plinth,
                     double zmin) {
  double gz = in.has_ground_z && !plinth ? in.ground_z : zmin;
  if (!in.has_ground_z && !plinth && !in.is_mesh() && lowest_samples_are_roof(s, zmin))
    gz = zmin - p.unknown_ground_depth;
  if (plinth) gz = zmin - p.plinth_depth;
  if (terrain) {  // the terrain plane's height under the outline's centroid
    Vec2 c = Vec2::Zero();
    for (const auto& q : outline) c += q;
    c /= double(outline.size());
    const Vec3& tn = terrain->normal;
    gz = -(tn.x() * c.x() + tn.y() * c.y() + terrain->d) / tn.z();
  }
  return gz;
}

/// Phase 5, the ground: normal -z (outward = down); CCW about -z = CW in xy.
Primitive ground_plane(const std::vector<Vec2>& outline, double gz) {
  Primitive g;
  g.inferred = true;
  g.normal = -Vec3::UnitZ();
  g.d = gz;  // -z + gz = 0  <=> z = gz
  g.u = Vec3::UnitX();
  g.v = g.normal.cross(g.u);
  std::vector<P2> pts, hull;
  for (const auto& q : outline) pts.emplace_back(q.x(), q.y());
  CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull));
  for (auto it = hull.rbegin(); it != hull.rend(); ++it) g.hull.emplace_back(it->x(), it->y(), gz);
  double ha = 0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const P2& a = hull[i];
    const P2& b = hull[(i + 1) % hull.size()];
    ha += a.x() * b.y() - b.x() * a.y();
  }
  g.hull_area = 0.5 * ha;
  for (const auto& t : triangulate(outline)) {
    g.alpha_tris.push_back(
        {Vec3(t[0].x(), t[0].y(), gz), Vec3(t[2].x(), t[2].y(), gz), Vec3(t[1].x(), t[1].y(), gz)});
    g.alpha_area += 0.5 * std::abs((t[1] - t[0]).x() * (t[2] - t[0]).y() -
                                   (t[2] - t[0]).x() * (t[1] - t[0]).y());
  }
  Vec2 c = Vec2::Zero();
  for (const auto& q : outline) c += q;
  c /= double(outline.size());
  g.centroid = Vec3(c.x(), c.y(), gz);
  return g;
}

/// (ours) The top of an inferred wall along the outline edge a -> b, sampled
/// in bins of about 0.5 m: per bin the highest sample within 1 m of the edge,
/// roof samples (normal.z >= 0.3) taken down or up their own slope to the
/// edge line (a gable wall gets its gable, an eave wall stops at the eave).
/// Empty bins are interpolated; empty when no sample is near the edge.
std::vector<double> wall_profile(const Samples& s, const Vec2& a, const Vec2& b) {
  const Vec2 e = b - a;
  const double len = e.norm();
  const Vec2 dir = e / len, out(dir.y(), -dir.x());  // outward = right of a -> b
  const int nb = std::max(1, int(std::lround(len / 0.5)));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> top(size_t(nb), nan);
  for (std::size_t k = 0; k < s.points.size(); ++k) {
    const Vec3& q = s.points[k];
    const Vec2 r = Vec2(q.x(), q.y()) - a;
    const double t = r.dot(dir), o = r.dot(out);
    if (std::abs(o) > 1.0 || t < -0.25 || t > len + 0.25) continue;
    if (seg_dist(Vec2(q.x(), q.y()), a, b) > 1.0) continue;
    const Vec3& n = s.normals[k];
    double z = q.z();
    if (n.z() >= 0.3) z += o * (n.x() * out.x() + n.y() * out.y()) / n.z();
    const int bin = std::clamp(int(t / len * nb), 0, nb - 1);
    if (std::isnan(top[size_t(bin)]) || z > top[size_t(bin)]) top[size_t(bin)] = z;
  }
  std::vector<int> filled;
  for (int i = 0; i < nb; ++i)
    if (!std::isnan(top[size_t(i)])) filled.push_back(i);
  if (filled.empty()) return {};
  for (int i = 0; i < nb; ++i) {
    if (!std::isnan(top[size_t(i)])) continue;
    const auto hi = std::upper_bound(filled.begin(), filled.end(), i);
    if (hi == filled.begin()) {
      top[size_t(i)] = top[size_t(filled.front())];
    } else if (hi == filled.end()) {
      top[size_t(i)] = top[size_t(filled.back())];
    } else {
      const int i0 = *(hi - 1), i1 = *hi;
      const double w = double(i - i0) / double(i1 - i0);
      top[size_t(i)] = (1 - w) * top[size_t(i0)] + w * top[size_t(i1)];
    }
  }
  return top;
}

/// Phase 6, the walls: one per outline edge, outward = right of the CCW edge
/// direction. Plinth walls reach up to the terrain along the scene's edge
/// (plinth implies on_terrain: on_low_up is set); building walls to the
/// highest sample near the outline edge, or (profile: meshes on a
/// footprint, labelled by rays) up to the roof's profile along the edge
/// (wall_profile), so that a gable or eave wall the scan missed does not
/// stand above the roof and turn the cells over the roof inside. Returns the
/// number of walls added.
int add_outline_walls(const Samples& s, const ClosureParams& p, const std::vector<Vec2>& outline,
                      double gz, const Coverage& cov, bool plinth, bool profile,
                      const std::vector<char>& on_low_up, std::vector<Primitive>& prims) {
  const double zmin = cov.zmin, zmax = cov.zmax;
  int added = 0;
  for (std::size_t i = 0; i < outline.size(); ++i) {
    const Vec2& a = outline[i];
    const Vec2& b = outline[(i + 1) % outline.size()];
    const Vec2 e = b - a;
    const double len = e.norm();
    if (len < 1e-6) continue;
    double top = -std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < s.points.size(); ++k) {
      const Vec3& q = s.points[k];
      if ((!plinth || on_low_up[k]) && seg_dist(Vec2(q.x(), q.y()), a, b) <= 1.0)
        top = std::max(top, q.z());
    }
    if (!std::isfinite(top)) top = plinth ? zmin : zmax;
    const double min_top = gz + (plinth ? p.plinth_depth : 1.0);
    top = std::max(top, min_top);
    std::vector<double> prof = profile && !plinth ? wall_profile(s, a, b) : std::vector<double>{};
    Primitive w;
    w.inferred = true;
    w.normal = Vec3(e.y() / len, -e.x() / len, 0.0);
    w.d = -(w.normal.x() * a.x() + w.normal.y() * a.y());
    w.u = Vec3::UnitZ().cross(w.normal).normalized();  // = edge direction
    w.v = w.normal.cross(w.u);                         // = +z
    // CCW about the outward normal: a, b at the bottom, then b, a at the top.
    const Vec3 A0(a.x(), a.y(), gz), B0(b.x(), b.y(), gz), A1(a.x(), a.y(), top),
        B1(b.x(), b.y(), top);
    w.hull = {A0, B0, B1, A1};
    w.hull_area = len * (top - gz);
    w.centroid = 0.25 * (A0 + B0 + A1 + B1);
    if (prof.empty()) {
      w.alpha_tris = {{A0, B0, B1}, {A0, B1, A1}};
      w.alpha_area = w.hull_area;
    } else {
      // The profile's points: the ends and the bin centres, each clamped to
      // [min_top, top]; quads between them, CCW about the outward normal.
      const int nb = int(prof.size());
      std::vector<std::pair<double, double>> pts;  // (t, height)
      const auto h = [&](int bin) { return std::clamp(prof[size_t(bin)], min_top, top); };
      pts.emplace_back(0.0, h(0));
      for (int k = 0; k < nb; ++k) pts.emplace_back((k + 0.5) * len / nb, h(k));
      pts.emplace_back(len, h(nb - 1));
      w.alpha_area = 0;
      for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
        const Vec2 pa = a + e * (pts[k].first / len), pb = a + e * (pts[k + 1].first / len);
        const Vec3 P0(pa.x(), pa.y(), gz), Q0(pb.x(), pb.y(), gz),
            P1(pa.x(), pa.y(), pts[k].second), Q1(pb.x(), pb.y(), pts[k + 1].second);
        if (pts[k + 1].first - pts[k].first <= 0) continue;
        w.alpha_tris.push_back({P0, Q0, Q1});
        w.alpha_tris.push_back({P0, Q1, P1});
        w.alpha_area +=
            0.5 * (pts[k + 1].first - pts[k].first) * (pts[k].second + pts[k + 1].second - 2 * gz);
      }
    }
    prims.push_back(std::move(w));
    ++added;
  }
  return added;
}

}  // namespace

int snap_inferred_walls(std::vector<Primitive>& prims, double max_off) {
  const double max_sin = std::sin(3.0 * M_PI / 180.0);
  // References: scanned vertical planes, largest first, then inferred walls,
  // longest first (index order breaks ties: deterministic).
  std::vector<int> refs;
  for (std::size_t i = 0; i < prims.size(); ++i)
    if (std::abs(prims[i].normal.z()) < 0.05 && !prims[i].from_template) refs.push_back(int(i));
  std::stable_sort(refs.begin(), refs.end(), [&](int a, int b) {
    const Primitive& A = prims[size_t(a)];
    const Primitive& B = prims[size_t(b)];
    if (A.inferred != B.inferred) return !A.inferred;
    return A.alpha_area > B.alpha_area;
  });
  // Walls in that order: a wall's candidates are the scanned planes and the
  // inferred walls before it (whose equations are final).
  int count = 0;
  for (std::size_t k = 0; k < refs.size(); ++k) {
    Primitive& w = prims[size_t(refs[k])];
    if (!w.inferred || w.hull.size() != 4) continue;
    for (std::size_t j = 0; j < refs.size(); ++j) {
      const Primitive& q = prims[size_t(refs[j])];
      if (j == k || (q.inferred && j > k)) continue;
      if (q.normal.cross(w.normal).norm() > max_sin || q.normal.dot(w.normal) < 0) continue;
      bool near = true;
      for (const Vec3& h : w.hull) near = near && std::abs(q.normal.dot(h) + q.d) <= max_off;
      if (!near) continue;
      const Vec3 n = q.normal;
      const double d = q.d;
      const auto project = [&](Vec3& x) { x -= (n.dot(x) + d) * n; };
      w.normal = n;
      w.d = d;
      for (auto& h : w.hull) project(h);
      project(w.centroid);
      w.u = Vec3::UnitZ().cross(n).normalized();
      w.v = n.cross(w.u);
      ++count;
      break;
    }
  }
  return count;
}

Closure close_building(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                       std::vector<Primitive>& prims, bool outline_walls) {
  Closure res;
  if (!p.enabled || s.points.size() < 3) return res;
  Coverage cov;
  if (!find_missing_walls(in, s, p, prims, cov)) return res;
  Terrain t = find_terrain(s, p, prims, cov);
  // airborne input: walls on the outline, unless the scan stands on a terrain sheet
  cov.walls_missing = cov.walls_missing || (outline_walls && !t.on_terrain);
  // A terrain sheet kept as a plinth: base plane under the whole scene and
  // walls up to the terrain along the scene's outline. The terrain has a hole
  // where the building stands; the ground floor's rays that escape through it
  // meet the plinth's base from inside.
  const bool plinth = t.on_terrain && p.terrain == lod::Terrain::Plinth;
  if (!cov.walls_missing && t.has_floor && !plinth) return res;
  // Cut: on a terrain sheet the base goes under the building only, at the
  // terrain's height (rays from the ground floor escaping through the hole in
  // the terrain would turn the ground floor out).
  const Primitive* terrain = t.plane;
  if (!t.on_terrain || plinth) terrain = nullptr;

  const std::vector<Vec2> outline = closure_outline(in, s, p, t, terrain, plinth);
  if (outline.size() < 3 || !(signed_area(outline) > 0)) return res;
  const double gz = ground_height(in, s, p, terrain, outline, plinth, cov.zmin);
  res.outline = outline;
  res.ground_z = gz;

  prims.push_back(ground_plane(outline, gz));
  res.added = 1;
  res.what = plinth ? Closure::Plinth : Closure::Base;
  if (!cov.walls_missing && !plinth) return res;  // walls were scanned: only the base was missing

  // Meshes (labelled by rays) on a footprint: walls under the roof's profile, and on
  // the plane of a seen wall they nearly coincide with.
  const bool mesh_on_footprint = in.is_mesh() && in.footprint.size() >= 3 && !terrain && !plinth;
  res.added += add_outline_walls(s, p, outline, gz, cov, plinth,
                                 mesh_on_footprint && p.wall_profile, t.on_low_up, prims);
  if (!plinth) res.what = cov.walls_unscanned ? Closure::Walls : Closure::FootprintWalls;
  res.snap_walls = mesh_on_footprint && p.wall_snap > 0;
  if (res.snap_walls) res.snapped = snap_inferred_walls(prims, p.wall_snap);
  return res;
}

}  // namespace citylod::lod::detail
