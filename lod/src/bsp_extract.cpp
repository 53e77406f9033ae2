// Watertight surface extraction from a labelled partition of an exact BSP.
//
// For each plane pi and side: region = (union of the faces on pi of inside
// cells whose outward normal is that side) minus (union of the faces on pi of
// inside cells on the other side), computed as exact 2D polygon sets (EPECK,
// projection dropping the dominant axis). Regions are lifted back exactly,
// collinear boundary vertices removed, T-junctions resolved by inserting every
// output vertex lying inside an output edge, and each region triangulated with
// an exact constrained Delaunay triangulation. Vertices are welded by exact
// equality and converted to double once. Non-manifold edges are removed by
// relabelling the smallest adjacent out-cell in and extracting again.
#include "bsp_impl.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <stdexcept>
#include <utility>

namespace citylod::lod::detail {

using namespace bspi;

namespace {

using Point2 = K::Point_2;
using Polygon2 = CGAL::Polygon_2<K>;
using PwH = CGAL::Polygon_with_holes_2<K>;
using PSet = CGAL::Polygon_set_2<K>;

struct FaceInfo {
  int nesting = -1;
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
using Fbb = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K, Fbb>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::No_constraint_intersection_requiring_constructions_tag>;

struct Region {
  int plane = -1;
  int side = 1;  ///< outward normal = side * plane normal
  int k = 2;     ///< dropped axis
  std::vector<std::vector<int>> loops;  ///< [0] outer; CCW seen from outside (holes CW)
};

struct PointLess {
  bool operator()(const Point3& a, const Point3& b) const { return CGAL::compare_xyz(a, b) == CGAL::SMALLER; }
};

int dominant_axis(const std::array<double, 4>& c) {
  int k = 0;
  for (int t = 1; t < 3; ++t)
    if (std::abs(c[t]) > std::abs(c[k])) k = t;
  return k;
}

void remove_collinear(std::vector<Point2>& L) {
  bool changed = true;
  while (changed && L.size() > 3) {
    changed = false;
    for (size_t i = 0; i < L.size() && L.size() > 3; ++i) {
      const size_t n = L.size();
      const Point2& a = L[(i + n - 1) % n];
      const Point2& b = L[i];
      const Point2& c = L[(i + 1) % n];
      if (CGAL::collinear(a, b, c) && CGAL::collinear_are_strictly_ordered_along_line(a, b, c)) {
        L.erase(L.begin() + long(i));
        changed = true;
        --i;
      }
    }
  }
}

void mark_domain(CDT& cdt, CDT::Face_handle start, int index, std::deque<CDT::Edge>& border) {
  if (start->info().nesting != -1) return;
  std::deque<CDT::Face_handle> queue{start};
  while (!queue.empty()) {
    CDT::Face_handle fh = queue.front();
    queue.pop_front();
    if (fh->info().nesting != -1) continue;
    fh->info().nesting = index;
    for (int i = 0; i < 3; ++i) {
      CDT::Edge e(fh, i);
      CDT::Face_handle n = fh->neighbor(i);
      if (n->info().nesting == -1) {
        if (cdt.is_constrained(e))
          border.push_back(e);
        else
          queue.push_back(n);
      }
    }
  }
}

void mark_domains(CDT& cdt) {
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info().nesting = -1;
  std::deque<CDT::Edge> border;
  mark_domain(cdt, cdt.infinite_face(), 0, border);
  while (!border.empty()) {
    CDT::Edge e = border.front();
    border.pop_front();
    CDT::Face_handle n = e.first->neighbor(e.second);
    if (n->info().nesting == -1) mark_domain(cdt, n, e.first->info().nesting + 1, border);
  }
}

struct Extracted {
  std::vector<Point3> pts;
  std::vector<Region> regions;
  std::vector<std::vector<int>> region_tris_flat;  // per region: 3*t ids
};

}  // namespace

namespace {

// One extraction pass with fixed labels.
Extracted extract_once(const BspData& I, const std::vector<int>& partition, const std::vector<char>& inside) {
  Extracted X;
  // --- faces per plane, split by outward side
  std::map<int, std::pair<std::vector<Polygon2>, std::vector<Polygon2>>> byplane;
  for (size_t i = 0; i < partition.size(); ++i) {
    if (!inside[i]) continue;
    const Cell& c = I.cells[partition[i]];
    for (const auto& f : c.faces) {
      const int pl = f.poly.plane;
      const int side = f.cell_pos ? -1 : 1;
      const auto& dc = I.dplanes[pl];
      const int k = dominant_axis(dc);
      const int u = (k + 1) % 3, w = (k + 2) % 3;
      std::vector<Point2> pts;
      pts.reserve(f.poly.v.size());
      for (int v : f.poly.v) {
        const Point3& p = I.verts[v].p;
        pts.emplace_back(p.cartesian(u), p.cartesian(w));
      }
      if (side * dc[k] < 0) std::reverse(pts.begin(), pts.end());
      auto& lists = byplane[pl];
      (side > 0 ? lists.first : lists.second).emplace_back(pts.begin(), pts.end());
    }
  }

  std::map<Point3, int, PointLess> weld;
  auto vid = [&](const Point3& p) {
    auto it = weld.find(p);
    if (it != weld.end()) return it->second;
    const int id = int(X.pts.size());
    X.pts.push_back(p);
    weld.emplace(p, id);
    return id;
  };

  for (auto& [pl, lists] : byplane) {
    const auto& dc = I.dplanes[pl];
    const int k = dominant_axis(dc);
    const int u = (k + 1) % 3, w = (k + 2) % 3;
    const Plane3& P = I.planes[pl];
    const FT coef[4] = {P.a(), P.b(), P.c(), P.d()};
    for (int side : {1, -1}) {
      auto& mine = side > 0 ? lists.first : lists.second;
      auto& other = side > 0 ? lists.second : lists.first;
      if (mine.empty()) continue;
      PSet R;
      R.join(mine.begin(), mine.end());
      if (!other.empty()) {
        PSet O;
        O.join(other.begin(), other.end());
        R.difference(O);
      }
      std::vector<PwH> pwhs;
      R.polygons_with_holes(std::back_inserter(pwhs));
      const bool flip = side * dc[k] < 0;
      for (const PwH& ph : pwhs) {
        Region reg;
        reg.plane = pl;
        reg.side = side;
        reg.k = k;
        auto add_loop = [&](const Polygon2& poly) {
          std::vector<Point2> L(poly.vertices_begin(), poly.vertices_end());
          remove_collinear(L);
          if (flip) std::reverse(L.begin(), L.end());
          std::vector<int> ids;
          ids.reserve(L.size());
          for (const Point2& q : L) {
            FT xyz[3];
            xyz[u] = q.x();
            xyz[w] = q.y();
            xyz[k] = -(coef[u] * q.x() + coef[w] * q.y() + coef[3]) / coef[k];
            ids.push_back(vid(Point3(xyz[0], xyz[1], xyz[2])));
          }
          reg.loops.push_back(std::move(ids));
        };
        add_loop(ph.outer_boundary());
        for (auto h = ph.holes_begin(); h != ph.holes_end(); ++h) add_loop(*h);
        X.regions.push_back(std::move(reg));
      }
    }
  }

  // --- T-junctions: insert every output vertex lying strictly inside an output edge
  {
    const size_t nv = X.pts.size();
    std::vector<Vec3> ap(nv);
    double scale = 1.0;
    for (size_t i = 0; i < nv; ++i) {
      ap[i] = Vec3(CGAL::to_double(X.pts[i].x()), CGAL::to_double(X.pts[i].y()), CGAL::to_double(X.pts[i].z()));
      scale = std::max(scale, ap[i].cwiseAbs().maxCoeff());
    }
    const double tol = 1e-7 * scale;
    struct ERef {
      int r, l, i;
    };
    std::vector<ERef> erefs;
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
    std::vector<Box> eboxes, vboxes;
    for (int r = 0; r < int(X.regions.size()); ++r)
      for (int l = 0; l < int(X.regions[r].loops.size()); ++l) {
        const auto& L = X.regions[r].loops[l];
        for (int i = 0; i < int(L.size()); ++i) {
          const Vec3& a = ap[L[i]];
          const Vec3& b = ap[L[(i + 1) % L.size()]];
          double lo3[3], hi3[3];
          for (int t = 0; t < 3; ++t) lo3[t] = std::min(a[t], b[t]) - tol, hi3[t] = std::max(a[t], b[t]) + tol;
          eboxes.emplace_back(lo3, hi3, int(erefs.size()));
          erefs.push_back({r, l, i});
        }
      }
    for (size_t v = 0; v < nv; ++v) {
      double lo3[3], hi3[3];
      for (int t = 0; t < 3; ++t) lo3[t] = ap[v][t] - tol, hi3[t] = ap[v][t] + tol;
      vboxes.emplace_back(lo3, hi3, int(v));
    }
    std::vector<std::pair<int, int>> cand;
    CGAL::box_intersection_d(eboxes.begin(), eboxes.end(), vboxes.begin(), vboxes.end(),
                             [&](const Box& e, const Box& v) { cand.emplace_back(e.info(), v.info()); });
    std::sort(cand.begin(), cand.end());
    std::map<std::pair<int, int>, std::map<int, std::vector<int>>> inserts;  // (r,l) -> i -> vertices
    for (const auto& [ei, v] : cand) {
      const ERef& er = erefs[ei];
      const auto& L = X.regions[er.r].loops[er.l];
      const int a = L[er.i], b = L[(er.i + 1) % L.size()];
      if (v == a || v == b) continue;
      const Point3 &pa = X.pts[a], &pb = X.pts[b], &pv = X.pts[v];
      if (CGAL::collinear(pa, pb, pv) && CGAL::collinear_are_strictly_ordered_along_line(pa, pv, pb))
        inserts[{er.r, er.l}][er.i].push_back(v);
    }
    for (auto& [rl, byedge] : inserts) {
      auto& L = X.regions[rl.first].loops[rl.second];
      std::vector<int> NL;
      NL.reserve(L.size() + byedge.size());
      for (int i = 0; i < int(L.size()); ++i) {
        NL.push_back(L[i]);
        auto it = byedge.find(i);
        if (it == byedge.end()) continue;
        auto& ins = it->second;
        const Point3& pa = X.pts[L[i]];
        std::sort(ins.begin(), ins.end(), [&](int x, int y) {
          return CGAL::compare_distance_to_point(pa, X.pts[x], X.pts[y]) == CGAL::SMALLER;
        });
        for (int v : ins) NL.push_back(v);
      }
      L = std::move(NL);
    }
  }

  // --- triangulate each region
  X.region_tris_flat.resize(X.regions.size());
  for (size_t r = 0; r < X.regions.size(); ++r) {
    const Region& reg = X.regions[r];
    const int k = reg.k, u = (k + 1) % 3, w = (k + 2) % 3;
    const auto& dc = I.dplanes[reg.plane];
    const bool flip = reg.side * dc[k] < 0;  // loops CCW from outside are CW in 2D
    CDT cdt;
    for (const auto& L : reg.loops) {
      std::vector<CDT::Vertex_handle> vh;
      vh.reserve(L.size());
      for (int id : L) {
        const Point3& p = X.pts[id];
        CDT::Vertex_handle h = cdt.insert(Point2(p.cartesian(u), p.cartesian(w)));
        h->info() = id;
        vh.push_back(h);
      }
      for (size_t i = 0; i < vh.size(); ++i) cdt.insert_constraint(vh[i], vh[(i + 1) % vh.size()]);
    }
    mark_domains(cdt);
    auto& tris = X.region_tris_flat[r];
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
      if (f->info().nesting % 2 != 1) continue;
      const int a = f->vertex(0)->info(), b = f->vertex(1)->info(), c = f->vertex(2)->info();
      tris.push_back(a);
      if (flip) {
        tris.push_back(c);
        tris.push_back(b);
      } else {
        tris.push_back(b);
        tris.push_back(c);
      }
    }
  }
  return X;
}

// Undirected edges used by more than two triangles.
std::vector<std::pair<int, int>> nonmanifold_edges(const Extracted& X) {
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : X.region_tris_flat)
    for (size_t i = 0; i + 2 < t.size(); i += 3)
      for (int e = 0; e < 3; ++e) {
        int a = t[i + e], b = t[i + (e + 1) % 3];
        if (a > b) std::swap(a, b);
        edges.emplace_back(a, b);
      }
  std::sort(edges.begin(), edges.end());
  std::vector<std::pair<int, int>> bad;
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i > 2) bad.push_back(edges[i]);
    i = j;
  }
  return bad;
}

