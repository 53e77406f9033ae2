// Hausdorff distances between LOD models (branch and bound over the triangles
// of one mesh, an AABB tree of the other's) and the choice of the models a building keeps in the
// tileset.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "citylod/tiler/assemble.hpp"

#include "citylod/io/error.hpp"
#include "citylod/lod/box_tree.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

namespace {

using io::Vec3d;

inline Vec3d sub(const Vec3d& a, const Vec3d& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
inline double dot(const Vec3d& a, const Vec3d& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline Vec3d axpy(const Vec3d& p, double s, const Vec3d& d) {
  return {p[0] + s * d[0], p[1] + s * d[1], p[2] + s * d[2]};
}
inline double norm2(const Vec3d& a) {
  return dot(a, a);
}

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5).
Vec3d closest_on_triangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3d bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return axpy(a, d1 / (d1 - d3), ab);
  const Vec3d cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return axpy(a, d2 / (d2 - d6), ac);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return axpy(b, (d4 - d3) / ((d4 - d3) + (d5 - d6)), sub(c, b));
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return axpy(axpy(a, v, ab), w, ac);
}

/// A mesh's triangles in a lod::BoxTree, for the distance from a point to the mesh.
class TriangleTree {
 public:
  explicit TriangleTree(const io::TriangleMesh& m) : mesh_(m), tree_(boxes(m)) {}

  /// Squared distance from p to the mesh; `hint`: a triangle likely to be near (the
  /// answer does not depend on it).
  double distance2(const Vec3d& p, std::uint32_t hint = lod::BoxTree::kNoHint) const {
    std::uint32_t tri;
    return nearest(p, tri, hint);
  }

  /// Squared distance from p to the mesh and the nearest triangle (the lowest
  /// index among equally near ones).
  double nearest(const Vec3d& p, std::uint32_t& tri,
                 std::uint32_t hint = lod::BoxTree::kNoHint) const {
    tri = 0;
    return tree_.nearest2(
        p, [&](std::uint32_t i) { return norm2(sub(p, closest(p, i))); }, &tri, hint);
  }

  /// Distance from p to triangle `tri` of the mesh.
  double distance_to(const Vec3d& p, std::uint32_t tri) const {
    return std::sqrt(norm2(sub(p, closest(p, tri))));
  }

 private:
  Vec3d closest(const Vec3d& p, std::uint32_t i) const {
    const auto& t = mesh_.triangles[i];
    return closest_on_triangle(p, mesh_.vertices[t[0]], mesh_.vertices[t[1]], mesh_.vertices[t[2]]);
  }

  static lod::BoxTree boxes(const io::TriangleMesh& m) {
    std::vector<lod::BoxTree::Box> lo(m.triangles.size()), hi(m.triangles.size());
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      const auto& t = m.triangles[i];
      for (std::size_t k = 0; k < 3; ++k) {
        lo[i][k] = std::min({m.vertices[t[0]][k], m.vertices[t[1]][k], m.vertices[t[2]][k]});
        hi[i][k] = std::max({m.vertices[t[0]][k], m.vertices[t[1]][k], m.vertices[t[2]][k]});
      }
    }
    return lod::BoxTree(std::move(lo), std::move(hi));
  }

  const io::TriangleMesh& mesh_;
  lod::BoxTree tree_;
};

/// A model prepared for Hausdorff distances, once however many it is compared with: its
/// triangles' tree, its vertices by position and its triangles by their vertices.
/// Consecutive models of a chain share most of their vertices and triangles (three in
/// four vertices, three in five triangles on the City3D scene), whose distance to the
/// other model is 0 without a query.
class MeshIndex {
 public:
  explicit MeshIndex(const io::TriangleMesh& m) : mesh_(m), tree_(m) {
    ids_.reserve(m.vertices.size());
    std::vector<char> used(m.vertices.size(), 0);
    for (const auto& t : m.triangles)  // a vertex no triangle uses is not on the surface
      for (const std::uint32_t i : t) {
        ids_.emplace(m.vertices[i], i);
        used[i] = 1;
      }
    for (std::uint32_t i = 0; i < used.size(); ++i)
      if (used[i]) used_.push_back(i);
    tris_.reserve(m.triangles.size());
    for (const auto& t : m.triangles) tris_.insert(key(t[0], t[1], t[2]));
    group_faces();
  }
  const io::TriangleMesh& mesh() const { return mesh_; }
  const TriangleTree& tree() const { return tree_; }
  /// The vertices its triangles use, in index order.
  const std::vector<std::uint32_t>& used() const { return used_; }
  /// Is p one of the model's vertices?
  bool has_vertex(const Vec3d& p) const { return ids_.count(p) > 0; }
  /// Distance from p to the planar face triangle `tri` lies in, when that face is
  /// convex (then the distance is a convex function: its largest value over a triangle
  /// is at a corner); else to the triangle alone. Never less than the distance to the
  /// model.
  double distance_to_face(const Vec3d& p, std::uint32_t tri) const {
    const std::uint32_t g = group_[tri];
    if (!convex_[g]) return tree_.distance_to(p, tri);
    double d = std::numeric_limits<double>::infinity();
    for (std::uint32_t k = first_[g]; k < first_[g + 1]; ++k)
      d = std::min(d, tree_.distance_to(p, members_[k]));
    return d;
  }
  /// Is triangle pqr (any order) one of the model's triangles?
  bool has_triangle(const Vec3d& p, const Vec3d& q, const Vec3d& r) const {
    const auto a = ids_.find(p), b = ids_.find(q), c = ids_.find(r);
    if (a == ids_.end() || b == ids_.end() || c == ids_.end()) return false;
    return tris_.count(key(a->second, b->second, c->second)) > 0;
  }

