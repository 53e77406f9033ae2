// check_solid: a solid as val3dity 2.6 reads and validates it (validity.hpp).
// Steps as the validator takes them: vertices snapped on reading (each new
// vertex becomes the first earlier one within the snap tolerance), then per
// face the ring checks, the planarity by distance to the least-squares plane,
// the simplicity of the ring projected on that plane and the planarity by the
// normals of its constrained Delaunay triangulation; then per shell the
// triangulated surface: closed, 2-manifold, one piece, outward, no
// self-intersection (check_mesh).
#include "citylod/lod/validity.hpp"

#include "citylod/lod/lod.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/linear_least_squares_fitting_3.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <list>
#include <map>
#include <string>
#include <unordered_map>

namespace citylod::lod {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;
using P2 = K::Point_2;

struct FaceInfo {
  int nesting = -1;
  bool in_domain() const { return nesting % 2 == 1; }
};
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<FaceInfo, K>;
using Fb = CGAL::Constrained_triangulation_face_base_2<K, Fbi>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;

/// Faces inside the constraints: nesting level by flood fill from the
/// infinite face, crossing a constraint adds one (CGAL's polygon example).
void mark_domains(Cdt& ct) {
  for (auto f = ct.all_faces_begin(); f != ct.all_faces_end(); ++f) f->info().nesting = -1;
  std::list<Cdt::Edge> border;
  auto fill = [&](Cdt::Face_handle start, int index) {
    std::list<Cdt::Face_handle> queue{start};
    while (!queue.empty()) {
      Cdt::Face_handle fh = queue.front();
      queue.pop_front();
      if (fh->info().nesting != -1) continue;
      fh->info().nesting = index;
      for (int i = 0; i < 3; ++i) {
        const Cdt::Edge e(fh, i);
        Cdt::Face_handle n = fh->neighbor(i);
        if (n->info().nesting == -1) {
          if (ct.is_constrained(e))
            border.push_back(e);
          else
            queue.push_back(n);
        }
      }
    }
  };
  fill(ct.infinite_face(), 0);
  while (!border.empty()) {
    const Cdt::Edge e = border.front();
    border.pop_front();
    Cdt::Face_handle n = e.first->neighbor(e.second);
    if (n->info().nesting == -1) fill(n, e.first->info().nesting + 1);
  }
}

/// val3dity's reading of one shell: a vertex within `snap` of an earlier one
/// (in order of first use) is that one.
struct Snapped {
  std::vector<Vec3> points;
  std::vector<std::vector<int>> rings;
};

Snapped snap_shell(const std::vector<Vec3>& vertices, const std::vector<std::vector<int>>& faces,
                   double snap) {
  Snapped s;
  const double cell = snap > 0 ? snap : 1.0;
  std::unordered_map<std::uint64_t, std::vector<int>> grid;
  auto key = [](long long x, long long y, long long z) {
    return (std::uint64_t(x) * 73856093u) ^ (std::uint64_t(y) * 19349663u) ^
           (std::uint64_t(z) * 83492791u);
  };
  std::map<int, int> seen;  // input vertex -> snapped point (a vertex reused is found again)
  for (const auto& f : faces) {
    std::vector<int> ring;
    for (const int vi : f) {
      const auto it = seen.find(vi);
      if (it != seen.end()) {
        ring.push_back(it->second);
        continue;
      }
      const Vec3& p = vertices[std::size_t(vi)];
      const long long cx = std::llround(std::floor(p.x() / cell)),
                      cy = std::llround(std::floor(p.y() / cell)),
                      cz = std::llround(std::floor(p.z() / cell));
      int best = -1;
      for (long long dx = -1; dx <= 1; ++dx)
        for (long long dy = -1; dy <= 1; ++dy)
          for (long long dz = -1; dz <= 1; ++dz) {
            const auto g = grid.find(key(cx + dx, cy + dy, cz + dz));
            if (g == grid.end()) continue;
            for (const int q : g->second)
              if ((s.points[std::size_t(q)] - p).squaredNorm() <= snap * snap &&
                  (best < 0 || q < best))
                best = q;
          }
      if (best < 0) {
        best = int(s.points.size());
        s.points.push_back(p);
        grid[key(cx, cy, cz)].push_back(best);
      }
      seen.emplace(vi, best);
      ring.push_back(best);
    }
    s.rings.push_back(std::move(ring));
  }
  return s;
}

P3 toP(const Vec3& v) {
  return P3(v.x(), v.y(), v.z());
}

Vec3 unit_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 n = (b - a).cross(c - a);
  const double l = n.norm();
  return l > 0 ? Vec3(n / l) : n;
}

