// Adaptive regularization (paper Section 4.1): the principal planes mildly
// (CGAL Shape_regularization), the secondary structures relative to their host,
// with cuboid templates for windows.
#include "regularization.hpp"

#include "epick.hpp"

#include <CGAL/Shape_regularization/regularize_planes.h>
#include <CGAL/property_map.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

namespace citylod::lod::detail {

namespace {

using namespace epick;

constexpr double kDeg = M_PI / 180.0;

Primitive make_rectangle_primitive(const Vec3& normal, const Vec3& corner, const Vec3& e1,
                                   const Vec3& e2) {
  Primitive p;
  p.normal = normal.normalized();
  const Vec3 c0 = corner, c1 = corner + e1, c2 = corner + e1 + e2, c3 = corner + e2;
  p.centroid = (c0 + c1 + c2 + c3) / 4.0;
  p.d = -p.normal.dot(p.centroid);
  p.u = e1.normalized();
  p.v = p.normal.cross(p.u).normalized();
  std::vector<Vec3> loop{c0, c1, c2, c3};
  if ((c1 - c0).cross(c2 - c0).dot(p.normal) < 0) std::reverse(loop.begin(), loop.end());
  p.hull = loop;
  p.alpha_tris = {{loop[0], loop[1], loop[2]}, {loop[0], loop[2], loop[3]}};
  p.hull_area = p.alpha_area = e1.norm() * e2.norm();
  p.from_template = true;
  return p;
}

}  // namespace

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

namespace {

/// Orientation snapping relative to the host: a secondary primitive within
/// the angle of parallel (perpendicular) to its host's normal is made so, on a
/// vertical host also horizontal or vertical; its plane goes through the
/// centroid of its inliers.
void snap_to_host(std::vector<Primitive>& prims, const Grouping::Cluster& cl, const Vec3& nh,
                  bool host_vertical, double cos_par, double sin_perp, const Samples& samples,
                  const AlphaParams& a) {
  for (int qi : cl.primitives) {
    Primitive& q = prims[size_t(qi)];
    if (q.inliers.empty()) continue;
    const double c = q.normal.dot(nh);
    Vec3 n = q.normal;
    if (std::abs(c) > cos_par) {
      n = (c > 0 ? 1.0 : -1.0) * nh;
    } else if (std::abs(c) < sin_perp) {
      n = (n - c * nh).normalized();
      if (host_vertical) {
        if (std::abs(n.z()) > cos_par)
          n = Vec3(0, 0, n.z() > 0 ? 1 : -1);
        else if (std::abs(n.z()) < sin_perp)
          n = Vec3(n.x(), n.y(), 0).normalized();
      }
    } else {
      continue;
    }
    Vec3 centroid = Vec3::Zero();
    for (int s : q.inliers) centroid += samples.points[size_t(s)];
    centroid /= double(q.inliers.size());
    q.normal = n;
    q.d = -n.dot(centroid);
    compute_shape(q, samples, a);
  }
}

/// Coplanarity within the cluster: parallel primitives closer than
/// p.secondary_distance get their weighted mean offset.
void merge_coplanar(std::vector<Primitive>& prims, const Grouping::Cluster& cl,
                    const RegularizationParams& p, const Samples& samples, const AlphaParams& a) {
  for (size_t i = 0; i < cl.primitives.size(); ++i)
    for (size_t j = i + 1; j < cl.primitives.size(); ++j) {
      Primitive& q1 = prims[size_t(cl.primitives[i])];
      Primitive& q2 = prims[size_t(cl.primitives[j])];
      if (q1.inliers.empty() || q2.inliers.empty()) continue;
      if ((q1.normal - q2.normal).norm() > 1e-12) continue;
      if (std::abs(q1.d - q2.d) < p.secondary_distance) {
        const double w1 = double(q1.inliers.size()), w2 = double(q2.inliers.size());
        const double d = (w1 * q1.d + w2 * q2.d) / (w1 + w2);
        q1.d = q2.d = d;
        compute_shape(q1, samples, a);
        compute_shape(q2, samples, a);
      }
    }
}

/// Cuboid templates for the cut-outs of a cluster on a vertical host: each
/// cut-out's box (its cells' extent, against the wall) as five rectangles
/// that replace the cut-out's primitives in the cluster. Returns the number
/// of templates made.
int window_templates(std::vector<Primitive>& prims, Grouping::Cluster& cl, const Primitive& host,
                     const IoView& view, const Bsp& bsp) {
  const Vec3 nh = host.normal;
  int made = 0;
  const Vec3 ax = Vec3(nh.x(), nh.y(), 0).normalized();  // out of the wall
  const Vec3 bz = Vec3::UnitZ();
  const Vec3 cy = bz.cross(ax).normalized();  // along the wall
  const double a_wall = -host.d / nh.dot(ax);
  std::vector<int> replaced;
  std::vector<int> added;
  for (int si : cl.structures) {
    const Structure& st = view.structures[size_t(si)];
    if (st.addon) continue;
    double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300, cmin = 1e300, cmax = -1e300;
    for (int leaf : view.regions[size_t(st.region)].leaves)
      for (const auto& x : bsp.cell_vertices(leaf)) {
        amin = std::min(amin, x.dot(ax));
        amax = std::max(amax, x.dot(ax));
        bmin = std::min(bmin, x.dot(bz));
        bmax = std::max(bmax, x.dot(bz));
        cmin = std::min(cmin, x.dot(cy));
        cmax = std::max(cmax, x.dot(cy));
      }
    amax = std::min(amax, a_wall);
    if (amax - amin < 0.05 || bmax - bmin < 0.05 || cmax - cmin < 0.05) continue;
    auto P = [&](double aa, double bb, double cc) { return Vec3(aa * ax + bb * bz + cc * cy); };
    const double da = amax - amin, db = bmax - bmin, dc = cmax - cmin;
    std::vector<Primitive> faces;
    faces.push_back(make_rectangle_primitive(ax, P(amin, bmin, cmin), dc * cy, db * bz));  // back
    faces.push_back(
        make_rectangle_primitive(cy, P(amin, bmin, cmin), da * ax, db * bz));  // side c_min
    faces.push_back(
        make_rectangle_primitive(-cy, P(amin, bmin, cmax), da * ax, db * bz));  // side c_max
    faces.push_back(make_rectangle_primitive(bz, P(amin, bmin, cmin), da * ax, dc * cy));  // bottom
    faces.push_back(make_rectangle_primitive(-bz, P(amin, bmax, cmin), da * ax, dc * cy));  // top
    for (auto& f : faces) {
      added.push_back(int(prims.size()));
      prims.push_back(std::move(f));
    }
    for (int pi : st.primitives) replaced.push_back(pi);
    ++made;
  }
  if (!added.empty()) {
    std::vector<int> kept;
    for (int pi : cl.primitives)
      if (std::find(replaced.begin(), replaced.end(), pi) == replaced.end()) kept.push_back(pi);
    kept.insert(kept.end(), added.begin(), added.end());
    std::stable_sort(kept.begin(), kept.end(), [&](int x, int y) {
      const double ax_ = prims[size_t(x)].alpha_area, ay_ = prims[size_t(y)].alpha_area;
      return ax_ != ay_ ? ax_ > ay_ : x < y;
    });
    cl.primitives = kept;
  }
  return made;
}

}  // namespace

int regularize_secondary(std::vector<Primitive>& prims, Grouping& grouping, const IoView& view,
                         const Bsp& bsp, const Samples& samples, const RegularizationParams& p,
                         const AlphaParams& a) {
  if (!p.enabled) return 0;
  const double cos_par = std::cos(p.secondary_angle_deg * kDeg);
  const double sin_perp = std::sin(p.secondary_angle_deg * kDeg);
  int templates = 0;
  for (auto& cl : grouping.clusters) {
    if (cl.host < 0) continue;
    const Primitive host = prims[size_t(cl.host)];
    const Vec3 nh = host.normal;
    const bool host_vertical = std::abs(nh.z()) < std::sin(p.vertical_host_deg * kDeg);
    snap_to_host(prims, cl, nh, host_vertical, cos_par, sin_perp, samples, a);
    merge_coplanar(prims, cl, p, samples, a);
    // Cuboid templates for windows: > 3 cut-outs on a near-vertical host.
    if (!host_vertical || cl.cutouts < p.min_cutouts_for_templates) continue;
    templates += window_templates(prims, cl, host, view, bsp);
  }
  return templates;
}

}  // namespace citylod::lod::detail
