// Exact adaptive BSP (Appendix B): construction and node geometry. The cells'
// adjacency lives in bsp_adjacency.cpp, the extraction of surfaces in
// bsp_extract.cpp. See bsp_impl.hpp for the representation.
#include "bsp_impl.hpp"

#include <CGAL/Exact_integer.h>
#include <CGAL/intersections.h>
#include <gmpxx.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace citylod::lod::detail {

using namespace bspi;

namespace {

constexpr double kPlaneMergeTol = 1e-12;

bool normalize_plane(std::array<double, 4>& c) {
  const double n = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  if (!(n > 1e-300) || !std::isfinite(n) || !std::isfinite(c[3])) return false;
  for (double& x : c) x /= n;
  return true;
}

Vec3 newell_normal(const std::vector<Vec3>& p) {
  Vec3 n = Vec3::Zero();
  for (size_t i = 0; i < p.size(); ++i) {
    const Vec3& a = p[i];
    const Vec3& b = p[(i + 1) % p.size()];
    n.x() += (a.y() - b.y()) * (a.z() + b.z());
    n.y() += (a.z() - b.z()) * (a.x() + b.x());
    n.z() += (a.x() - b.x()) * (a.y() + b.y());
  }
  return n;
}

}  // namespace

// ---------------------------------------------------------------------------
// Plane table and vertices

namespace {

/// The point of three planes by Cramer's rule, in kernel K: a lazy Epeck
/// construction of its own (CGAL::intersection of three planes goes through a
/// line and gives up its interval approximation on most axis-parallel planes,
/// then constructs exactly). Throws when the planes do not meet in one point.
template <class K>
struct PlanesPoint {
  using result_type = typename K::Point_3;
  result_type operator()(const typename K::Plane_3& a, const typename K::Plane_3& b,
                         const typename K::Plane_3& c) const {
    const auto p = CGAL::Intersections::internal::intersection_point(a, b, c, K());
    if (!p) throw std::logic_error("Bsp: edge does not cross the cutting plane in one point");
    return *p;
  }
};
using ConstructPlanesPoint =
    CGAL::Lazy_construction<K, PlanesPoint<K::Approximate_kernel>, PlanesPoint<K::Exact_kernel>>;

}  // namespace

int BspData::find_or_add_plane(const std::array<double, 4>& c, int* flip) {
  for (size_t j = 0; j < dplanes.size(); ++j) {
    const auto& q = dplanes[j];
    double dp = 0, dm = 0;
    for (int k = 0; k < 4; ++k) {
      dp = std::max(dp, std::abs(q[k] - c[k]));
      dm = std::max(dm, std::abs(q[k] + c[k]));
    }
    if (dp <= kPlaneMergeTol) {
      *flip = 1;
      return int(j);
    }
    if (dm <= kPlaneMergeTol) {
      *flip = -1;
      return int(j);
    }
  }
  dplanes.push_back(c);
  planes.emplace_back(FT(c[0]), FT(c[1]), FT(c[2]), FT(c[3]));
  *flip = 1;
  return int(dplanes.size()) - 1;
}

int BspData::add_vertex(const Point3& p, const std::array<int, 3>& def,
                        std::vector<int> on_planes) {
  Vertex v;
  v.p = p;
  v.def = def;
  v.approx = Vec3(CGAL::to_double(p.x()) + 0.0, CGAL::to_double(p.y()) + 0.0,
                  CGAL::to_double(p.z()) + 0.0);  // no -0
  std::sort(on_planes.begin(), on_planes.end());
  on_planes.erase(std::unique(on_planes.begin(), on_planes.end()), on_planes.end());
  v.planes = std::move(on_planes);
  verts.push_back(std::move(v));
  return int(verts.size()) - 1;
}