/// The 2D checks of one ring; on success `tris` holds its constrained
/// triangulation (indices into s.points), oriented as the ring.
SolidCheck check_face(const Snapped& s, std::size_t fi, const Tolerances& tol,
                      std::vector<std::array<int, 3>>& tris) {
  SolidCheck r;
  r.face = int(fi);
  const std::vector<int>& ring = s.rings[fi];
  if (ring.size() < 3) {
    r.error = 101;
    r.detail = "ring of " + std::to_string(ring.size()) + " distinct points";
    return r;
  }
  for (std::size_t i = 0; i < ring.size(); ++i)
    if (ring[i] == ring[(i + 1) % ring.size()]) {
      r.error = 102;
      r.detail = "two consecutive points closer than the snap tolerance";
      return r;
    }
  if (ring.size() == 3) {
    if (CGAL::collinear(toP(s.points[std::size_t(ring[0])]), toP(s.points[std::size_t(ring[1])]),
                        toP(s.points[std::size_t(ring[2])]))) {
      r.error = 104;
      r.detail = "triangle collapsed to a line";
      return r;
    }
    tris.push_back({ring[0], ring[1], ring[2]});
    return r;
  }
  std::vector<P3> pts;
  for (const int i : ring) pts.push_back(toP(s.points[std::size_t(i)]));
  K::Plane_3 plane;
  CGAL::linear_least_squares_fitting_3(pts.begin(), pts.end(), plane, CGAL::Dimension_tag<0>());
  for (const P3& p : pts) {
    const double d2 = CGAL::to_double(CGAL::squared_distance(p, plane));
    if (d2 > tol.planarity_d2p * tol.planarity_d2p) {
      r.error = 203;
      r.detail = "distance to the fitted plane " + std::to_string(std::sqrt(d2)) + " m";
      return r;
    }
  }
  CGAL::Polygon_2<K> pgn;
  for (const P3& p : pts) pgn.push_back(plane.to_2d(p));
  if (!pgn.is_simple()) {
    r.error = 104;
    r.detail = "ring self-intersects on its plane";
    return r;
  }
  const bool reversed = !pgn.is_counterclockwise_oriented();
  Cdt ct;
  Cdt::Vertex_handle first, prev;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Cdt::Vertex_handle v = ct.insert(pgn[int(i)]);
    v->info() = ring[i];
    if (i == 0)
      first = v;
    else
      ct.insert_constraint(prev, v);
    prev = v;
  }
  ct.insert_constraint(prev, first);
  mark_domains(ct);
  std::vector<std::array<int, 3>> face_tris;
  for (auto f = ct.finite_faces_begin(); f != ct.finite_faces_end(); ++f)
    if (f->info().in_domain()) {
      std::array<int, 3> t{f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
      if (reversed) std::swap(t[0], t[1]);
      face_tris.push_back(t);
    }
  if (face_tris.empty()) {
    r.error = 104;
    r.detail = "ring encloses no area";
    return r;
  }
  const Vec3 n0 =
      unit_normal(s.points[std::size_t(face_tris[0][0])], s.points[std::size_t(face_tris[0][1])],
                  s.points[std::size_t(face_tris[0][2])]);
  for (const auto& t : face_tris) {
    const Vec3 n1 = unit_normal(s.points[std::size_t(t[0])], s.points[std::size_t(t[1])],
                                s.points[std::size_t(t[2])]);
    const double angle = std::atan2(n0.cross(n1).norm(), n0.dot(n1)) * 180.0 / M_PI;
    if (angle > tol.planarity_normals_deg) {
      r.error = 204;
      r.detail = "triangle normals " + std::to_string(angle) + " degrees apart";
      return r;
    }
  }
  tris.insert(tris.end(), face_tris.begin(), face_tris.end());
  return r;
}

}  // namespace

