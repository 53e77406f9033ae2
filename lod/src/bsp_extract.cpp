// Watertight surface extraction from a labelled partition of an exact BSP.
//
// For each plane pi and side: region = (union of the faces on pi of inside
// cells whose outward normal is that side) minus (union of the faces on pi of
// inside cells on the other side). The faces on one plane are convex and, per
// side, interior-disjoint, so the region boundary is computed exactly edge by
// edge: along every face edge, the coverage of both sides of the edge by the
// faces of both sets (their edges on that line, or their interiors crossing
// it) is swept, and each boundary piece is emitted by exactly one owner edge.
// The pieces are chained into loops (pinch vertices resolved by angle), the
// collinear vertices dropped, the loops lifted back to 3D exactly and welded
// by exact equality. T-junctions are resolved by inserting every output vertex
// lying inside an output edge, and each plane side is triangulated with an
// exact constrained Delaunay triangulation; each connected domain is one merged
// region. Vertices are converted to double once. Non-manifold edges (and
// then pinched vertices) are removed by relabelling the smallest adjacent
// out-cell in and extracting again. Everything is exact (EPECK, lazy with
// shallow DAGs; the BSP vertices enter as exact rationals computed with integer
// determinants).
#include "bsp_impl.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <exception>
#include <map>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace citylod::lod::detail {

using namespace bspi;

namespace bspx {

/// A point on the plane (exact): a BSP vertex (vid >= 0) or the intersection
/// of 3 table planes def (the plane itself and two edge planes).
struct EvPt {
  K::Point_2 p;
  int vid = -1;
  std::array<int, 3> def{-1, -1, -1};
};

/// Regions of one plane: the key of its faces, the loops of both sides.
struct PlaneRegions {
  std::vector<int> key;
  std::array<std::vector<std::vector<EvPt>>, 2> loops;
};

/// The crossing points of one plane by its pair of table planes (exact).
using Crossings = std::unordered_map<uint64_t, EvPt>;

/// Exact coordinates of BSP vertices and of crossing points (by their plane
/// triple), and the vertices' 2D projections per dropped axis: computed once
/// per pass, or once per cache when there is one (the values are exact, so
/// reusing them changes nothing).
struct Coords {
  std::unordered_map<int, std::array<ET, 3>> exact;
  std::map<std::array<int, 3>, std::array<ET, 3>> crossing;
  std::unordered_map<int, K::Point_2> proj[3];
};

}  // namespace bspx

namespace bspx {

/// A plane side's triangulation in positions of its loops' points (the loops
/// flattened, each point at its first position).
struct GroupTriangles {
  std::vector<std::vector<int>> faces;
  std::vector<int> tris;
  int regions = 0;
};

inline uint64_t mix(uint64_t h, uint64_t x) {
  h = (h ^ x) * 0xFF51AFD7ED558CCDULL;
  return h ^ (h >> 32);
}

struct KeyHash {
  size_t operator()(const std::vector<uint64_t>& k) const {
    uint64_t h = 0x9E3779B97F4A7C15ULL ^ k.size();
    for (uint64_t x : k) h = mix(h, x);
    return size_t(h);
  }
};

/// Points (a, b, v) by their identities: does v lie strictly inside segment ab?
using Triple = std::array<uint64_t, 3>;
struct TripleHash {
  size_t operator()(const Triple& t) const { return size_t(mix(mix(mix(0, t[0]), t[1]), t[2])); }
};

}  // namespace bspx

struct ExtractCache::Impl {
  std::unordered_map<int, bspx::PlaneRegions> byplane;
  std::unordered_map<int, bspx::Crossings> crossings;  ///< per plane
  bspx::Coords coords;
  /// Triangulations by plane side and loop points (bspx::group_key): a side
  /// whose loops are the same points is the same triangulation.
  std::unordered_map<std::vector<uint64_t>, bspx::GroupTriangles, bspx::KeyHash> groups;
  /// T-junction tests by the identities of the edge's ends and the vertex.
  std::unordered_map<bspx::Triple, bool, bspx::TripleHash> inside_edge;
};
ExtractCache::ExtractCache() : impl(std::make_unique<Impl>()) {}
ExtractCache::~ExtractCache() = default;