 private:
  struct PointHash {
    std::size_t operator()(const Vec3d& p) const {
      std::uint64_t h = 0xcbf29ce484222325ULL;
      for (double v : p) {
        std::uint64_t bits;
        std::memcpy(&bits, &v, sizeof bits);
        h = (h ^ bits) * 0x100000001b3ULL;
        h ^= h >> 29;
      }
      return std::size_t(h);
    }
  };
  using Key = std::array<std::uint32_t, 3>;  ///< a triangle's vertex ids, sorted
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return std::size_t((std::uint64_t(k[0]) * 0x9E3779B97F4A7C15ULL) ^
                         (std::uint64_t(k[1]) * 0xC2B2AE3D27D4EB4FULL) ^
                         (std::uint64_t(k[2]) * 0x165667B19E3779F9ULL));
    }
  };
  static Key key(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    if (a > b) std::swap(a, b);
    if (b > c) std::swap(b, c);
    if (a > b) std::swap(a, b);
    return {a, b, c};
  }
  /// The model's planar faces: triangles joined across an edge (corners by position)
  /// when each lies in the other's plane (within kCoplanar); a face is convex when its
  /// area is its convex hull's.
  void group_faces() {
    constexpr double kCoplanar = 1e-9;  // metres
    const auto& m = mesh_;
    const std::size_t n = m.triangles.size();
    std::vector<Vec3d> normal(n);
    std::vector<double> area(n), offset(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& t = m.triangles[i];
      const Vec3d u = sub(m.vertices[t[1]], m.vertices[t[0]]);
      const Vec3d w = sub(m.vertices[t[2]], m.vertices[t[0]]);
      const Vec3d c{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                    u[0] * w[1] - u[1] * w[0]};
      const double len = std::sqrt(norm2(c));
      area[i] = len / 2;
      normal[i] = len > 0 ? Vec3d{c[0] / len, c[1] / len, c[2] / len} : Vec3d{0, 0, 0};
      offset[i] = dot(normal[i], m.vertices[t[0]]);
    }
    const auto in_plane = [&](std::size_t i, std::size_t j) {  // j's corners in i's plane
      if (area[i] <= 0 || dot(normal[i], normal[j]) <= 0) return false;
      for (const std::uint32_t v : m.triangles[j])
        if (std::fabs(dot(normal[i], m.vertices[v]) - offset[i]) > kCoplanar) return false;
      return true;
    };
    std::vector<std::uint32_t> parent(n);
    std::iota(parent.begin(), parent.end(), 0u);
    const auto root = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    // each edge (its corners by position) of each triangle; a later triangle on an
    // edge is joined to the first
    std::vector<std::uint32_t> at(m.vertices.size(), 0);
    for (const auto& t : m.triangles)
      for (const std::uint32_t v : t) at[v] = ids_.at(m.vertices[v]);
    std::vector<std::array<std::uint32_t, 3>> edges;  // corner, corner, triangle
    edges.reserve(3 * n);
    for (std::uint32_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        std::uint32_t a = at[m.triangles[i][k]], b = at[m.triangles[i][(k + 1) % 3]];
        if (a > b) std::swap(a, b);
        edges.push_back({a, b, i});
      }
    std::sort(edges.begin(), edges.end());
    for (std::size_t e = 0, f = 0; e < edges.size(); e = f) {
      for (f = e + 1; f < edges.size() && edges[f][0] == edges[e][0] && edges[f][1] == edges[e][1];
           ++f) {
        const std::uint32_t i = edges[f][2], j = edges[e][2];
        if (in_plane(i, j) && in_plane(j, i)) parent[root(i)] = root(j);
      }
    }
    // faces in order of their first triangle; members by face
    group_.assign(n, 0);
    std::vector<std::uint32_t> id(n, ~0u);
    std::uint32_t groups = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint32_t r = root(i);
      if (id[r] == ~0u) id[r] = groups++;
      group_[i] = id[r];
    }
    first_.assign(groups + 1, 0);
    for (std::uint32_t i = 0; i < n; ++i) ++first_[group_[i] + 1];
    for (std::uint32_t g = 0; g < groups; ++g) first_[g + 1] += first_[g];
    members_.resize(n);
    std::vector<std::uint32_t> fill(first_.begin(), first_.end() - 1);
    for (std::uint32_t i = 0; i < n; ++i) members_[fill[group_[i]]++] = i;
    convex_.assign(groups, 0);
    for (std::uint32_t g = 0; g < groups; ++g) {
      if (first_[g + 1] - first_[g] < 2) continue;  // one triangle: the triangle's own bound
      const Vec3d& nr = normal[members_[first_[g]]];
      // the plane's coordinates: drop the normal's largest axis
      const int drop = std::fabs(nr[0]) >= std::fabs(nr[1]) && std::fabs(nr[0]) >= std::fabs(nr[2])
                           ? 0
                           : (std::fabs(nr[1]) >= std::fabs(nr[2]) ? 1 : 2);
      const int ax = drop == 0 ? 1 : 0, ay = drop == 2 ? 1 : 2;
      std::vector<std::array<double, 2>> pts;
      double sum = 0;
      for (std::uint32_t k = first_[g]; k < first_[g + 1]; ++k) {
        sum += area[members_[k]];
        for (const std::uint32_t v : m.triangles[members_[k]])
          pts.push_back({m.vertices[v][std::size_t(ax)], m.vertices[v][std::size_t(ay)]});
      }
      const double hull = hull_area(std::move(pts)) / std::fabs(nr[std::size_t(drop)]);
      convex_[g] = std::fabs(hull - sum) <= 1e-9 * std::max(1.0, sum);
    }
  }
  /// Area of the convex hull of points in a plane (monotone chain).
  static double hull_area(std::vector<std::array<double, 2>> p) {
    std::sort(p.begin(), p.end());
    p.erase(std::unique(p.begin(), p.end()), p.end());
    if (p.size() < 3) return 0;
    const auto cross = [](const std::array<double, 2>& o, const std::array<double, 2>& a,
                          const std::array<double, 2>& b) {
      return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    };
    std::vector<std::array<double, 2>> h(2 * p.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
      h[k++] = p[i];
    }
    for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
      while (k >= t && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
      h[k++] = p[i];
    }
    h.resize(k - 1);
    double a = 0;
    for (std::size_t i = 0; i < h.size(); ++i) {
      const auto& u = h[i];
      const auto& v = h[(i + 1) % h.size()];
      a += u[0] * v[1] - u[1] * v[0];
    }
    return std::fabs(a) / 2;
  }

  const io::TriangleMesh& mesh_;
  TriangleTree tree_;
  std::vector<std::uint32_t> group_, first_, members_;  // planar faces: by triangle, members
  std::vector<char> convex_;
  std::unordered_map<Vec3d, std::uint32_t, PointHash> ids_;
  std::unordered_set<Key, KeyHash> tris_;
  std::vector<std::uint32_t> used_;
};

