// The models' metrics: check_mesh (exact edge incidence + self-intersections),
// mesh_volume, and evaluate_model(): the metrics of the paper's quantitative
// evaluation for any model against a reference surface (used by `citylod eval`).
#include "citylod/lod/lod.hpp"
#include "fidelity.hpp"

#include <Eigen/Geometry>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace citylod::lod {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;

std::uint64_t key(int a, int b) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

bool degenerate_tri(const TriangleMesh& m, const std::array<int, 3>& t) {
  if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return true;
  const P3 a(m.vertices[t[0]].x(), m.vertices[t[0]].y(), m.vertices[t[0]].z());
  const P3 b(m.vertices[t[1]].x(), m.vertices[t[1]].y(), m.vertices[t[1]].z());
  const P3 c(m.vertices[t[2]].x(), m.vertices[t[2]].y(), m.vertices[t[2]].z());
  return CGAL::collinear(a, b, c);
}

/// Do triangles h and g meet other than along what they share? As CGAL's
/// do_faces_intersect (PMP::self_intersections) decides it for two faces of a
/// polygon mesh (vertices by index): a shared edge -- the four corners coplanar
/// and the corners opposite it on one side of it; one shared vertex -- either
/// opposite edge meets the other triangle; none -- the triangles meet. The same
/// triangle the other way round (three shared corners) meets. `soup`: also two
/// coplanar triangles overlapping around a shared vertex (in a soup, not a mesh).
bool faces_intersect(const std::vector<P3>& pts, const std::array<int, 3>& h,
                     const std::array<int, 3>& g, bool soup) {
  int shared = 0, hs[3] = {0, 0, 0}, gs[3] = {0, 0, 0};  // the shared corners' positions
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (h[size_t(i)] == g[size_t(j)]) {
        hs[shared] = i;
        gs[shared] = j;
        ++shared;
      }
  const auto at = [&](const std::array<int, 3>& t, int i) -> const P3& {
    return pts[size_t(t[size_t(i % 3)])];
  };
  if (shared == 3) return true;
  if (shared == 2) {  // a shared edge pq; r, s: the corners opposite it
    const P3 &p = at(h, hs[0]), &q = at(h, hs[1]), &r = at(h, 3 - hs[0] - hs[1]),
             &s = at(g, 3 - gs[0] - gs[1]);
    return CGAL::coplanar(p, q, r, s) && CGAL::coplanar_orientation(p, q, r, s) == CGAL::POSITIVE;
  }
  const K::Triangle_3 th(at(h, 0), at(h, 1), at(h, 2)), tg(at(g, 0), at(g, 1), at(g, 2));
  if (shared == 0) return CGAL::do_intersect(th, tg);
  const int a = hs[0], b = gs[0];  // the shared vertex v
  if (CGAL::do_intersect(th, K::Segment_3(at(g, b + 1), at(g, b + 2))) ||
      CGAL::do_intersect(tg, K::Segment_3(at(h, a + 1), at(h, a + 2))))
    return true;
  if (!soup || !CGAL::coplanar(at(h, 0), at(h, 1), at(h, 2), at(g, b + 1)) ||
      !CGAL::coplanar(at(h, 0), at(h, 1), at(h, 2), at(g, b + 2)))
    return false;
  // Coplanar around v: a point slightly inside one near v, tested in the other.
  const P3& v = at(h, a);
  const K::Vector_3 d = ((at(g, b + 1) - v) + (at(g, b + 2) - v)) * 1e-6;
  if (th.has_on(v + d)) return true;
  const K::Vector_3 d1 = ((at(h, a + 1) - v) + (at(h, a + 2) - v)) * 1e-6;
  return tg.has_on(v + d1);
}