int BspData::sign(int vi, int P) {
  Vertex& v = verts[vi];
  for (int q : v.planes)
    if (q == P) return 0;
  for (const auto& qs : v.signs)
    if (qs.first == P) return qs.second;
  // the interval approximations first; when they do not decide, the exact
  // sign from integer determinants (CGAL's filtered predicate would construct
  // the lazy point and plane exactly, each once)
  CGAL::Uncertain<CGAL::Sign> u;
  {
    CGAL::Protect_FPU_rounding<true> guard;
    const auto& q = CGAL::approx(v.p);
    const auto& h = CGAL::approx(planes[P]);
    u = CGAL::sign(h.a() * q.x() + h.b() * q.y() + h.c() * q.z() + h.d());
  }
  const int s = CGAL::is_certain(u) ? int(CGAL::get_certain(u)) : exact_sign_of(v.def, P);
  if (s == 0)
    v.planes.push_back(P);
  else
    v.signs.emplace_back(P, static_cast<signed char>(s));
  return s;
}

int BspData::cut(int a, int b, int S, int E, int P) {
  // Memoized by the edge (a,b) and P, so that the faces sharing an edge get the
  // same vertex, and by the plane triple, so that every cell (and polygon
  // piece) cutting the same line by the same plane shares it too. (The edge
  // memo is needed: an edge may lie on more than two planes, and its faces may
  // name different edge planes for it.)
  const CutKey ekey{std::min(a, b), std::max(a, b), P};
  auto ie = cut_memo.find(ekey);
  if (ie != cut_memo.end()) return ie->second;
  int t[3] = {S, E, P};
  std::sort(t, t + 3);
  const CutKey tkey{t[0], t[1], t[2]};
  auto add_common = [&](Vertex& x) {
    for (int q : verts[a].planes)
      if (std::find(verts[b].planes.begin(), verts[b].planes.end(), q) != verts[b].planes.end() &&
          std::find(x.planes.begin(), x.planes.end(), q) == x.planes.end())
        x.planes.push_back(q);
  };
  auto it = triple_memo.find(tkey);
  int id;
  if (it != triple_memo.end()) {
    id = it->second;
  } else {
    id = add_vertex(ConstructPlanesPoint()(planes[S], planes[E], planes[P]), {S, E, P}, {S, E, P});
    triple_memo.emplace(tkey, id);
  }
  add_common(verts[id]);
  cut_memo.emplace(ekey, id);
  return id;
}

namespace {

/// The power of two that makes the coefficients of c integers, or false when
/// they span too many binades to scale in double.
bool integer_shift(const std::array<double, 4>& c, int& shift) {
  int emin = INT32_MAX, emax = INT32_MIN;
  for (double x : c) {
    if (x == 0) continue;
    int e;
    std::frexp(x, &e);
    emin = std::min(emin, e - 53);
    emax = std::max(emax, e);
  }
  shift = emin == INT32_MAX ? 0 : -emin;
  return emax == INT32_MIN || emax - emin <= 1000;
}

/// GMP scratch integers for the point of three table planes by Cramer's rule
/// on their coefficients scaled to integers (allocated once per thread).
struct DetScratch {
  mpz_t m[3][4], t, D, N[3], h[4], acc;
  DetScratch() {
    for (auto& r : m)
      for (auto& x : r) mpz_init2(x, 256);
    mpz_init2(t, 512);
    mpz_init2(D, 512);
    for (auto& x : N) mpz_init2(x, 512);
    for (auto& x : h) mpz_init2(x, 256);
    mpz_init2(acc, 1024);
  }
  ~DetScratch() {
    for (auto& r : m)
      for (auto& x : r) mpz_clear(x);
    mpz_clear(t);
    mpz_clear(D);
    for (auto& x : N) mpz_clear(x);
    for (auto& x : h) mpz_clear(x);
    mpz_clear(acc);
  }
  DetScratch(const DetScratch&) = delete;
  DetScratch& operator=(const DetScratch&) = delete;
  // out = det of columns (c0, c1, c2) of m
  void det3(mpz_t out, int c0, int c1, int c2) {
    mpz_set_ui(out, 0);
    const int r[3][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}};  // even permutations of the rows
    for (const auto& p : r) {
      mpz_mul(t, m[p[1]][c1], m[p[2]][c2]);
      mpz_submul(t, m[p[1]][c2], m[p[2]][c1]);
      mpz_addmul(out, m[p[0]][c0], t);
    }
  }
  /// The point of the planes `def` (A x = -d) as x_k = -N_k / D; false when
  /// the coefficients cannot be scaled to integers in double (then nothing is
  /// set). Throws when the planes are not independent (D = 0).
  bool solve(const std::vector<std::array<double, 4>>& dplanes, const std::array<int, 3>& def) {
    int shift[3];
    for (int r = 0; r < 3; ++r)
      if (!integer_shift(dplanes[def[r]], shift[r])) return false;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) mpz_set_d(m[r][c], std::ldexp(dplanes[def[r]][c], shift[r]));
    det3(D, 0, 1, 2);
    if (mpz_sgn(D) == 0) throw std::logic_error("Bsp: vertex planes are not independent");
    det3(N[0], 3, 1, 2);  // det(A with column k replaced by d)
    det3(N[1], 0, 3, 2);
    det3(N[2], 0, 1, 3);
    return true;
  }
};

}  // namespace