namespace {

using bspx::EvPt;

using Point2 = K::Point_2;
using Line2 = K::Line_2;

struct FaceInfo {
  int nesting = -1;
  int domain = -1;
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
using Fbb = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K, Fbb>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<
    K, Tds, CGAL::No_constraint_intersection_requiring_constructions_tag>;

int dominant_axis(const std::array<double, 4>& c) {
  int k = 0;
  for (int t = 1; t < 3; ++t)
    if (std::abs(c[t]) > std::abs(c[k])) k = t;
  return k;
}

/// A face of an inside cell on plane pi, projected (drop axis k), CCW in 2D.
struct F2 {
  std::vector<Point2> p;
  std::vector<int> vid;             ///< BSP vertex ids
  std::vector<int> ep;              ///< edge planes: ep[i] contains edge vid[i] -> vid[i+1]
  std::vector<Eigen::Vector2d> ap;  ///< approximations
  bool a = true;                    ///< outward normal +n (else -n)
};

/// Per-plane context: the table, the projection, and memoized crossing points.
struct PlaneCtx {
  const BspData& I;
  int pl, k, u, w;
  bspx::Crossings& cross;  ///< this plane's, kept in the cache when there is one
  /// Is x exactly known to lie on table plane E? (false means "unknown")
  bool known_on(const EvPt& x, int E) const {
    if (x.vid >= 0) {
      const auto& ps = I.verts[x.vid].planes;
      return std::find(ps.begin(), ps.end(), E) != ps.end();
    }
    return x.def[0] == E || x.def[1] == E || x.def[2] == E;
  }
  /// The point of the plane on table planes E1 and E2 (exact leaves).
  const EvPt& crossing(int E1, int E2) {
    if (E1 > E2) std::swap(E1, E2);
    const uint64_t key = (uint64_t(uint32_t(E1)) << 32) | uint32_t(E2);
    auto it = cross.find(key);
    if (it != cross.end()) return it->second;
    EvPt e;
    e.def = {pl, E1, E2};
    ET c[3];
    I.exact_coords_of(e.def, c);
    e.p = Point2(EK::Point_2(c[u], c[w]));
    return cross.emplace(key, std::move(e)).first->second;
  }
  int common_line_plane(const EvPt& a, const EvPt& b, const EvPt& c) const {
    auto planes_of = [&](const EvPt& x, int buf[3], int& n) -> const int* {
      if (x.vid >= 0) {
        n = int(I.verts[x.vid].planes.size());
        return I.verts[x.vid].planes.data();
      }
      for (int t = 0; t < 3; ++t) buf[t] = x.def[t];
      n = 3;
      return buf;
    };
    int bb[3], nb;
    const int* pb = planes_of(b, bb, nb);
    for (int t = 0; t < nb; ++t)
      if (pb[t] != pl && known_on(a, pb[t]) && known_on(c, pb[t])) return pb[t];
    return -1;
  }
};

/// Key of an exact point by the intervals of its coordinates. All the points
/// welded here are built from exact rational leaves, whose intervals are the
/// tightest ones: equal points have identical keys, so exact comparisons are
/// only needed inside a bucket.
template <int N>
struct IKey {
  std::array<double, 2 * N> v;
  bool operator<(const IKey& o) const { return v < o.v; }
};
inline IKey<2> ikey(const Point2& p) {
  const auto& a = CGAL::approx(p);
  return {{a.x().inf(), a.x().sup(), a.y().inf(), a.y().sup()}};
}
inline IKey<3> ikey(const Point3& p) {
  const auto& a = CGAL::approx(p);
  return {{a.x().inf(), a.x().sup(), a.y().inf(), a.y().sup(), a.z().inf(), a.z().sup()}};
}

/// Exact welding of points (Point2 or Point3) into ids.
template <class Pt, int N>
struct Welder {
  std::map<IKey<N>, std::vector<int>> buckets;
  /// id of an equal point already added, or -1
  int find(const Pt& p, const std::vector<Pt>& pts) const {
    auto it = buckets.find(ikey(p));
    if (it == buckets.end()) return -1;
    for (int id : it->second)
      if (pts[id] == p) return id;
    return -1;
  }
  void add(const Pt& p, int id) { buckets[ikey(p)].push_back(id); }
};

/// Plane-local point table (exact welding).
struct LocalPts {
  std::vector<EvPt> pts;
  std::vector<Point2> xy;
  Welder<Point2, 2> idx;
  std::unordered_map<int, int> byvid;
  std::map<std::array<int, 3>, int> bydef;
  int get(const EvPt& e) {
    std::array<int, 3> key = e.def;
    std::sort(key.begin(), key.end());
    if (e.vid >= 0) {
      auto it = byvid.find(e.vid);
      if (it != byvid.end()) return it->second;
    } else {
      auto it = bydef.find(key);
      if (it != bydef.end()) return it->second;
    }
    int id = idx.find(e.p, xy);
    if (id >= 0) {
      if (pts[id].vid < 0 && e.vid >= 0) pts[id].vid = e.vid;
    } else {
      id = int(pts.size());
      pts.push_back(e);
      xy.push_back(e.p);
      idx.add(e.p, id);
    }
    if (e.vid >= 0)
      byvid.emplace(e.vid, id);
    else
      bydef.emplace(key, id);
    return id;
  }
};

enum : unsigned { AL = 1, AR = 2, BL = 4, BR = 8 };

struct Iv {
  EvPt s, e;
  unsigned fl;
};

/// Buffers reused across edges (fewer small allocations).
struct Scratch {
  std::vector<Iv> ivs;
  std::vector<int> o;
  std::vector<EvPt> cr, ev, u;
  std::vector<unsigned> fl;
  std::vector<int> li;
};

/// Boundary of R+ = A - B (out[0]) and R- = B - A (out[1]) along edge ei of
/// face fi, as directed segments (region on the left in 2D) between local
/// points.
void edge_boundary(PlaneCtx& C, const std::vector<F2>& F, int fi, int ei,
                   const std::vector<int>& cand, LocalPts& L,
                   std::vector<std::pair<int, int>> out[2], Scratch& S) {
  const F2& f = F[fi];
  const int n = int(f.p.size());
  const EvPt P{f.p[ei], f.vid[ei]};
  const EvPt Q{f.p[(ei + 1) % n], f.vid[(ei + 1) % n]};
  const int E = f.ep[ei];  // the edge's line is this plane's intersection with E
  // order along the edge: by the coordinate along which it extends most (the
  // points compared are on the edge's line, so one coordinate decides)
  // (exactly: an edge may be tiny, its approximate direction meaningless)
  const Eigen::Vector2d dap = f.ap[(ei + 1) % n] - f.ap[ei];
  const bool dx0 = CGAL::compare_x(P.p, Q.p) == CGAL::EQUAL,
             dy0 = !dx0 && CGAL::compare_y(P.p, Q.p) == CGAL::EQUAL;
  const bool byx = !dx0 && (dy0 || std::abs(dap.x()) >= std::abs(dap.y()));
  const bool asc =
      byx ? CGAL::compare_x(P.p, Q.p) == CGAL::SMALLER : CGAL::compare_y(P.p, Q.p) == CGAL::SMALLER;
  auto cmp = [byx](const EvPt& x, const EvPt& y) {
    if (x.vid >= 0 ? x.vid == y.vid : (y.vid < 0 && x.def == y.def))
      return CGAL::EQUAL;  // same point
    return byx ? CGAL::compare_x(x.p, y.p) : CGAL::compare_y(x.p, y.p);
  };
  auto less = [&](const EvPt& x, const EvPt& y) {
    return cmp(x, y) == (asc ? CGAL::SMALLER : CGAL::LARGER);
  };
  auto same = [&](const EvPt& x, const EvPt& y) { return cmp(x, y) == CGAL::EQUAL; };
  auto& ivs = S.ivs;
  auto& o = S.o;
  auto& cr = S.cr;
  ivs.clear();
  for (int g : cand) {
    if (g == fi) continue;
    const F2& G = F[g];
    const int m = int(G.p.size());
    o.resize(m);
    bool pos = false, neg = false;
    int zeros = 0;
    for (int j = 0; j < m; ++j) {
      const int gv = G.vid[j];
      o[j] = (gv == P.vid || gv == Q.vid || C.known_on(EvPt{G.p[j], gv}, E))
                 ? 0
                 : int(CGAL::orientation(P.p, Q.p, G.p[j]));
      pos |= o[j] > 0;
      neg |= o[j] < 0;
      zeros += o[j] == 0;
    }
    unsigned fl;
    EvPt s, e;
    if (pos && neg) {
      cr.clear();
      for (int j = 0; j < m; ++j) {
        const int jn = (j + 1) % m;
        if (o[j] == 0) {
          cr.push_back({G.p[j], G.vid[j]});
        } else if (o[j] * o[jn] < 0) {
          cr.push_back(C.crossing(E, G.ep[j]));
        }
      }
      if (cr.size() != 2)
        throw std::logic_error("Bsp::extract: a convex face crosses a line in != 2 points");
      if (less(cr[1], cr[0])) std::swap(cr[0], cr[1]);
      s = cr[0];
      e = cr[1];
      fl = G.a ? (AL | AR) : (BL | BR);
    } else if (zeros == 2) {
      cr.clear();
      for (int j = 0; j < m; ++j)
        if (o[j] == 0) cr.push_back({G.p[j], G.vid[j]});
      if (less(cr[1], cr[0])) std::swap(cr[0], cr[1]);
      s = cr[0];
      e = cr[1];
      fl = pos ? (G.a ? AL : BL) : (G.a ? AR : BR);
    } else {
      continue;
    }
    // clip to [P, Q]
    if (less(s, P)) s = P;
    if (less(Q, e)) e = Q;
    if (!less(s, e)) continue;
    ivs.push_back({s, e, fl});
  }
  auto& ev = S.ev;
  ev.clear();
  ev.push_back(P);
  ev.push_back(Q);
  for (const auto& iv : ivs) {
    ev.push_back(iv.s);
    ev.push_back(iv.e);
  }
  std::stable_sort(ev.begin(), ev.end(), less);
  {
    auto& u = S.u;
    u.clear();
    for (const auto& x : ev) {
      if (!u.empty() && same(u.back(), x)) {
        if (u.back().vid < 0) u.back().vid = x.vid;
        continue;
      }
      u.push_back(x);
    }
    ev.swap(u);
  }
  const int np = int(ev.size()) - 1;
  auto& fl = S.fl;
  fl.assign(np, f.a ? AL : BL);
  auto index_of = [&](const EvPt& x) {
    return int(std::lower_bound(ev.begin(), ev.end(), x, less) - ev.begin());
  };
  for (const auto& iv : ivs) {
    const int is = index_of(iv.s), ie = index_of(iv.e);
    for (int j = is; j < ie; ++j) fl[j] |= iv.fl;
  }
  auto& li = S.li;
  li.assign(ev.size(), -1);
  auto lid = [&](int j) {
    if (li[j] < 0) li[j] = L.get(ev[j]);
    return li[j];
  };
  for (int j = 0; j < np; ++j) {
    const unsigned c = fl[j];
    if (f.a) {
      if (!(c & BL) && !(c & AR)) out[0].emplace_back(lid(j), lid(j + 1));
      if ((c & BR) && !(c & AR) && (c & BL)) out[1].emplace_back(lid(j + 1), lid(j));
    } else {
      if (!(c & AL) && !(c & BR)) out[1].emplace_back(lid(j), lid(j + 1));
      if ((c & AR) && !(c & BR) && (c & AL)) out[0].emplace_back(lid(j + 1), lid(j));
    }
  }
}

/// Chain directed segments (region on the left) into loops of local point ids.
std::vector<std::vector<int>> chain_loops(const std::vector<std::pair<int, int>>& segs,
                                          const LocalPts& L) {
  std::unordered_map<int, std::vector<int>> outs;
  for (int s = 0; s < int(segs.size()); ++s) outs[segs[s].first].push_back(s);
  std::vector<int> next(segs.size(), -1), used(segs.size(), 0);
  for (int s = 0; s < int(segs.size()); ++s) {
    const int u = segs[s].first, v = segs[s].second;
    auto it = outs.find(v);
    if (it == outs.end()) throw std::logic_error("Bsp::extract: open boundary");
    const auto& cand = it->second;
    int best = cand[0];
    if (cand.size() > 1) {
      // first outgoing segment clockwise from the reversed incoming direction
      const Point2& pv = L.pts[v].p;
      const Point2& pu = L.pts[u].p;
      auto bucket = [&](int t) {
        const Point2& w = L.pts[segs[t].second].p;
        const auto o = CGAL::orientation(pv, pu, w);
        if (o == CGAL::RIGHT_TURN) return 0;
        if (o == CGAL::LEFT_TURN) return 2;
        return CGAL::collinear_are_ordered_along_line(pu, pv, w) ? 1 : 3;
      };
      auto before = [&](int t1, int t2) {
        const int b1 = bucket(t1), b2 = bucket(t2);
        if (b1 != b2) return b1 < b2;
        return CGAL::orientation(pv, L.pts[segs[t1].second].p, L.pts[segs[t2].second].p) ==
               CGAL::RIGHT_TURN;
      };
      for (int t : cand)
        if (before(t, best)) best = t;
    }
    if (used[best]++) throw std::logic_error("Bsp::extract: ambiguous boundary at a vertex");
    next[s] = best;
  }
  std::vector<std::vector<int>> loops;
  std::vector<char> seen(segs.size(), 0);
  for (int s0 = 0; s0 < int(segs.size()); ++s0) {
    if (seen[s0]) continue;
    std::vector<int> loop;
    int s = s0;
    do {
      seen[s] = 1;
      loop.push_back(segs[s].first);
      s = next[s];
    } while (s != s0 && !seen[s]);
    if (s != s0) throw std::logic_error("Bsp::extract: boundary chain does not close");
    loops.push_back(std::move(loop));
  }
  return loops;
}

void remove_collinear(std::vector<int>& loop, const LocalPts& L, const PlaneCtx& C) {
  bool changed = true;
  while (changed && loop.size() > 3) {
    changed = false;
    for (size_t i = 0; i < loop.size() && loop.size() > 3; ++i) {
      const size_t n = loop.size();
      const Point2& a = L.pts[loop[(i + n - 1) % n]].p;
      const Point2& b = L.pts[loop[i]].p;
      const Point2& c = L.pts[loop[(i + 1) % n]].p;
      const bool col = C.common_line_plane(L.pts[loop[(i + n - 1) % n]], L.pts[loop[i]],
                                           L.pts[loop[(i + 1) % n]]) >= 0 ||
                       CGAL::collinear(a, b, c);
      if (col && CGAL::collinear_are_strictly_ordered_along_line(a, b, c)) {
        loop.erase(loop.begin() + long(i));
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

/// Output of one plane side.
struct Group {
  int plane = -1, side = 1, k = 2;
  std::vector<std::vector<int>> loops;  ///< global ids, region on the left in 2D
  std::unordered_map<int, Point2> p2;   ///< 2D points of the group's own vertices
  std::vector<std::vector<int>> faces;  ///< output polygons (3D orientation)
  std::vector<int> tris;                ///< output triangles, flat (3D orientation)
  int regions = 0;
};

struct Extracted {
  std::vector<Point3> pts;
  /// Per point, what it was lifted from (point_identity): the same identity is
  /// the same point in every extraction from one BSP.
  std::vector<uint64_t> ident;
  std::vector<Group> groups;
};

constexpr uint64_t kNoIdentity = ~uint64_t(0);

/// A BSP vertex by its id, a crossing point by its plane triple (when each
/// index fits in 21 bits; else none).
uint64_t point_identity(const EvPt& ep) {
  if (ep.vid >= 0) return (uint64_t(1) << 63) | uint64_t(ep.vid);
  uint64_t key = 0;
  for (int d : ep.def) {
    if (d < 0 || d >= (1 << 21)) return kNoIdentity;
    key = (key << 21) | uint64_t(d);
  }
  return key;
}

/// The inside nodes, with every pair of inside siblings replaced by their
/// parent (recursively): same solid, fewer and larger faces.
std::vector<int> collapse_inside(const BspData& I, const std::vector<int>& partition,
                                 const std::vector<char>& inside) {
  std::vector<char> mark(I.nodes.size(), 0);
  std::deque<int> work;
  for (size_t i = 0; i < partition.size(); ++i)
    if (inside[i]) {
      mark[partition[i]] = 1;
      work.push_back(partition[i]);
    }
  while (!work.empty()) {
    const int n = work.front();
    work.pop_front();
    if (!mark[n]) continue;
    const int p = I.nodes[n].parent;
    if (p < 0) continue;
    const auto& ch = I.nodes[p].children;
    if (mark[ch[0]] && mark[ch[1]]) {
      mark[ch[0]] = mark[ch[1]] = 0;
      mark[p] = 1;
      work.push_back(p);
    }
  }
  std::vector<int> out;
  for (int n = 0; n < int(mark.size()); ++n)
    if (mark[n]) out.push_back(n);
  return out;
}

/// Boundary loops of one plane's region, per side (0: outward +n, 1: -n), as
/// exact plane points, collinear vertices dropped.
std::array<std::vector<std::vector<EvPt>>, 2> plane_loops(const BspData& I, int pl,
                                                          const std::vector<F2>& F,
                                                          bspx::Crossings& cross,
                                                          Scratch& scratch) {
  using Box2 = CGAL::Box_intersection_d::Box_with_info_d<double, 2, int>;
  const auto& dc = I.dplanes[pl];
  const int k = dominant_axis(dc);
  const int u = (k + 1) % 3, w = (k + 2) % 3;
  // candidate faces per edge
  double scale = 1.0;
  for (const auto& f : F)
    for (const auto& q : f.ap) scale = std::max(scale, q.cwiseAbs().maxCoeff());
  const double tol = 1e-7 * scale;
  std::vector<Box2> eb, fb;
  std::vector<std::pair<int, int>> erefs;
  for (int fi = 0; fi < int(F.size()); ++fi) {
    const auto& ap = F[fi].ap;
    double flo[2] = {1e300, 1e300}, fhi[2] = {-1e300, -1e300};
    for (int e = 0; e < int(ap.size()); ++e) {
      const auto& a = ap[e];
      const auto& b = ap[(e + 1) % ap.size()];
      double lo2[2], hi2[2];
      for (int t = 0; t < 2; ++t) {
        lo2[t] = std::min(a[t], b[t]) - tol;
        hi2[t] = std::max(a[t], b[t]) + tol;
        flo[t] = std::min(flo[t], lo2[t]);
        fhi[t] = std::max(fhi[t], hi2[t]);
      }
      eb.emplace_back(lo2, hi2, int(erefs.size()));
      erefs.emplace_back(fi, e);
    }
    fb.emplace_back(flo, fhi, fi);
  }
  std::vector<std::vector<int>> cand(erefs.size());
  CGAL::box_intersection_d(
      eb.begin(), eb.end(), fb.begin(), fb.end(),
      [&](const Box2& e, const Box2& f) { cand[e.info()].push_back(f.info()); });
  LocalPts L;
  PlaneCtx C{I, pl, k, u, w, cross};
  std::vector<std::pair<int, int>> segs[2];
  for (int e = 0; e < int(erefs.size()); ++e) {
    std::sort(cand[e].begin(), cand[e].end());
    edge_boundary(C, F, erefs[e].first, erefs[e].second, cand[e], L, segs, scratch);
  }
  std::array<std::vector<std::vector<EvPt>>, 2> out;
  for (int si = 0; si < 2; ++si) {
    if (segs[si].empty()) continue;
    for (auto& loop : chain_loops(segs[si], L)) {
      remove_collinear(loop, L, C);
      std::vector<EvPt> pts;
      pts.reserve(loop.size());
      for (int li : loop) pts.push_back(L.pts[li]);
      out[si].push_back(std::move(pts));
    }
  }
  return out;
}

/// Exact coordinates of the BSP vertices and crossing points one extraction
/// pass uses (kept in the cache when there is one), and the vertices' 2D
/// projections per dropped axis.
struct PassCoords {
  const BspData& I;
  bspx::Coords own;
  bspx::Coords& c;
  std::unordered_map<int, Point2> (&proj)[3];
  PassCoords(const BspData& bsp, ExtractCache* cache)
      : I(bsp), c(cache ? cache->impl->coords : own), proj(c.proj) {}
  const std::array<ET, 3>& coords(int v) {
    auto it = c.exact.find(v);
    if (it != c.exact.end()) return it->second;
    std::array<ET, 3> x;
    I.exact_coords_of(I.verts[v].def, x.data());
    return c.exact.emplace(v, std::move(x)).first->second;
  }
  const std::array<ET, 3>& crossing(const std::array<int, 3>& def) {
    auto it = c.crossing.find(def);
    if (it != c.crossing.end()) return it->second;
    std::array<ET, 3> x;
    I.exact_coords_of(def, x.data());
    return c.crossing.emplace(def, std::move(x)).first->second;
  }
};

/// Phase 1: the faces of the cells `in_nodes` per plane, projected to 2D
/// (oriented so that their side's region lies on the left).
std::map<int, std::vector<F2>> gather_faces(const BspData& I, const std::vector<int>& in_nodes,
                                            PassCoords& pc) {
  std::map<int, std::vector<F2>> byplane;
  for (int node : in_nodes) {
    const Cell& c = I.cells[node];
    for (const auto& f : c.faces) {
      const int pl = f.poly.plane;
      const int side = f.cell_pos ? -1 : 1;
      const auto& dc = I.dplanes[pl];
      const int k = dominant_axis(dc);
      const int u = (k + 1) % 3, w = (k + 2) % 3;
      F2 g;
      g.a = side > 0;
      g.vid = f.poly.v;
      g.ep = f.poly.e;
      if (side * dc[k] < 0) {
        const int n = int(g.vid.size());
        std::reverse(g.vid.begin(), g.vid.end());
        for (int i = 0; i < n; ++i) g.ep[i] = f.poly.e[(2 * n - 2 - i) % n];
      }
      g.p.reserve(g.vid.size());
      g.ap.reserve(g.vid.size());
      for (int v : g.vid) {
        auto it = pc.proj[k].find(v);
        if (it == pc.proj[k].end()) {
          const auto& p = pc.coords(v);
          it = pc.proj[k].emplace(v, Point2(EK::Point_2(p[u], p[w]))).first;
        }
        g.p.push_back(it->second);
        g.ap.emplace_back(I.verts[v].approx[u], I.verts[v].approx[w]);
      }
      byplane[pl].push_back(std::move(g));
    }
  }
  return byplane;
}

/// The faces on one plane with the identical faces of both sides removed
/// (they cancel).
std::vector<F2> cancel_opposite_faces(std::vector<F2>& faces0) {
  std::vector<F2> F;
  std::map<std::vector<int>, std::vector<int>> bykey;
  for (int i = 0; i < int(faces0.size()); ++i) {
    std::vector<int> key = faces0[i].vid;
    std::sort(key.begin(), key.end());
    bykey[key].push_back(i);
  }
  std::vector<char> drop(faces0.size(), 0);
  for (const auto& [key, ids] : bykey)
    if (ids.size() == 2 && faces0[ids[0]].a != faces0[ids[1]].a) drop[ids[0]] = drop[ids[1]] = 1;
  for (int i = 0; i < int(faces0.size()); ++i)
    if (!drop[i]) F.push_back(std::move(faces0[i]));
  return F;
}

/// Phase 2: per plane, the boundary loops of both sides' regions (from the
/// cache when the plane's faces are unchanged), lifted to 3D and welded into
/// X.pts; one Group per plane side.
void plane_regions(const BspData& I, std::map<int, std::vector<F2>>& byplane, ExtractCache* cache,
                   PassCoords& pc, int threads, Extracted& X) {
  Welder<Point3, 3> weld;
  // the id of an exact point: a point welded before, or a new one with the
  // identity of the plane point it is lifted from
  auto gid = [&](const Point3& p, const EvPt& from) {
    int id = weld.find(p, X.pts);
    if (id >= 0) return id;
    id = int(X.pts.size());
    X.pts.push_back(p);
    X.ident.push_back(point_identity(from));
    weld.add(p, id);
    return id;
  };

  // The planes whose loops are not cached, computed on `threads` threads
  // (independent of each other), then lifted in plane order.
  // A plane's crossing points stay in the cache (they are exact): its faces
  // change between candidates, its crossings mostly do not.
  struct Todo {
    int pl;
    std::vector<F2> F;
    bspx::PlaneRegions* out;
    bspx::Crossings* cross;
  };
  std::vector<Todo> todo;
  std::vector<std::pair<int, const bspx::PlaneRegions*>> planes;
  std::deque<bspx::PlaneRegions> fresh;
  std::deque<bspx::Crossings> fresh_cross;
  for (auto& [pl, faces0] : byplane) {
    std::vector<F2> F = cancel_opposite_faces(faces0);
    if (F.empty()) continue;
    // The faces on this plane as a key: unchanged faces give unchanged loops.
    std::vector<int> key;
    for (const auto& f : F) {
      key.push_back(f.a ? -1 : -2);
      key.push_back(int(f.vid.size()));
      key.insert(key.end(), f.vid.begin(), f.vid.end());
      key.insert(key.end(), f.ep.begin(), f.ep.end());
    }
    bspx::PlaneRegions* e = nullptr;
    if (cache) {
      e = &cache->impl->byplane[pl];
      if (e->key != key) {
        e->key = std::move(key);
        todo.push_back({pl, std::move(F), e, &cache->impl->crossings[pl]});
      }
    } else {
      e = &fresh.emplace_back();
      todo.push_back({pl, std::move(F), e, &fresh_cross.emplace_back()});
    }
    planes.emplace_back(pl, e);
  }
  std::vector<std::exception_ptr> errors(todo.size());
  const long nt = long(todo.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (nt > 1 && threads > 1)
  for (long t = 0; t < nt; ++t) {
    try {
      Scratch scratch;
      Todo& d = todo[size_t(t)];
      d.out->loops = plane_loops(I, d.pl, d.F, *d.cross, scratch);
    } catch (...) {
      errors[size_t(t)] = std::current_exception();
    }
  }
  for (const auto& e : errors)
    if (e) {
      if (cache) cache->impl->byplane.clear();  // entries of the failed pass are unfinished
      std::rethrow_exception(e);
    }
  // A BSP vertex or crossing point met again (on another plane's loop) is the
  // point welded before: looked up by its vertex id or plane triple instead of
  // an exact comparison of the lifted points (same ids, no exact arithmetic).
  std::unordered_map<int, int> by_vid;
  std::map<std::array<int, 3>, int> by_def;
  auto lifted_id = [&](const EvPt& ep) {
    if (ep.vid >= 0) {
      auto it = by_vid.find(ep.vid);
      if (it != by_vid.end()) return it->second;
      const auto& c = pc.coords(ep.vid);
      return by_vid.emplace(ep.vid, gid(Point3(EK::Point_3(c[0], c[1], c[2])), ep)).first->second;
    }
    auto it = by_def.find(ep.def);
    if (it != by_def.end()) return it->second;
    const auto& c = pc.crossing(ep.def);
    return by_def.emplace(ep.def, gid(Point3(EK::Point_3(c[0], c[1], c[2])), ep)).first->second;
  };
  for (const auto& [pl, regions] : planes) {
    const auto& loops = regions->loops;
    const int k = dominant_axis(I.dplanes[pl]);
    // loops per side; lift to 3D
    for (int si = 0; si < 2; ++si) {
      if (loops[si].empty()) continue;
      Group G;
      G.plane = pl;
      G.side = si == 0 ? 1 : -1;
      G.k = k;
      for (const auto& loop : loops[si]) {
        std::vector<int> ids;
        ids.reserve(loop.size());
        for (const EvPt& ep : loop) {
          const int id = lifted_id(ep);
          G.p2.emplace(id, ep.p);
          ids.push_back(id);
        }
        G.loops.push_back(std::move(ids));
      }
      X.groups.push_back(std::move(G));
    }
  }
}

/// Phase 3, T-junctions: inserts every output vertex lying strictly inside an
/// output edge.
void insert_tjunctions(Extracted& X, ExtractCache* cache) {
  const size_t nv = X.pts.size();
  std::vector<Vec3> ap(nv);
  double scale = 1.0;
  for (size_t i = 0; i < nv; ++i) {
    ap[i] = Vec3(CGAL::to_double(X.pts[i].x()), CGAL::to_double(X.pts[i].y()),
                 CGAL::to_double(X.pts[i].z()));
    scale = std::max(scale, ap[i].cwiseAbs().maxCoeff());
  }
  const double tol = 1e-7 * scale;
  struct ERef {
    int r, l, i;
  };
  std::vector<ERef> erefs;
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> eboxes, vboxes;
  for (int r = 0; r < int(X.groups.size()); ++r)
    for (int l = 0; l < int(X.groups[r].loops.size()); ++l) {
      const auto& L = X.groups[r].loops[l];
      for (int i = 0; i < int(L.size()); ++i) {
        const Vec3& a = ap[L[i]];
        const Vec3& b = ap[L[(i + 1) % L.size()]];
        double lo3[3], hi3[3];
        for (int t = 0; t < 3; ++t)
          lo3[t] = std::min(a[t], b[t]) - tol, hi3[t] = std::max(a[t], b[t]) + tol;
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
  CGAL::box_intersection_d(
      eboxes.begin(), eboxes.end(), vboxes.begin(), vboxes.end(),
      [&](const Box& e, const Box& v) { cand.emplace_back(e.info(), v.info()); });
  std::sort(cand.begin(), cand.end());
  std::map<std::pair<int, int>, std::map<int, std::vector<int>>> inserts;  // (r,l) -> i -> vertices
  for (const auto& [ei, v] : cand) {
    const ERef& er = erefs[ei];
    const auto& L = X.groups[er.r].loops[er.l];
    const int a = L[er.i], b = L[(er.i + 1) % L.size()];
    if (v == a || v == b) continue;
    const Point3 &pa = X.pts[a], &pb = X.pts[b], &pv = X.pts[v];
    auto test = [&] {
      return CGAL::collinear(pa, pb, pv) &&
             CGAL::collinear_are_strictly_ordered_along_line(pa, pv, pb);
    };
    const bspx::Triple key{X.ident[size_t(a)], X.ident[size_t(b)], X.ident[size_t(v)]};
    bool inside;
    if (!cache || key[0] == kNoIdentity || key[1] == kNoIdentity || key[2] == kNoIdentity) {
      inside = test();
    } else {
      auto it = cache->impl->inside_edge.find(key);
      if (it == cache->impl->inside_edge.end())
        it = cache->impl->inside_edge.emplace(key, test()).first;
      inside = it->second;
    }
    if (inside) inserts[{er.r, er.l}][er.i].push_back(v);
  }
  for (auto& [rl, byedge] : inserts) {
    auto& L = X.groups[rl.first].loops[rl.second];
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

/// Phase 4: triangulates one plane side; each connected domain is one merged
/// region, output as its loop when that is a simple polygon, else as triangles.
void triangulate_group(const BspData& I, const std::vector<Point3>& pts, Group& G) {
  const int k = G.k, u = (k + 1) % 3, w = (k + 2) % 3;
  const bool flip = G.side * I.dplanes[G.plane][k] < 0;  // CCW in 2D is CW seen from outside
  CDT cdt;
  std::unordered_map<uint64_t, int> edge_loop;
  for (int l = 0; l < int(G.loops.size()); ++l) {
    const auto& Lp = G.loops[l];
    std::vector<CDT::Vertex_handle> vh;
    vh.reserve(Lp.size());
    for (int id : Lp) {
      auto it = G.p2.find(id);
      const Point2 q =
          it != G.p2.end() ? it->second : Point2(pts[id].cartesian(u), pts[id].cartesian(w));
      CDT::Vertex_handle h = cdt.insert(q);
      h->info() = id;
      vh.push_back(h);
    }
    for (size_t i = 0; i < vh.size(); ++i) {
      const int a = Lp[i], b = Lp[(i + 1) % Lp.size()];
      edge_loop[(uint64_t(uint32_t(a)) << 32) | uint32_t(b)] = l;
      cdt.insert_constraint(vh[i], vh[(i + 1) % vh.size()]);
    }
  }
  mark_domains(cdt);
  int ndom = 0;
  std::vector<std::vector<int>> dom_tris, dom_loops;
  for (auto f0 = cdt.finite_faces_begin(); f0 != cdt.finite_faces_end(); ++f0) {
    if (f0->info().nesting % 2 != 1 || f0->info().domain >= 0) continue;
    const int dom = ndom++;
    std::vector<int> dtris;
    std::vector<int> dloops;
    std::deque<CDT::Face_handle> queue{f0};
    f0->info().domain = dom;
    while (!queue.empty()) {
      CDT::Face_handle fh = queue.front();
      queue.pop_front();
      for (int t = 0; t < 3; ++t) dtris.push_back(fh->vertex(t)->info());
      for (int i = 0; i < 3; ++i) {
        if (cdt.is_constrained(CDT::Edge(fh, i))) {
          const int a = fh->vertex(CDT::ccw(i))->info(), b = fh->vertex(CDT::cw(i))->info();
          auto it = edge_loop.find((uint64_t(uint32_t(a)) << 32) | uint32_t(b));
          if (it == edge_loop.end())
            throw std::logic_error("Bsp::extract: constraint not on a loop");
          dloops.push_back(it->second);
          continue;
        }
        CDT::Face_handle n = fh->neighbor(i);
        if (cdt.is_infinite(n) || n->info().domain >= 0) continue;
        n->info().domain = dom;
        queue.push_back(n);
      }
    }
    std::sort(dloops.begin(), dloops.end());
    dloops.erase(std::unique(dloops.begin(), dloops.end()), dloops.end());
    if (flip)
      for (size_t i = 0; i < dtris.size(); i += 3) std::swap(dtris[i + 1], dtris[i + 2]);
    dom_tris.push_back(std::move(dtris));
    dom_loops.push_back(std::move(dloops));
  }
  // a loop touching itself at a vertex may bound several domains, or one
  // domain through a pinch (a weakly simple polygon that triangulators of
  // OBJ readers get wrong): then those domains are output as triangles, not
  // as the loop
  std::vector<int> loop_doms(G.loops.size(), 0);
  for (const auto& dl : dom_loops)
    for (int l : dl) ++loop_doms[l];
  auto simple = [](std::vector<int> ids) {
    std::sort(ids.begin(), ids.end());
    return std::adjacent_find(ids.begin(), ids.end()) == ids.end();
  };
  for (int d = 0; d < ndom; ++d) {
    const auto& dtris = dom_tris[d];
    if (dom_loops[d].size() == 1 && loop_doms[dom_loops[d][0]] == 1 &&
        simple(G.loops[dom_loops[d][0]])) {
      std::vector<int> face = G.loops[dom_loops[d][0]];
      if (flip) std::reverse(face.begin(), face.end());
      G.faces.push_back(std::move(face));
    } else {
      for (size_t i = 0; i < dtris.size(); i += 3)
        G.faces.push_back({dtris[i], dtris[i + 1], dtris[i + 2]});
    }
    G.tris.insert(G.tris.end(), dtris.begin(), dtris.end());
  }
  G.regions = ndom;
}

/// The key of a plane side's triangulation: plane, side and its loops as the
/// identities of their points (empty when a point has none). Equal keys are
/// the same exact points in the same order, so the same triangulation.
std::vector<uint64_t> group_key(const Extracted& X, const Group& G) {
  std::vector<uint64_t> key{uint64_t(uint32_t(G.plane)), uint64_t(G.side > 0),
                            uint64_t(G.loops.size())};
  for (const auto& L : G.loops) {
    key.push_back(L.size());
    for (int id : L) {
      if (X.ident[size_t(id)] == kNoIdentity) return {};
      key.push_back(X.ident[size_t(id)]);
    }
  }
  return key;
}

/// The group's loop ids flattened (position -> id).
std::vector<int> flat_ids(const Group& G) {
  std::vector<int> flat;
  for (const auto& L : G.loops) flat.insert(flat.end(), L.begin(), L.end());
  return flat;
}

/// A triangulation of G in positions of its flattened loops.
bspx::GroupTriangles to_positions(const Group& G) {
  const std::vector<int> flat = flat_ids(G);
  std::unordered_map<int, int> pos;
  for (int j = 0; j < int(flat.size()); ++j) pos.emplace(flat[size_t(j)], j);
  bspx::GroupTriangles T;
  T.regions = G.regions;
  T.tris.reserve(G.tris.size());
  for (int id : G.tris) T.tris.push_back(pos.at(id));
  for (const auto& f : G.faces) {
    std::vector<int>& q = T.faces.emplace_back();
    for (int id : f) q.push_back(pos.at(id));
  }
  return T;
}

/// G's triangulation from one of the same key (positions -> G's ids).
void from_positions(const bspx::GroupTriangles& T, Group& G) {
  const std::vector<int> flat = flat_ids(G);
  G.regions = T.regions;
  G.tris.clear();
  G.tris.reserve(T.tris.size());
  for (int j : T.tris) G.tris.push_back(flat[size_t(j)]);
  G.faces.clear();
  for (const auto& q : T.faces) {
    std::vector<int>& f = G.faces.emplace_back();
    for (int j : q) f.push_back(flat[size_t(j)]);
  }
}

// One extraction pass: the boundary of the union of the cells `in_nodes`.
Extracted extract_once(const BspData& I, const std::vector<int>& in_nodes, ExtractCache* cache) {
  Extracted X;
  PassCoords pc(I, cache);
  std::map<int, std::vector<F2>> byplane = gather_faces(I, in_nodes, pc);
  const int threads = cache ? std::max(1, cache->threads) : 1;
  plane_regions(I, byplane, cache, pc, threads, X);
  insert_tjunctions(X, cache);
  // the plane sides are triangulated independently; a side triangulated in
  // an earlier extraction (same key) is taken from the cache
  const long ng = long(X.groups.size());
  std::vector<std::vector<uint64_t>> keys(X.groups.size());
  std::vector<const bspx::GroupTriangles*> known(X.groups.size(), nullptr);
  if (cache)
    for (size_t g = 0; g < X.groups.size(); ++g) {
      keys[g] = group_key(X, X.groups[g]);
      if (keys[g].empty()) continue;
      const auto it = cache->impl->groups.find(keys[g]);
      if (it != cache->impl->groups.end()) known[g] = &it->second;
    }
  std::vector<std::exception_ptr> errors(X.groups.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (ng > 1 && threads > 1)
  for (long g = 0; g < ng; ++g) {
    try {
      if (known[size_t(g)])
        from_positions(*known[size_t(g)], X.groups[size_t(g)]);
      else
        triangulate_group(I, X.pts, X.groups[size_t(g)]);
    } catch (...) {
      errors[size_t(g)] = std::current_exception();
    }
  }
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  if (cache)
    for (size_t g = 0; g < X.groups.size(); ++g)
      if (!known[g] && !keys[g].empty())
        cache->impl->groups.emplace(std::move(keys[g]), to_positions(X.groups[g]));
  return X;
}

// Undirected edges used by more than two triangles.
std::vector<std::pair<int, int>> nonmanifold_edges(const Extracted& X) {
  std::vector<std::pair<int, int>> edges;
  size_t nt = 0;
  for (const auto& G : X.groups) nt += G.tris.size();
  edges.reserve(nt);
  for (const auto& G : X.groups)
    for (size_t i = 0; i + 2 < G.tris.size(); i += 3)
      for (int e = 0; e < 3; ++e) {
        int a = G.tris[i + e], b = G.tris[i + (e + 1) % 3];
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

// Vertices whose triangles form more than one fan through edges at the vertex
// (two in-cones touching at a point).
std::vector<int> pinched_vertices(const Extracted& X) {
  std::vector<std::array<int, 3>> tris;
  for (const auto& G : X.groups)
    for (size_t i = 0; i + 2 < G.tris.size(); i += 3)
      tris.push_back({G.tris[i], G.tris[i + 1], G.tris[i + 2]});
  std::vector<std::vector<int>> around(X.pts.size());
  for (size_t t = 0; t < tris.size(); ++t)
    for (int v : tris[t]) around[size_t(v)].push_back(int(t));
  std::vector<int> bad;
  std::vector<int> parent;
  std::unordered_map<int, int> by_other;
  for (size_t v = 0; v < around.size(); ++v) {
    const auto& ts = around[v];
    if (ts.size() < 2) continue;
    parent.resize(ts.size());
    for (size_t i = 0; i < ts.size(); ++i) parent[i] = int(i);
    auto find = [&](int x) {
      while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
      return x;
    };
    by_other.clear();
    for (size_t i = 0; i < ts.size(); ++i)
      for (int w : tris[size_t(ts[i])]) {
        if (w == int(v)) continue;
        const auto [it, fresh] = by_other.emplace(w, int(i));
        if (!fresh) parent[size_t(find(int(i)))] = find(it->second);
      }
    int fans = 0;
    for (size_t i = 0; i < ts.size(); ++i) fans += find(int(i)) == int(i);
    if (fans > 1) bad.push_back(int(v));
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

using Boxes = std::vector<std::pair<Vec3, Vec3>>;

/// Bounding boxes (double) of the cells of `partition`.
Boxes cell_boxes(const BspData& D, const std::vector<int>& partition) {
  const auto& cells = D.cells;
  const auto& verts = D.verts;
  Boxes bbox(partition.size());
  for (size_t i = 0; i < partition.size(); ++i) {
    Vec3 lo3 = Vec3::Constant(1e300), hi3 = Vec3::Constant(-1e300);
    for (int v : D.cell_vertex_ids(cells[partition[i]]))
      lo3 = lo3.cwiseMin(verts[v].approx), hi3 = hi3.cwiseMax(verts[v].approx);
    bbox[i] = {lo3, hi3};
  }
  return bbox;
}

/// True when box b lies more than tol outside [lo, hi] along some axis.
bool box_apart(const std::pair<Vec3, Vec3>& b, const Vec3& lo, const Vec3& hi, double tol) {
  return (b.first.array() > hi.array() + tol).any() || (b.second.array() < lo.array() - tol).any();
}

/// The out-cells turned in to remove the non-manifold edges `bad` (sorted,
/// unique): per edge, the smallest out-cell whose closure holds its midpoint.
std::vector<int> edge_flips(const BspData& D, const std::vector<int>& partition,
                            const std::vector<char>& inside, const Extracted& X,
                            const std::vector<std::pair<int, int>>& bad, const Boxes& bbox) {
  const auto& cells = D.cells;
  const auto& nodes = D.nodes;
  std::vector<int> flip;
  for (const auto& [a, b] : bad) {
    // out-cells around the edge: those whose closure contains its midpoint
    // (an out-wedge may be cut into several cells along the edge; flipping
    // one shortens the non-manifold part, the next round handles the rest)
    const Point3 &pa = X.pts[a], &pb = X.pts[b];
    const Point3 mid = CGAL::midpoint(pa, pb);
    const Vec3 qa(CGAL::to_double(pa.x()), CGAL::to_double(pa.y()), CGAL::to_double(pa.z()));
    const Vec3 qb(CGAL::to_double(pb.x()), CGAL::to_double(pb.y()), CGAL::to_double(pb.z()));
    const Vec3 elo = qa.cwiseMin(qb), ehi = qa.cwiseMax(qb);
    const double tol =
        1e-6 * (1.0 + std::max(elo.cwiseAbs().maxCoeff(), ehi.cwiseAbs().maxCoeff()));
    int best = -1;
    for (size_t i = 0; i < partition.size(); ++i) {
      if (inside[i]) continue;
      if (box_apart(bbox[i], elo, ehi, tol)) continue;
      const Cell& c = cells[partition[i]];
      if (!cell_contains(D, c, mid)) continue;
      if (best < 0 || nodes[partition[i]].volume < nodes[partition[best]].volume) best = int(i);
    }
    if (best >= 0) flip.push_back(best);
  }
  std::sort(flip.begin(), flip.end());
  flip.erase(std::unique(flip.begin(), flip.end()), flip.end());
  return flip;
}

/// (ours) A pinched vertex (two in-cones meeting at a point) is removed by
/// the smallest change: the smallest cell whose closure holds the vertex, in
/// or out, changes sides (joining the cones or cutting one back). Out-cells to
/// turn in are appended to `flip` after its first `n_edge_flips` entries (the
/// edge repair's), in-cells to turn out go to `flip_out`; both sorted, unique.
void pinch_flips(const BspData& D, const std::vector<int>& partition,
                 const std::vector<char>& inside, const std::vector<char>& locked,
                 const Extracted& X, const std::vector<int>& pinched, const Boxes& bbox,
                 size_t n_edge_flips, std::vector<int>& flip, std::vector<int>& flip_out) {
  const auto& cells = D.cells;
  const auto& nodes = D.nodes;
  for (int v : pinched) {
    const Point3& p = X.pts[size_t(v)];
    const Vec3 q(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
    const double tol = 1e-6 * (1.0 + q.cwiseAbs().maxCoeff());
    int best = -1;
    for (size_t i = 0; i < partition.size(); ++i) {
      if (locked[i]) continue;
      if (box_apart(bbox[i], q, q, tol)) continue;
      if (!cell_contains(D, cells[partition[i]], p)) continue;
      if (best < 0 || nodes[partition[i]].volume < nodes[partition[best]].volume) best = int(i);
    }
    if (best >= 0 && !std::binary_search(flip.begin(), flip.begin() + long(n_edge_flips), best))
      (inside[size_t(best)] ? flip_out : flip).push_back(best);
  }
  std::sort(flip.begin() + long(n_edge_flips), flip.end());
  flip.erase(std::unique(flip.begin() + long(n_edge_flips), flip.end()), flip.end());
  std::sort(flip_out.begin(), flip_out.end());
  flip_out.erase(std::unique(flip_out.begin(), flip_out.end()), flip_out.end());
}

/// The extracted surface converted to double once: polygons and triangles.
void convert(const Extracted& X, BspSurface& S) {
  S.polygons.vertices.resize(X.pts.size());
  for (size_t i = 0; i < X.pts.size(); ++i)
    S.polygons.vertices[i] =
        Vec3(CGAL::to_double(X.pts[i].x()) + 0.0, CGAL::to_double(X.pts[i].y()) + 0.0,
             CGAL::to_double(X.pts[i].z()) + 0.0);
  S.triangles.vertices = S.polygons.vertices;
  for (const Group& G : X.groups) {
    S.merged_regions += G.regions;
    for (size_t i = 0; i + 2 < G.tris.size(); i += 3)
      S.triangles.triangles.push_back({G.tris[i], G.tris[i + 1], G.tris[i + 2]});
    for (const auto& f : G.faces) S.polygons.faces.push_back(f);
  }
}

}  // namespace

BspSurface bspi::extract_surface(const BspData& D, const std::vector<int>& partition,
                                 std::vector<char> inside, ExtractCache* cache) {
  const auto& cells = D.cells;
  if (inside.size() != partition.size())
    throw std::invalid_argument("Bsp::extract: labels / partition size mismatch");
  for (int n : partition)
    if (n < 0 || n >= int(cells.size())) throw std::out_of_range("Bsp::extract: node id");
  BspSurface S;
  Extracted X;
  Boxes bbox;  // lazily filled
  const int max_rounds = 64;
  std::vector<char> locked(partition.size(),
                           0);  // flipped by the pinch repair once: not chosen again
  S.edge_repaired.assign(partition.size(), 0);
  for (int round = 0;; ++round) {
    X = extract_once(D, collapse_inside(D, partition, inside), cache);
    const auto bad = nonmanifold_edges(X);
    // Pinched vertices are repaired in the first half of the rounds only, so
    // the last rounds always end the edge repair (which never fails).
    const auto pinched =
        bad.empty() && round < max_rounds / 2 ? pinched_vertices(X) : std::vector<int>{};
    if ((bad.empty() && pinched.empty()) || round >= max_rounds) break;
    if (bbox.empty()) bbox = cell_boxes(D, partition);
    std::vector<int> flip = edge_flips(D, partition, inside, X, bad, bbox);
    const size_t n_edge_flips = flip.size();
    std::vector<int> flip_out;
    pinch_flips(D, partition, inside, locked, X, pinched, bbox, n_edge_flips, flip, flip_out);
    if (flip.empty() && flip_out.empty()) break;
    for (size_t k = 0; k < flip.size(); ++k) {
      inside[size_t(flip[k])] = 1;
      if (k >= n_edge_flips) locked[size_t(flip[k])] = 1;
    }
    for (size_t k = 0; k < n_edge_flips; ++k) S.edge_repaired[size_t(flip[k])] = 1;
    for (int i : flip_out) inside[i] = 0, locked[size_t(i)] = 1;
    S.labels_flipped += int(flip.size() + flip_out.size());
  }

  S.inside = inside;
  convert(X, S);
  return S;
}

BspSurface Bsp::extract(const std::vector<int>& partition, std::vector<char> inside,
                        ExtractCache* cache) const {
  return extract_surface(*impl_, partition, std::move(inside), cache);
}

}  // namespace citylod::lod::detail