/// Does any pair of triangles meet (faces_intersect)? Every pair whose closed
/// bounding boxes meet is tested; the predicates are exact, so the answer does
/// not depend on which other pairs are also tested. A sweep along the longest axis
/// for a model's few thousand triangles; above kSweepMax, where boxes that all span
/// that axis (long walls) would make the sweep quadratic, CGAL's box intersection.
bool self_intersects(const std::vector<P3>& pts, const std::vector<std::array<int, 3>>& tris,
                     bool soup) {
  constexpr std::size_t kSweepMax = 4096;
  const std::size_t n = tris.size();
  std::vector<CGAL::Bbox_3> box(n);
  CGAL::Bbox_3 all;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& t = tris[i];
    box[i] = pts[size_t(t[0])].bbox() + pts[size_t(t[1])].bbox() + pts[size_t(t[2])].bbox();
    all += box[i];
  }
  const auto meet = [&](std::size_t a, std::size_t b) {
    return faces_intersect(pts, tris[a], tris[b], soup);
  };
  if (n > kSweepMax) {
    using Box = CGAL::Box_intersection_d::Box_with_handle_d<double, 3, std::size_t,
                                                            CGAL::Box_intersection_d::ID_EXPLICIT>;
    std::vector<Box> boxes;
    boxes.reserve(n);
    for (std::size_t i = 0; i < n; ++i) boxes.emplace_back(box[i], i);
    struct Stop {};
    try {
      CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
        if (meet(a.handle(), b.handle())) throw Stop();
      });
    } catch (const Stop&) {
      return true;
    }
    return false;
  }
  int ax = 0;
  for (int k = 1; k < 3; ++k)
    if (all.max(k) - all.min(k) > all.max(ax) - all.min(ax)) ax = k;
  std::vector<std::uint32_t> order(n);
  for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return box[a].min(ax) < box[b].min(ax) || (box[a].min(ax) == box[b].min(ax) && a < b);
  });
  for (std::size_t a = 0; a < n; ++a) {
    const CGAL::Bbox_3& ba = box[order[a]];
    for (std::size_t b = a + 1; b < n && box[order[b]].min(ax) <= ba.max(ax); ++b) {
      const CGAL::Bbox_3& bb = box[order[b]];
      bool overlap = true;
      for (int k = 0; k < 3 && overlap; ++k)
        overlap = bb.min(k) <= ba.max(k) && ba.min(k) <= bb.max(k);
      if (overlap && meet(order[a], order[b])) return true;
    }
  }
  return false;
}

/// Union-find over ints.
struct Dsu {
  std::vector<int> p;
  explicit Dsu(std::size_t n) : p(n) {
    for (std::size_t i = 0; i < n; ++i) p[i] = int(i);
  }
  int find(int x) {
    while (p[size_t(x)] != x) x = p[size_t(x)] = p[size_t(p[size_t(x)])];
    return x;
  }
  void unite(int a, int b) { p[size_t(find(a))] = find(b); }
};

/// Pinched vertices and shells by exact incidence: triangles are joined
/// through shared (undirected) edges; a vertex is pinched when its incident
/// triangles fall into more than one such group around it (the fans are
/// joined only through edges incident to the vertex).
void count_fans_and_shells(const TriangleMesh& mesh, MeshCheck& r) {
  const std::size_t nt = mesh.triangles.size();
  Dsu shells(nt);
  std::unordered_map<std::uint64_t, int> first_of_edge;  // undirected edge -> a triangle
  first_of_edge.reserve(nt * 2);
  // Per vertex: its incident triangles (around[first[v]..first[v + 1])), to group
  // them by shared edges at it.
  std::vector<int> first(mesh.vertices.size() + 1, 0), around(3 * nt);
  for (const auto& tri : mesh.triangles)
    for (const int v : tri) ++first[size_t(v) + 1];
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) first[v + 1] += first[v];
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (std::size_t t = 0; t < nt; ++t) {
    const auto& tri = mesh.triangles[t];
    for (int i = 0; i < 3; ++i) {
      around[size_t(fill[size_t(tri[i])]++)] = int(t);
      const int a = std::min(tri[i], tri[(i + 1) % 3]), b = std::max(tri[i], tri[(i + 1) % 3]);
      const auto [it, fresh] = first_of_edge.emplace(key(a, b), int(t));
      if (!fresh) shells.unite(int(t), it->second);
    }
  }
  std::vector<double> volume(nt, 0.0);  // per shell root
  std::vector<char> root_seen(nt, 0);
  const Vec3 o = mesh.vertices.empty() ? Vec3::Zero() : mesh.vertices[0];
  for (std::size_t t = 0; t < nt; ++t) {
    const auto& tri = mesh.triangles[t];
    const int root = shells.find(int(t));
    root_seen[size_t(root)] = 1;
    const Vec3 a = mesh.vertices[size_t(tri[0])] - o, b = mesh.vertices[size_t(tri[1])] - o,
               c = mesh.vertices[size_t(tri[2])] - o;
    volume[size_t(root)] += a.dot(b.cross(c));
  }
  for (std::size_t t = 0; t < nt; ++t)
    if (root_seen[t]) (volume[t] > 0 ? r.shells : r.cavities)++;
  // Around vertex v, triangles sharing an edge (v, w) are in one fan: the (w, triangle)
  // pairs sorted by w, equal neighbours joined.
  std::vector<std::pair<int, int>> by_other;  // other endpoint w -> local triangle index
  std::vector<int> parent;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const int* ts = around.data() + first[v];
    const std::size_t n = std::size_t(first[v + 1] - first[v]);
    if (n < 2) continue;
    by_other.clear();
    parent.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      parent[i] = int(i);
      for (const int w : mesh.triangles[size_t(ts[i])])
        if (w != int(v)) by_other.emplace_back(w, int(i));
    }
    auto find = [&](int x) {
      while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
      return x;
    };
    std::sort(by_other.begin(), by_other.end());
    for (std::size_t k = 1; k < by_other.size(); ++k)
      if (by_other[k].first == by_other[k - 1].first)
        parent[size_t(find(by_other[k].second))] = find(by_other[k - 1].second);
    int fans = 0;
    for (std::size_t i = 0; i < n; ++i) fans += find(int(i)) == int(i) ? 1 : 0;
    if (fans > 1) ++r.pinched_vertices;
  }
}

}  // namespace