int BspData::exact_sign_of(const std::array<int, 3>& def, int P) const {
  thread_local DetScratch S;
  int shift;
  if (!integer_shift(dplanes[P], shift) || !S.solve(dplanes, def)) {  // exactly with CGAL
    ET x[3];
    exact_coords_of(def, x);
    return int(planes[P].oriented_side(Point3(EK::Point_3(x[0], x[1], x[2]))));
  }
  // sign(h . (x, 1)) with x_k = -N_k / D: sign(D) * sign(D h3 - sum_k h_k N_k)
  for (int c = 0; c < 4; ++c) mpz_set_d(S.h[c], std::ldexp(dplanes[P][c], shift));
  mpz_mul(S.acc, S.h[3], S.D);
  for (int k = 0; k < 3; ++k) mpz_submul(S.acc, S.h[k], S.N[k]);
  return mpz_sgn(S.acc) * mpz_sgn(S.D);
}

void BspData::exact_coords_of(const std::array<int, 3>& def, ET out[3]) const {
  thread_local DetScratch S;
  if (!S.solve(dplanes, def)) {  // cannot scale in double: let CGAL do it
    const auto res = CGAL::intersection(planes[def[0]], planes[def[1]], planes[def[2]]);
    const Point3* pt = res ? boost::get<Point3>(&*res) : nullptr;
    if (!pt) throw std::logic_error("Bsp: vertex planes are not independent");
    for (int t = 0; t < 3; ++t) out[t] = CGAL::exact(pt->cartesian(t));
    return;
  }
  for (int k = 0; k < 3; ++k) {
    mpz_neg(S.N[k], S.N[k]);
    if constexpr (std::is_same_v<ET, mpq_class>) {
      mpq_class q;
      mpz_set(q.get_num_mpz_t(), S.N[k]);
      mpz_set(q.get_den_mpz_t(), S.D);
      q.canonicalize();
      out[k] = std::move(q);
    } else {
      out[k] = ET(CGAL::Exact_integer(mpz_class(S.N[k]))) / ET(CGAL::Exact_integer(mpz_class(S.D)));
    }
  }
}

// ---------------------------------------------------------------------------
// Polygon and cell splitting

void BspData::split_poly(const Poly& f, int P, Poly* neg, Poly* pos) {
  const int n = int(f.v.size());
  if (neg) neg->v.clear(), neg->e.clear(), neg->plane = f.plane;
  if (pos) pos->v.clear(), pos->e.clear(), pos->plane = f.plane;
  int sg_local[16];
  std::vector<int> sg_heap;
  int* sg = sg_local;
  if (n > 16) {
    sg_heap.resize(n);
    sg = sg_heap.data();
  }
  bool hasneg = false, haspos = false;
  for (int i = 0; i < n; ++i) {
    sg[i] = sign(f.v[i], P);
    hasneg |= sg[i] < 0;
    haspos |= sg[i] > 0;
  }
  if (!haspos) {
    if (hasneg && neg) *neg = f;
    return;
  }
  if (!hasneg) {
    if (pos) *pos = f;
    return;
  }
  for (int s : {-1, 1}) {
    Poly* out = s < 0 ? neg : pos;
    if (!out) continue;
    out->v.reserve(n + 2);
    out->e.reserve(n + 2);
    for (int i = 0; i < n; ++i) {
      const int j = (i + 1 == n) ? 0 : i + 1;
      const int ta = -s * sg[i], tb = -s * sg[j];
      if (ta <= 0) {
        out->v.push_back(f.v[i]);
        out->e.push_back((tb <= 0 || ta < 0) ? f.e[i] : P);
      }
      if ((ta < 0 && tb > 0) || (ta > 0 && tb < 0)) {
        out->v.push_back(cut(f.v[i], f.v[j], f.plane, f.e[i], P));
        out->e.push_back(ta < 0 ? P : f.e[i]);
      }
    }
  }
}