bool cell_contains(const BspData& I, const Cell& c, const Point3& p) {
  for (const auto& f : c.faces) {
    const CGAL::Oriented_side s = I.planes[f.poly.plane].oriented_side(p);
    if (f.cell_pos ? s == CGAL::ON_NEGATIVE_SIDE : s == CGAL::ON_POSITIVE_SIDE) return false;
  }
  return true;
}

}  // namespace

BspSurface bspi::extract_surface(const BspData& D, const std::vector<int>& partition, std::vector<char> inside) {
  const auto& cells = D.cells;
  const auto& nodes = D.nodes;
  const auto& verts = D.verts;
  if (inside.size() != partition.size()) throw std::invalid_argument("Bsp::extract: labels / partition size mismatch");
  for (int n : partition)
    if (n < 0 || n >= int(cells.size())) throw std::out_of_range("Bsp::extract: node id");
  BspSurface S;
  Extracted X;
  std::vector<std::pair<Vec3, Vec3>> bbox;  // lazily filled
  const int max_rounds = 64;
  for (int round = 0;; ++round) {
    X = extract_once(D, partition, inside);
    const auto bad = nonmanifold_edges(X);
    if (bad.empty() || round >= max_rounds) break;
    if (bbox.empty()) {
      bbox.resize(partition.size());
      for (size_t i = 0; i < partition.size(); ++i) {
        Vec3 lo3 = Vec3::Constant(1e300), hi3 = Vec3::Constant(-1e300);
        for (int v : D.cell_vertex_ids(cells[partition[i]])) lo3 = lo3.cwiseMin(verts[v].approx), hi3 = hi3.cwiseMax(verts[v].approx);
        bbox[i] = {lo3, hi3};
      }
    }
    std::vector<int> flip;
    for (const auto& [a, b] : bad) {
      const Point3 &pa = X.pts[a], &pb = X.pts[b];
      const Vec3 qa(CGAL::to_double(pa.x()), CGAL::to_double(pa.y()), CGAL::to_double(pa.z()));
      const Vec3 qb(CGAL::to_double(pb.x()), CGAL::to_double(pb.y()), CGAL::to_double(pb.z()));
      const Vec3 elo = qa.cwiseMin(qb), ehi = qa.cwiseMax(qb);
      const double tol = 1e-6 * (1.0 + std::max(elo.cwiseAbs().maxCoeff(), ehi.cwiseAbs().maxCoeff()));
      int best = -1;
      for (size_t i = 0; i < partition.size(); ++i) {
        if (inside[i]) continue;
        if ((bbox[i].first.array() > ehi.array() + tol).any() || (bbox[i].second.array() < elo.array() - tol).any())
          continue;
        const Cell& c = cells[partition[i]];
        if (!cell_contains(D, c, pa) || !cell_contains(D, c, pb)) continue;
        if (best < 0 || nodes[partition[i]].volume < nodes[partition[best]].volume) best = int(i);
      }
      if (best >= 0) flip.push_back(best);
    }
    std::sort(flip.begin(), flip.end());
    flip.erase(std::unique(flip.begin(), flip.end()), flip.end());
    if (flip.empty()) break;
    for (int i : flip) inside[i] = 1;
    S.labels_flipped += int(flip.size());
  }

  S.inside = inside;
  // --- convert once
  S.polygons.vertices.resize(X.pts.size());
  for (size_t i = 0; i < X.pts.size(); ++i)
    S.polygons.vertices[i] = Vec3(CGAL::to_double(X.pts[i].x()), CGAL::to_double(X.pts[i].y()), CGAL::to_double(X.pts[i].z()));
  S.triangles.vertices = S.polygons.vertices;
  S.merged_regions = int(X.regions.size());
  for (size_t r = 0; r < X.regions.size(); ++r) {
    const auto& t = X.region_tris_flat[r];
    for (size_t i = 0; i + 2 < t.size(); i += 3) S.triangles.triangles.push_back({t[i], t[i + 1], t[i + 2]});
    if (X.regions[r].loops.size() == 1) {
      S.polygons.faces.push_back(X.regions[r].loops[0]);
    } else {
      for (size_t i = 0; i + 2 < t.size(); i += 3) S.polygons.faces.push_back({t[i], t[i + 1], t[i + 2]});
    }
  }
  return S;
}

}  // namespace citylod::lod::detail