/// Raises `best` to the largest distance from a corner of A's triangles to B (a corner
/// of B's own: 0); stops once best >= stop_above.
void vertex_distance(const MeshIndex& a, const MeshIndex& b, double stop_above, double& best) {
  if (best >= stop_above) return;  // also a negative stop_above
  double best2 = best * best;
  const double stop2 = stop_above * stop_above;
  std::uint32_t near = lod::BoxTree::kNoHint;  // consecutive vertices are mostly near
  for (const std::uint32_t i : a.used()) {
    if (best2 >= stop2) break;
    if (const Vec3d& v = a.mesh().vertices[i]; !b.has_vertex(v))
      best2 = std::max(best2, b.tree().nearest(v, near, near));
  }
  best = std::max(best, std::sqrt(best2));
}

/// Raises `best` to the directed Hausdorff distance h(A -> B) = max over the
/// surface of A of the distance to B, to within `tol`, by branch and bound on
/// A's triangles. Upper bounds of the distance to B on a triangle with
/// centroid g: d(g) + R (the distance is 1-Lipschitz; R = centroid to farthest
/// vertex), and max_i d_T(v_i) for T the triangle of B nearest to g (the
/// distance to one triangle is convex, so its maximum is at a vertex, and
/// d_B <= d_T). Triangles that cannot beat `best` by more than `tol` are
/// dropped, the others split in four. `best` starts at what is already known (the other
/// direction, the vertices), so the large surfaces two LOD models share are
/// dropped at once. Stops once best >= stop_above.
void directed(const io::TriangleMesh& a, const MeshIndex& b, double tol, double stop_above,
              double& best) {
  struct Tri {
    Vec3d a, b, c;
  };
  const TriangleTree& tb = b.tree();
  std::vector<Tri> stack;
  for (const auto& t : a.triangles) {
    const Tri tri{a.vertices[t[0]], a.vertices[t[1]], a.vertices[t[2]]};
    if (!b.has_triangle(tri.a, tri.b, tri.c)) stack.push_back(tri);  // B's own: 0
  }
  std::size_t budget = 2000000;  // distance queries; bounds the worst case (coincident surfaces)
  std::uint32_t last = lod::BoxTree::kNoHint;  // the previous query's nearest triangle
  while (!stack.empty() && budget > 0 && best < stop_above) {
    const Tri t = stack.back();
    stack.pop_back();
    const Vec3d g{(t.a[0] + t.b[0] + t.c[0]) / 3, (t.a[1] + t.b[1] + t.c[1]) / 3,
                  (t.a[2] + t.b[2] + t.c[2]) / 3};
    const double r =
        std::sqrt(std::max({norm2(sub(t.a, g)), norm2(sub(t.b, g)), norm2(sub(t.c, g))}));
    if (r <= tol * 0.5) continue;  // within tol of its (evaluated) vertices
    std::uint32_t near;
    const double dg = std::sqrt(tb.nearest(g, near, last));
    last = near;
    --budget;
    best = std::max(best, dg);
    if (dg + r <= best + tol) continue;
    if (std::max({b.distance_to_face(t.a, near), b.distance_to_face(t.b, near),
                  b.distance_to_face(t.c, near)}) <= best + tol)
      continue;
    const Vec3d ab{(t.a[0] + t.b[0]) / 2, (t.a[1] + t.b[1]) / 2, (t.a[2] + t.b[2]) / 2};
    const Vec3d bc{(t.b[0] + t.c[0]) / 2, (t.b[1] + t.c[1]) / 2, (t.b[2] + t.c[2]) / 2};
    const Vec3d ca{(t.c[0] + t.a[0]) / 2, (t.c[1] + t.a[1]) / 2, (t.c[2] + t.a[2]) / 2};
    for (const Vec3d& m : {ab, bc, ca}) best = std::max(best, std::sqrt(tb.distance2(m, near)));
    budget -= std::min<std::size_t>(budget, 3);
    stack.push_back({t.a, ab, ca});
    stack.push_back({ab, t.b, bc});
    stack.push_back({ca, bc, t.c});
    stack.push_back({ab, bc, ca});
  }
}