int BspData::classify_cell(const Cell& c, int P) {
  bool hasneg = false, haspos = false;
  for (const auto& f : c.faces)
    for (int v : f.poly.v) {
      const int s = sign(v, P);
      hasneg |= s < 0;
      haspos |= s > 0;
      if (hasneg && haspos) return 0;
    }
  if (hasneg) return -1;
  if (haspos) return 1;
  return 2;
}

void BspData::split_cell(const Cell& c, int P, Cell* neg, Cell* pos, Poly* cap) {
  // cap edges of the negative child: reversed on-P edges of its faces
  std::vector<std::array<int, 3>> capedges;  // from, to, edge plane
  Poly pn, pp;
  if (neg) neg->faces.clear();
  if (pos) pos->faces.clear();
  for (const auto& f : c.faces) {
    split_poly(f.poly, P, &pn, &pp);
    if (!pn.v.empty()) {
      const int n = int(pn.v.size());
      for (int i = 0; i < n; ++i) {
        const int u = pn.v[i], w = pn.v[(i + 1) % n];
        if (sign(u, P) == 0 && sign(w, P) == 0) capedges.push_back({w, u, f.poly.plane});
      }
      if (neg) neg->faces.push_back({pn, f.cell_pos});
    }
    if (!pp.v.empty() && pos) pos->faces.push_back({pp, f.cell_pos});
  }
  // chain
  std::map<int, std::pair<int, int>> next;
  for (const auto& e : capedges)
    if (!next.emplace(e[0], std::make_pair(e[1], e[2])).second)
      throw std::logic_error("Bsp: inconsistent cap (vertex used twice)");
  if (next.size() < 3) throw std::logic_error("Bsp: degenerate cap");
  Poly capn;
  capn.plane = P;
  const int start = next.begin()->first;
  int cur = start;
  do {
    auto it = next.find(cur);
    if (it == next.end()) throw std::logic_error("Bsp: open cap chain");
    capn.v.push_back(cur);
    capn.e.push_back(it->second.second);
    cur = it->second.first;
    if (capn.v.size() > next.size()) throw std::logic_error("Bsp: cap chain loops");
  } while (cur != start);
  if (capn.v.size() != next.size()) throw std::logic_error("Bsp: cap has several loops");
  if (pos) {
    Poly capp;
    capp.plane = P;
    const int n = int(capn.v.size());
    capp.v.reserve(n);
    capp.e.reserve(n);
    // reversed loop: v0, v_{n-1}, ..., v1; edge (v_i -> v_{i-1}) has plane e[i-1]
    for (int k = 0; k < n; ++k) {
      const int i = (n - k) % n;
      capp.v.push_back(capn.v[i]);
      capp.e.push_back(capn.e[(i + n - 1) % n]);
    }
    pos->faces.push_back({std::move(capp), true});
  }
  if (cap) *cap = capn;
  if (neg) neg->faces.push_back({std::move(capn), false});
}