SolidCheck check_solid(const PolygonSolid& solid, const Tolerances& tol) {
  SolidCheck r;
  if (solid.shells.empty()) {
    r.error = 301;
    r.detail = "no shell";
    return r;
  }
  for (std::size_t si = 0; si < solid.shells.size(); ++si) {
    const auto& faces = solid.shells[si];
    for (const auto& f : faces)
      for (const int v : f)
        if (v < 0 || std::size_t(v) >= solid.vertices.size()) {
          r.error = 101;
          r.shell = int(si);
          r.detail = "vertex index out of range";
          return r;
        }
    if (faces.size() < 4) {
      r.error = 301;
      r.shell = int(si);
      r.detail = std::to_string(faces.size()) + " faces";
      return r;
    }
    const Snapped s = snap_shell(solid.vertices, faces, tol.snap);
    TriangleMesh mesh;
    mesh.vertices = s.points;
    for (std::size_t fi = 0; fi < s.rings.size(); ++fi) {
      SolidCheck f = check_face(s, fi, tol, mesh.triangles);
      if (!f.valid()) {
        f.shell = int(si);
        return f;
      }
    }
    const MeshCheck m = check_mesh(mesh);
    r.shell = int(si);
    if (m.nonmanifold_edges > 0) {
      r.error = 304;
      r.detail = std::to_string(m.nonmanifold_edges) + " non-manifold edges";
    } else if (m.boundary_edges > 0) {
      r.error = 302;
      r.detail = std::to_string(m.boundary_edges) + " boundary edges";
    } else if (m.pinched_vertices > 0) {
      r.error = 303;
      r.detail = std::to_string(m.pinched_vertices) + " non-manifold vertices";
    } else if (m.shells + m.cavities != 1) {
      r.error = 305;
      r.detail = std::to_string(m.shells + m.cavities) + " connected components";
    } else if (m.self_intersecting) {
      r.error = 306;
      r.detail = "the shell intersects itself";
    } else if (!m.oriented || (si == 0) != (m.shells == 1)) {
      r.error = 307;
      r.detail =
          si == 0 ? "the outer shell is not oriented outwards" : "a cavity is not oriented inwards";
    } else {
      r.shell = -1;
      continue;
    }
    return r;
  }
  return r;
}

std::vector<std::vector<int>> face_errors(const PolygonSolid& solid, const Tolerances& tol) {
  std::vector<std::vector<int>> out;
  for (const auto& faces : solid.shells) {
    out.emplace_back();
    bool indices_ok = true;
    for (const auto& f : faces)
      for (const int v : f)
        indices_ok = indices_ok && v >= 0 && std::size_t(v) < solid.vertices.size();
    if (!indices_ok) {
      out.back().assign(faces.size(), 101);
      continue;
    }
    const Snapped s = snap_shell(solid.vertices, faces, tol.snap);
    std::vector<std::array<int, 3>> tris;
    for (std::size_t fi = 0; fi < s.rings.size(); ++fi)
      out.back().push_back(check_face(s, fi, tol, tris).error);
  }
  return out;
}

double signed_volume(const std::vector<Vec3>& vertices,
                     const std::vector<std::vector<int>>& faces) {
  double volume = 0;  // 1/6 sum over faces of (a vertex . the face's doubled vector area)
  for (const auto& f : faces) {
    if (f.empty()) continue;
    Vec3 n(0, 0, 0);
    for (std::size_t i = 0; i < f.size(); ++i)
      n += vertices[std::size_t(f[i])].cross(vertices[std::size_t(f[(i + 1) % f.size()])]);
    volume += vertices[std::size_t(f[0])].dot(n) / 6;
  }
  return volume;
}