double hausdorff(const MeshIndex& a, const MeshIndex& b, double tolerance, double stop_above) {
  const io::TriangleMesh &ma = a.mesh(), &mb = b.mesh();
  if (ma.triangles.empty() || mb.triangles.empty()) return std::numeric_limits<double>::infinity();
  if (!(tolerance > 0)) throw std::invalid_argument("hausdorff_distance: tolerance must be > 0");
  if (&ma == &mb || (ma.vertices == mb.vertices && ma.triangles == mb.triangles))
    return 0.0;  // the same model (common)
  double best = 0;
  vertex_distance(a, b, stop_above, best);
  vertex_distance(b, a, stop_above, best);
  directed(ma, b, tolerance, stop_above, best);
  directed(mb, a, tolerance, stop_above, best);
  return best;
}

}  // namespace

double hausdorff_distance(const io::TriangleMesh& a, const io::TriangleMesh& b, double tolerance,
                          double stop_above) {
  if (a.triangles.empty() || b.triangles.empty()) return std::numeric_limits<double>::infinity();
  return hausdorff(MeshIndex(a), MeshIndex(b), tolerance, stop_above);
}

ModelChoice choose_models(const LodReport& report, const std::vector<io::TriangleMesh>& meshes,
                          double min_change_m, double tolerance_m) {
  const std::vector<ModelRecord>& entries = report.models;
  if (entries.size() != meshes.size())
    throw std::invalid_argument("choose_models: models and meshes differ in size");
  auto anchor = [&](std::size_t m) { return is_anchor(entries[m].kind); };
  ModelChoice out;
  if (entries.empty()) return out;
  std::vector<std::size_t> order(entries.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t x, std::size_t y) { return entries[x].step < entries[y].step; });
  // The finest model: the last anchor (the last model if none is an anchor);
  // models without triangles never count.
  std::ptrdiff_t finest_pos = -1;
  for (std::size_t i = 0; i < order.size(); ++i)
    if (!meshes[order[i]].triangles.empty() &&
        (anchor(order[i]) || finest_pos < 0 || !anchor(order[size_t(finest_pos)])))
      finest_pos = std::ptrdiff_t(i);
  if (finest_pos < 0) return out;
  order.resize(size_t(finest_pos) + 1);
  const std::size_t finest = order.back();

  // Each candidate prepared once for the distances below.
  std::vector<std::unique_ptr<MeshIndex>> index(entries.size());
  for (std::size_t m : order)
    if (!meshes[m].triangles.empty()) index[m] = std::make_unique<MeshIndex>(meshes[m]);
  const auto distance = [&](std::size_t x, std::size_t y, double stop_above) {
    return hausdorff(*index[x], *index[y], tolerance_m, stop_above);
  };
  constexpr double kAll = std::numeric_limits<double>::infinity();

  // Distance to the finest model, measured in full for every kept model (-1: not yet).
  std::vector<double> to_finest(entries.size(), -1.0);
  to_finest[finest] = 0;
  const auto keep = [&](std::vector<std::size_t>& kept, std::size_t m) {
    if (to_finest[m] < 0) to_finest[m] = distance(m, finest, kAll);
    kept.push_back(m);
  };
  auto next_anchor_after = [&](std::size_t i) {
    for (std::size_t j = i + 1; j < order.size(); ++j)
      if (anchor(order[j]) && !meshes[order[j]].triangles.empty()) return order[j];
    return finest;
  };
  constexpr double kSame = 1e-3;  // metres: the same surface

  // Walk coarse -> fine.
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::size_t m = order[i];
    if (meshes[m].triangles.empty()) continue;
    if (m == finest) {
      kept.push_back(m);
      continue;
    }
    const std::size_t next_anchor = next_anchor_after(i);
    if (anchor(m)) {
      // Every anchor, unless it is the very same model as the next one.
      if (distance(m, next_anchor, kSame) >= kSame) keep(kept, m);
      continue;
    }
    // An interpolation changes the look when it differs from the previous kept
    // model and from the next anchor, and brings the building closer to its
    // finest model (a lower error: otherwise a client refines both at once).
    if (!kept.empty()) {
      const std::size_t prev = kept.back();
      // No closer to the finest than prev by min_change: the search stops once that is
      // certain. The distance it has found only grows along the search, so a search
      // that does not stop is the full one: the model's distance.
      const double bound = to_finest[prev] - min_change_m;
      const double d = distance(m, finest, std::nextafter(bound, kAll));
      if (d > bound) continue;
      to_finest[m] = d;
      if (distance(m, prev, min_change_m) < min_change_m) continue;
    }
    if (distance(m, next_anchor, min_change_m) < min_change_m) continue;
    keep(kept, m);
  }
  // Monotone in RMSE: never worse than a coarser kept model by more than the
  // tolerance (the finest stays; models without an RMSE are not judged).
  {
    const double finest_rmse = report.rmse_m(finest);
    std::vector<std::size_t> mono;
    double best = std::numeric_limits<double>::infinity();
    for (const std::size_t m : kept) {
      const double r = report.rmse_m(m);
      if (m != finest && r >= 0 && finest_rmse >= 0 && r < finest_rmse - kChainMonotoneTolerance_m)
        continue;  // the finest would be worse than it
      if (m != finest && r >= 0 && r > best + kChainMonotoneTolerance_m) continue;
      if (r >= 0) best = std::min(best, r);
      mono.push_back(m);
    }
    kept = std::move(mono);
  }
  out.kept = kept;
  out.hausdorff_m.resize(kept.size());
  out.error_m.resize(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) out.hausdorff_m[i] = to_finest[kept[i]];
  // Strictly decreasing, 0 only for the finest: a coarser model whose distance
  // happens to be smaller than a finer one's is charged the finer error + 1 cm.
  double next = 0;
  for (std::size_t i = kept.size(); i-- > 0;) {
    out.error_m[i] = (i + 1 == kept.size()) ? 0.0 : std::max(out.hausdorff_m[i], next + 0.01);
    next = out.error_m[i];
  }
  return out;
}

}  // namespace citylod::tiler