std::vector<int> BspData::cell_vertex_ids(const Cell& c) const {
  std::vector<int> ids;
  for (const auto& f : c.faces)
    for (int v : f.poly.v) ids.push_back(v);
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

void BspData::fill_node_geometry(BspNode& n, const Cell& c) const {
  const auto ids = cell_vertex_ids(c);
  Vec3 ctr = Vec3::Zero();
  for (int v : ids) ctr += verts[v].approx;
  if (!ids.empty()) ctr /= double(ids.size());
  n.center = ctr;
  double vol = 0;
  for (const auto& f : c.faces) {
    const auto& L = f.poly.v;
    const Vec3 a = verts[L[0]].approx - ctr;
    for (size_t i = 1; i + 1 < L.size(); ++i) {
      const Vec3 b = verts[L[i]].approx - ctr;
      const Vec3 d = verts[L[i + 1]].approx - ctr;
      vol += a.dot(b.cross(d));
    }
  }
  n.volume = vol / 6.0;
}

// ---------------------------------------------------------------------------
// Construction

namespace {

/// The box planes and the root cell, the box.
void init_box(BspData& I, const Vec3& lo, const Vec3& hi) {
  // box planes: 2k -> coordinate k = lo[k], 2k+1 -> coordinate k = hi[k]; normal +e_k
  for (int k = 0; k < 3; ++k)
    for (int h = 0; h < 2; ++h) {
      std::array<double, 4> c{0, 0, 0, -(h ? hi[k] : lo[k])};
      c[k] = 1;
      I.dplanes.push_back(c);
      I.planes.emplace_back(FT(c[0]), FT(c[1]), FT(c[2]), FT(c[3]));
    }
  // root cell: corners i + 2j + 4l
  for (int l = 0; l < 2; ++l)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        const int id =
            I.add_vertex(Point3(i ? hi.x() : lo.x(), j ? hi.y() : lo.y(), l ? hi.z() : lo.z()),
                         {0 + i, 2 + j, 4 + l}, {0 + i, 2 + j, 4 + l});
        (void)id;
      }
  {
    Cell root;
    for (int k = 0; k < 3; ++k)
      for (int h = 0; h < 2; ++h) {
        const int pl = 2 * k + h;
        std::vector<int> loop;
        // the 4 corners with coordinate k == h, in cyclic order in the (k+1, k+2) axes
        const int u = (k + 1) % 3, w = (k + 2) % 3;
        const int uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (const auto& q : uv) {
          int bits[3];
          bits[k] = h;
          bits[u] = q[0];
          bits[w] = q[1];
          loop.push_back(bits[0] + 2 * bits[1] + 4 * bits[2]);
        }
        // this loop is CCW seen from +e_k; outward is +e_k iff h == 1
        if (h == 0) std::reverse(loop.begin(), loop.end());
        Poly p;
        p.plane = pl;
        p.v = loop;
        for (int e = 0; e < 4; ++e) {
          const auto& A = I.verts[loop[e]].planes;
          const auto& B = I.verts[loop[(e + 1) % 4]].planes;
          int ep = -1;
          for (int q : A)
            if (q != pl && std::find(B.begin(), B.end(), q) != B.end()) ep = q;
          p.e.push_back(ep);
        }
        root.faces.push_back({std::move(p), h == 0});
      }
    BspNode rn;
    I.fill_node_geometry(rn, root);
    I.nodes.push_back(rn);
    I.cells.push_back(std::move(root));
  }
}

/// An input polygon on its table support plane.
struct Prep {
  int support = -1;
  std::vector<Vec3> loop;  // projected, CCW around the table support normal
};

/// (ours) A support plane whose normal is within I.merge.angle of an earlier
/// polygon's support (either orientation), each polygon within
/// I.merge.distance of the other's plane, takes that support's coefficients: two such planes cross,
/// or run side by side, at a hair's breadth, and cut wedges and slabs thinner than a validator's
/// snap tolerance, slivers that fold when it welds their vertices.
void snap_to_near_support(const BspData& I, const std::vector<Prep>& prep, size_t i,
                          const std::vector<Vec3>& loop, std::array<double, 4>& c) {
  const double md = I.merge.distance;
  if (!(md > 0)) return;
  const double min_cos = std::cos(I.merge.angle);
  const auto off = [](const std::array<double, 4>& pl, const std::vector<Vec3>& pts) {
    double worst = 0;
    for (const Vec3& x : pts)
      worst = std::max(worst, std::abs(pl[0] * x.x() + pl[1] * x.y() + pl[2] * x.z() + pl[3]));
    return worst;
  };
  for (size_t j = 0; j < i; ++j) {
    const int S = prep[j].support;
    if (S < 6) continue;  // none, or a box cut
    const auto& q = I.dplanes[size_t(S)];
    const double cosine = c[0] * q[0] + c[1] * q[1] + c[2] * q[2];
    if (std::abs(cosine) < min_cos) continue;
    if (off(q, loop) > md || off(c, prep[j].loop) > md) continue;
    const double s = cosine >= 0 ? 1.0 : -1.0;
    for (int k = 0; k < 4; ++k) c[size_t(k)] = s * q[size_t(k)];
    return;
  }
}

/// The planes of the input polygons: their supports (the split planes) go into
/// the table first; each polygon projected on its plane, CCW around the table
/// support's normal (support -1: degenerate, skipped).
std::vector<Prep> prepare_polygons(BspData& I, const std::vector<BspPolygon>& ordered) {
  std::vector<Prep> prep(ordered.size());
  for (size_t i = 0; i < ordered.size(); ++i) {
    const BspPolygon& bp = ordered[i];
    if (bp.polygon.size() < 3) continue;
    std::array<double, 4> c = bp.plane;
    if (!normalize_plane(c)) continue;
    int flip = 1;
    Vec3 n(c[0], c[1], c[2]);
    // project onto the input plane, drop repeated points
    std::vector<Vec3> q;
    for (const Vec3& p : bp.polygon) {
      if (!p.allFinite()) continue;
      Vec3 pr = p - (n.dot(p) + c[3]) * n;
      if (q.empty() || (pr - q.back()).norm() > 1e-9) q.push_back(pr);
    }
    while (q.size() > 1 && (q.front() - q.back()).norm() <= 1e-9) q.pop_back();
    if (q.size() < 3) continue;
    const Vec3 nn = newell_normal(q);
    if (nn.norm() < 1e-12) continue;  // no area
    snap_to_near_support(I, prep, i, q, c);
    const int S = I.find_or_add_plane(c, &flip);
    const Vec3 ns = double(flip) * n;
    if (nn.dot(ns) < 0) std::reverse(q.begin(), q.end());
    prep[i].support = S;
    prep[i].loop = std::move(q);
  }
  I.n_split_planes = int(I.dplanes.size());
  return prep;
}

/// Each polygon as a piece of the root cell: its support plane's section of
/// the box clipped by the polygon's edge planes (added to the table).
std::vector<Piece> root_pieces_of(BspData& I, const std::vector<BspPolygon>& ordered,
                                  std::vector<Prep>& prep) {
  std::vector<Piece> root_pieces;
  for (size_t i = 0; i < ordered.size(); ++i) {
    Prep& pr = prep[i];
    if (pr.support < 0 || pr.support < 6) continue;  // degenerate, or on the box boundary
    const int S = pr.support;
    if (I.classify_cell(I.cells[0], S) != 0) continue;  // plane misses the open box
    Poly piece;
    I.split_cell(I.cells[0], S, nullptr, nullptr, &piece);
    const Vec3 ns(I.dplanes[S][0], I.dplanes[S][1], I.dplanes[S][2]);
    const auto& q = pr.loop;
    bool empty = false;
    for (size_t e = 0; e < q.size() && !empty; ++e) {
      const Vec3& a = q[e];
      const Vec3& b = q[(e + 1) % q.size()];
      Vec3 ne = (b - a).cross(ns);  // points out of the polygon
      const double len = ne.norm();
      if (!(len > 1e-12)) continue;
      ne /= len;
      std::array<double, 4> ce{ne.x(), ne.y(), ne.z(), -ne.dot(a)};
      int flip = 1;
      const int E = I.find_or_add_plane(ce, &flip);
      if (E == S) continue;
      Poly kept;
      if (flip > 0)
        I.split_poly(piece, E, &kept, nullptr);
      else
        I.split_poly(piece, E, nullptr, &kept);
      if (kept.v.empty()) empty = true;
      piece = std::move(kept);
    }
    if (empty || piece.v.size() < 3) continue;
    root_pieces.push_back({std::move(piece), ordered[i].primitive});
  }
  return root_pieces;
}

/// Adaptive BSP, depth first (negative child first): a node is split by the
/// first piece with positive area inside it; stops at `max_leaves` leaves.
void split_adaptive(BspData& I, std::vector<Piece> root_pieces, int max_leaves) {
  struct Work {
    int node;
    std::vector<Piece> pieces;
  };
  std::vector<Work> stack;
  stack.push_back({0, std::move(root_pieces)});
  int leaves = 1;
  while (!stack.empty()) {
    Work w = std::move(stack.back());
    stack.pop_back();
    for (size_t idx = 0; idx < w.pieces.size(); ++idx) {
      const int P = w.pieces[idx].poly.plane;
      if (I.classify_cell(I.cells[w.node], P) != 0) continue;  // piece on the cell boundary
      if (max_leaves > 0 && leaves >= max_leaves) {
        I.cap_hit = true;
        stack.clear();
        break;
      }
      Cell cn, cp;
      I.split_cell(I.cells[w.node], P, &cn, &cp, nullptr);
      Work wn, wp;
      Poly qn, qp;
      for (size_t j = idx + 1; j < w.pieces.size(); ++j) {
        Piece& q = w.pieces[j];
        if (q.poly.plane == P) continue;  // consumed with the splitting piece
        I.split_poly(q.poly, P, &qn, &qp);
        if (!qn.v.empty()) wn.pieces.push_back({qn, q.primitive});
        if (!qp.v.empty()) wp.pieces.push_back({qp, q.primitive});
      }
      const int parent = w.node;
      const int depth = I.nodes[parent].depth + 1;
      const int idn = int(I.nodes.size()), idp = idn + 1;
      BspNode nn, np;
      nn.parent = np.parent = parent;
      nn.depth = np.depth = depth;
      I.fill_node_geometry(nn, cn);
      I.fill_node_geometry(np, cp);
      I.nodes.push_back(nn);
      I.nodes.push_back(np);
      I.cells.push_back(std::move(cn));
      I.cells.push_back(std::move(cp));
      BspNode& pn = I.nodes[parent];
      pn.children = {idn, idp};
      pn.split_primitive = w.pieces[idx].primitive;
      pn.split_plane = P;
      ++leaves;
      wn.node = idn;
      wp.node = idp;
      stack.push_back(std::move(wp));
      stack.push_back(std::move(wn));
      break;
    }
  }
}

}  // namespace