PolygonSolid make_solid(std::vector<Vec3> vertices, const std::vector<std::vector<int>>& faces,
                        std::vector<int>* shell_of) {
  std::vector<int> parent(faces.size());
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
  const auto find = [&](int x) {
    while (parent[std::size_t(x)] != x)
      x = parent[std::size_t(x)] = parent[std::size_t(parent[std::size_t(x)])];
    return x;
  };
  // faces joined across their edges (by vertex index): the edges sorted, each joined
  // to the first face on it
  std::vector<std::array<int, 3>> edges;  // a < b, face
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t i = 0; i < faces[f].size(); ++i) {
      int a = faces[f][i], b = faces[f][(i + 1) % faces[f].size()];
      if (a > b) std::swap(a, b);
      edges.push_back({a, b, int(f)});
    }
  std::sort(edges.begin(), edges.end());
  for (std::size_t e = 1; e < edges.size(); ++e)
    if (edges[e][0] == edges[e - 1][0] && edges[e][1] == edges[e - 1][1])
      parent[std::size_t(find(edges[e][2]))] = find(edges[e - 1][2]);
  // the pieces in order of their first face, each face's piece
  std::vector<std::size_t> piece_of_root(faces.size(), ~std::size_t(0));
  std::vector<std::vector<std::vector<int>>> pieces;
  std::vector<std::size_t> piece_of(faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    std::size_t& piece = piece_of_root[std::size_t(find(int(f)))];
    if (piece == ~std::size_t(0)) {
      piece = pieces.size();
      pieces.emplace_back();
    }
    pieces[piece].push_back(faces[f]);
    piece_of[f] = piece;
  }
  // the outer shell: the piece enclosing the largest volume (the first of equals)
  std::size_t outer = 0;
  double largest = pieces.empty() ? 0 : signed_volume(vertices, pieces[0]);
  for (std::size_t k = 1; k < pieces.size(); ++k) {
    const double v = signed_volume(vertices, pieces[k]);
    if (v > largest) {
      largest = v;
      outer = k;
    }
  }
  std::vector<int> shell_index(pieces.size());  // outer 0, the others in piece order
  for (std::size_t k = 0, next = 1; k < pieces.size(); ++k)
    shell_index[k] = k == outer ? 0 : int(next++);
  PolygonSolid s;
  s.vertices = std::move(vertices);
  s.shells.resize(pieces.size());
  for (std::size_t k = 0; k < pieces.size(); ++k)
    s.shells[std::size_t(shell_index[k])] = std::move(pieces[k]);
  if (shell_of) {
    shell_of->resize(faces.size());
    for (std::size_t f = 0; f < faces.size(); ++f) (*shell_of)[f] = shell_index[piece_of[f]];
  }
  return s;
}

double min_vertex_distance(const PolygonSolid& solid) {
  std::vector<char> used(solid.vertices.size(), 0);
  for (const auto& sh : solid.shells)
    for (const auto& f : sh)
      for (const int v : f)
        if (v >= 0 && std::size_t(v) < used.size()) used[std::size_t(v)] = 1;
  std::vector<Vec3> p;
  for (std::size_t i = 0; i < used.size(); ++i)
    if (used[i]) p.push_back(solid.vertices[i]);
  std::sort(p.begin(), p.end(), [](const Vec3& a, const Vec3& b) {
    return a.x() < b.x() ||
           (a.x() == b.x() && (a.y() < b.y() || (a.y() == b.y() && a.z() < b.z())));
  });
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size() && p[j].x() - p[i].x() < best; ++j)
      if (p[j] != p[i]) best = std::min(best, (p[j] - p[i]).norm());
  return best;
}

}  // namespace citylod::lod