MeshCheck check_mesh(const TriangleMesh& mesh, bool test_self_intersections) {
  MeshCheck r;
  // Undirected edge -> (count, directed balance per direction).
  struct E {
    int count = 0;
    int ab = 0;
    int ba = 0;
  };
  std::unordered_map<std::uint64_t, E> edges;
  edges.reserve(mesh.triangles.size() * 2);
  const int nv = static_cast<int>(mesh.vertices.size());
  bool bad_index = false;
  for (const auto& t : mesh.triangles) {
    for (int i = 0; i < 3; ++i) {
      int a = t[i], b = t[(i + 1) % 3];
      if (a < 0 || b < 0 || a >= nv || b >= nv || a == b) {
        bad_index = true;
        continue;
      }
      const bool fwd = a < b;
      E& e = edges[fwd ? key(a, b) : key(b, a)];
      ++e.count;
      (fwd ? e.ab : e.ba)++;
    }
  }
  bool oriented = !bad_index;
  for (const auto& kv : edges) {
    const E& e = kv.second;
    if (e.count == 1) ++r.boundary_edges;
    if (e.count > 2) ++r.nonmanifold_edges;
    if (!(e.ab == 1 && e.ba == 1)) oriented = false;
  }
  r.closed =
      !bad_index && !mesh.triangles.empty() && r.boundary_edges == 0 && r.nonmanifold_edges == 0;
  if (!bad_index) count_fans_and_shells(mesh, r);
  r.edge_manifold = !bad_index && r.nonmanifold_edges == 0;
  r.oriented = oriented && !mesh.triangles.empty();
  if (!test_self_intersections) return r;

  std::vector<P3> pts;
  pts.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) pts.emplace_back(v.x(), v.y(), v.z());
  std::vector<std::array<int, 3>> tris;
  tris.reserve(mesh.triangles.size());
  bool degenerate = bad_index;
  for (const auto& t : mesh.triangles) {
    if (t[0] < 0 || t[1] < 0 || t[2] < 0 || t[0] >= nv || t[1] >= nv || t[2] >= nv) continue;
    if (degenerate_tri(mesh, t)) {
      degenerate = true;
      continue;
    }
    tris.push_back(t);
  }
  // Degenerate triangles count as a defect of the surface ("self-intersecting").
  if (degenerate) {
    r.self_intersecting = true;
    return r;
  }

  // A valid polygon mesh (closed, oriented -- each edge once each way --, no
  // degenerate triangle, no pinched vertex: what PMP::is_polygon_soup_a_polygon_mesh
  // checks) is tested as PMP::does_self_intersect tests it; else as a soup.
  r.self_intersecting =
      self_intersects(pts, tris, !(r.edge_manifold && r.oriented && r.pinched_vertices == 0));
  return r;
}

double mesh_volume(const TriangleMesh& mesh) {
  double v = 0.0;
  const int nv = static_cast<int>(mesh.vertices.size());
  if (nv == 0) return 0.0;
  const Vec3 o =
      mesh.vertices[0];  // relative coordinates: exact for closed meshes, better conditioned
  for (const auto& t : mesh.triangles) {
    if (t[0] < 0 || t[1] < 0 || t[2] < 0 || t[0] >= nv || t[1] >= nv || t[2] >= nv) continue;
    const Vec3 a = mesh.vertices[t[0]] - o;
    const Vec3 b = mesh.vertices[t[1]] - o;
    const Vec3 c = mesh.vertices[t[2]] - o;
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

ModelEvaluation evaluate_model(const TriangleMesh& model, const BuildingInput& reference,
                               int samples) {
  if (reference.points.empty()) throw LodError("eval", "empty reference");
  ModelEvaluation ev;
  ev.check = check_mesh(model);
  ev.triangles = model.triangles.size();
  ev.volume = mesh_volume(model);
  detail::Samples s;
  if (reference.is_mesh()) {
    s = detail::make_samples(reference, NormalParams{});  // area-weighted samples of the faces
  } else {
    s.points = reference.points;  // distances need no normals
    s.weights.assign(s.points.size(), 1.0);
  }
  Vec3 lo = reference.points.front(), hi = lo;
  for (const auto& p : reference.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  ev.diagonal = (hi - lo).norm();
  const detail::Fidelity f =
      detail::FidelityMeter(reference, s, std::max(1e-9, ev.diagonal), std::max(1, samples))
          .measure(model);
  ev.e1 = f.e1;
  ev.e2 = f.e2;
  ev.hausdorff = f.hausdorff;
  return ev;
}

}  // namespace citylod::lod