Bsp::Bsp(const Vec3& lo, const Vec3& hi, const std::vector<BspPolygon>& ordered, int max_leaves,
         PlaneMerge merge)
    : impl_(std::make_unique<Impl>()) {
  Impl& I = *impl_;
  I.lo = lo;
  I.hi = hi;
  I.merge = merge;
  if (!(hi.x() > lo.x() && hi.y() > lo.y() && hi.z() > lo.z()))
    throw std::invalid_argument("Bsp: empty box");
  init_box(I, lo, hi);
  std::vector<Prep> prep = prepare_polygons(I, ordered);
  split_adaptive(I, root_pieces_of(I, ordered, prep), max_leaves);
  I.cut_memo.clear();
  I.cut_memo.rehash(0);
  I.triple_memo.clear();
  I.triple_memo.rehash(0);
}

Bsp::~Bsp() = default;
Bsp::Bsp(Bsp&&) noexcept = default;
Bsp& Bsp::operator=(Bsp&&) noexcept = default;

bool Bsp::cap_hit() const {
  return impl_->cap_hit;
}
const std::vector<BspNode>& Bsp::nodes() const {
  return impl_->nodes;
}

std::vector<int> Bsp::leaves() const {
  std::vector<int> out;
  for (size_t i = 0; i < impl_->nodes.size(); ++i)
    if (impl_->nodes[i].is_leaf()) out.push_back(int(i));
  return out;
}

std::vector<std::array<double, 4>> Bsp::planes() const {
  return std::vector<std::array<double, 4>>(impl_->dplanes.begin(),
                                            impl_->dplanes.begin() + impl_->n_split_planes);
}

std::vector<Vec3> Bsp::cell_vertices(int node) const {
  if (node < 0 || node >= int(impl_->cells.size())) throw std::out_of_range("Bsp::cell_vertices");
  std::vector<Vec3> out;
  for (int v : impl_->cell_vertex_ids(impl_->cells[node])) out.push_back(impl_->verts[v].approx);
  return out;
}

}  // namespace citylod::lod::detail
