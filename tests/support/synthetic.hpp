// Synthetic buildings with exactly known geometry, for the tests of every module.
// Header-only, no CGAL. Each building is a closed set of convex planar faces
// (CCW seen from outside) from which we derive:
//  - a point cloud: uniform grid sampling of every face (spacing h, grid
//    anchored at the origin of each plane's frame), exact outward normals,
//    optional isotropic Gaussian noise (std::mt19937 + own Box-Muller, so the
//    values are identical on every platform);
//  - a triangle mesh: faces fanned, T-junctions between faces resolved,
//    vertices welded -> closed, oriented, edge-manifold; optional uniform 1-to-4
//    refinement (refine_levels) for a denser MVS-like mesh.
#pragma once

#include "citylod/lod/types.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <tuple>
#include <vector>

namespace citylod::test {

using lod::BuildingInput;
using lod::TriangleMesh;
using lod::Vec2;
using lod::Vec3;

/// A convex planar polygon, CCW seen from outside; `normal` is its outward unit normal.
struct Face {
  std::vector<Vec3> loop;
  Vec3 normal;
};

struct SynthOptions {
  double spacing = 0.1;      ///< m, grid step of the point sampling
  bool with_normals = true;  ///< false: BuildingInput::normals left empty
  double noise_sigma = 0.0;  ///< m, isotropic Gaussian noise on the points
  std::uint32_t seed = 1;    ///< noise seed
  int refine_levels = 0;     ///< mesh: uniform 1-to-4 splits of every triangle
};

struct SynthBuilding {
  BuildingInput input;      ///< point cloud (points [+ normals]) or mesh (points + triangles)
  double volume = 0.0;      ///< m^3, exact
  int planes = 0;           ///< number of distinct connected planar regions of the surface
  std::vector<Face> faces;  ///< the exact surface
  TriangleMesh mesh;        ///< the exact surface as a closed triangle mesh (both variants)
};

// ------------------------------------------------------------------ helpers

/// Rectangle o + s*e1 + t*e2 (s in [0,l1], t in [0,l2]) minus axis-aligned holes
/// {s0,s1,t0,t1} (disjoint, inside), as a grid of convex rectangles. Outward
/// normal = e1 x e2 (e1, e2 unit and orthogonal).
inline void add_rect(std::vector<Face>& faces, const Vec3& o, const Vec3& e1, double l1,
                     const Vec3& e2, double l2,
                     const std::vector<std::array<double, 4>>& holes = {}) {
  std::vector<double> ss{0, l1}, ts{0, l2};
  for (const auto& h : holes) {
    ss.push_back(h[0]);
    ss.push_back(h[1]);
    ts.push_back(h[2]);
    ts.push_back(h[3]);
  }
  std::sort(ss.begin(), ss.end());
  ss.erase(std::unique(ss.begin(), ss.end()), ss.end());
  std::sort(ts.begin(), ts.end());
  ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
  const Vec3 n = e1.cross(e2).normalized();
  for (std::size_t i = 0; i + 1 < ss.size(); ++i)
    for (std::size_t j = 0; j + 1 < ts.size(); ++j) {
      const double sm = 0.5 * (ss[i] + ss[i + 1]), tm = 0.5 * (ts[j] + ts[j + 1]);
      bool in_hole = false;
      for (const auto& h : holes)
        if (sm > h[0] && sm < h[1] && tm > h[2] && tm < h[3]) in_hole = true;
      if (in_hole) continue;
      Face f;
      f.normal = n;
      f.loop = {o + ss[i] * e1 + ts[j] * e2, o + ss[i + 1] * e1 + ts[j] * e2,
                o + ss[i + 1] * e1 + ts[j + 1] * e2, o + ss[i] * e1 + ts[j + 1] * e2};
      faces.push_back(std::move(f));
    }
}

/// Convex polygon from its loop (CCW from outside); normal by Newell's method.
inline void add_polygon(std::vector<Face>& faces, std::vector<Vec3> loop) {
  Vec3 n = Vec3::Zero();
  for (std::size_t i = 0; i < loop.size(); ++i) n += loop[i].cross(loop[(i + 1) % loop.size()]);
  faces.push_back({std::move(loop), n.normalized()});
}

/// The 6 faces of an axis-aligned box; `skip` bit i drops face i (0:-x 1:+x 2:-y 3:+y 4:-z 5:+z).
inline void add_box(std::vector<Face>& faces, const Vec3& lo, const Vec3& hi, unsigned skip = 0) {
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  const Vec3 d = hi - lo;
  if (!(skip & 1)) add_rect(faces, lo, Z, d.z(), Y, d.y());  // -x: z x y = -x
  if (!(skip & 2)) add_rect(faces, Vec3(hi.x(), lo.y(), lo.z()), Y, d.y(), Z, d.z());  // +x
  if (!(skip & 4)) add_rect(faces, lo, X, d.x(), Z, d.z());  // -y: x x z = -y
  if (!(skip & 8)) add_rect(faces, Vec3(lo.x(), hi.y(), lo.z()), Z, d.z(), X, d.x());   // +y
  if (!(skip & 16)) add_rect(faces, lo, Y, d.y(), X, d.x());                            // -z
  if (!(skip & 32)) add_rect(faces, Vec3(lo.x(), lo.y(), hi.z()), X, d.x(), Y, d.y());  // +z
}

/// Standard normal deviates, platform-stable (mt19937 raw output + Box-Muller).
class Gauss {
 public:
  explicit Gauss(std::uint32_t seed) : rng_(seed) {}
  double operator()() {
    if (has_) {
      has_ = false;
      return spare_;
    }
    double u1 = (static_cast<double>(rng_()) + 1.0) / 4294967297.0;  // (0,1)
    double u2 = static_cast<double>(rng_()) / 4294967296.0;          // [0,1)
    const double r = std::sqrt(-2.0 * std::log(u1)), a = 2.0 * 3.14159265358979323846 * u2;
    spare_ = r * std::sin(a);
    has_ = true;
    return r * std::cos(a);
  }

 private:
  std::mt19937 rng_;
  double spare_ = 0;
  bool has_ = false;
};

/// Grid sampling of the faces (see the file comment).
inline void sample_faces(const std::vector<Face>& faces, const SynthOptions& o, BuildingInput& in) {
  const double h = o.spacing;
  Gauss g(o.seed);
  for (const Face& f : faces) {
    const Vec3 n = f.normal;
    const Vec3 u =
        (std::abs(n.z()) < 0.9 ? Vec3::UnitZ().cross(n) : n.cross(Vec3::UnitX()).cross(n))
            .normalized();
    const Vec3 v = n.cross(u);
    const double off = n.dot(f.loop[0]);
    std::vector<Vec2> p2;
    double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
    for (const auto& q : f.loop) {
      p2.emplace_back(q.dot(u), q.dot(v));
      umin = std::min(umin, p2.back().x());
      umax = std::max(umax, p2.back().x());
      vmin = std::min(vmin, p2.back().y());
      vmax = std::max(vmax, p2.back().y());
    }
    const long i0 = static_cast<long>(std::floor(umin / h - 0.5)),
               i1 = static_cast<long>(std::ceil(umax / h));
    const long j0 = static_cast<long>(std::floor(vmin / h - 0.5)),
               j1 = static_cast<long>(std::ceil(vmax / h));
    for (long i = i0; i <= i1; ++i)
      for (long j = j0; j <= j1; ++j) {
        const Vec2 p((i + 0.5) * h, (j + 0.5) * h);
        bool inside = true;
        for (std::size_t k = 0; k < p2.size() && inside; ++k) {
          const Vec2 a = p2[k], b = p2[(k + 1) % p2.size()];
          const double c = (b.x() - a.x()) * (p.y() - a.y()) - (b.y() - a.y()) * (p.x() - a.x());
          if (c < 0) inside = false;
        }
        if (!inside) continue;
        Vec3 q = off * n + p.x() * u + p.y() * v;
        if (o.noise_sigma > 0) q += o.noise_sigma * Vec3(g(), g(), g());
        in.points.push_back(q);
        if (o.with_normals) in.normals.push_back(n);
      }
  }
}

/// Closed triangle mesh of the faces: fan triangulation, T-junctions split, vertices welded.
inline TriangleMesh mesh_faces(const std::vector<Face>& faces, int refine_levels = 0) {
  TriangleMesh m;
  std::map<std::tuple<long long, long long, long long>, int> index;
  auto vid = [&](const Vec3& p) {
    const auto k = std::make_tuple(std::llround(p.x() * 1e7), std::llround(p.y() * 1e7),
                                   std::llround(p.z() * 1e7));
    auto it = index.find(k);
    if (it != index.end()) return it->second;
    m.vertices.push_back(p);
    index.emplace(k, static_cast<int>(m.vertices.size() - 1));
    return static_cast<int>(m.vertices.size() - 1);
  };
  for (const Face& f : faces) {
    std::vector<int> ids;
    for (const auto& p : f.loop) ids.push_back(vid(p));
    for (std::size_t i = 1; i + 1 < ids.size(); ++i)
      m.triangles.push_back({ids[0], ids[i], ids[i + 1]});
  }
  // T-junctions: split every triangle edge at the vertices lying inside it.
  bool changed = true;
  while (changed) {
    changed = false;
    std::vector<std::array<int, 3>> out;
    for (const auto& t : m.triangles) {
      bool split = false;
      for (int e = 0; e < 3 && !split; ++e) {
        const Vec3& a = m.vertices[t[e]];
        const Vec3& b = m.vertices[t[(e + 1) % 3]];
        const Vec3 ab = b - a;
        const double l2 = ab.squaredNorm();
        for (int w = 0; w < static_cast<int>(m.vertices.size()); ++w) {
          if (w == t[0] || w == t[1] || w == t[2]) continue;
          const Vec3 ap = m.vertices[w] - a;
          const double s = ap.dot(ab) / l2;
          if (s <= 1e-9 || s >= 1 - 1e-9) continue;
          if ((ap - s * ab).squaredNorm() > 1e-14) continue;
          out.push_back({t[e], w, t[(e + 2) % 3]});
          out.push_back({w, t[(e + 1) % 3], t[(e + 2) % 3]});
          split = changed = true;
          break;
        }
      }
      if (!split) out.push_back(t);
    }
    m.triangles.swap(out);
  }
  for (int l = 0; l < refine_levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto mv = [&](int a, int b) {
      const auto k = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(k);
      if (it != mid.end()) return it->second;
      m.vertices.push_back(0.5 * (m.vertices[k.first] + m.vertices[k.second]));
      const int id = static_cast<int>(m.vertices.size() - 1);
      mid.emplace(k, id);
      return id;
    };
    std::vector<std::array<int, 3>> out;
    for (const auto& t : m.triangles) {
      const int ab = mv(t[0], t[1]), bc = mv(t[1], t[2]), ca = mv(t[2], t[0]);
      out.push_back({t[0], ab, ca});
      out.push_back({ab, t[1], bc});
      out.push_back({ca, bc, t[2]});
      out.push_back({ab, bc, ca});
    }
    m.triangles.swap(out);
  }
  return m;
}

/// Fills input as a point cloud (mesh=false) or a triangle mesh (mesh=true).
inline SynthBuilding finish(std::vector<Face> faces, double volume, int planes,
                            const SynthOptions& o, bool mesh) {
  SynthBuilding b;
  b.volume = volume;
  b.planes = planes;
  b.mesh = mesh_faces(faces, mesh ? o.refine_levels : 0);
  if (mesh) {
    b.input.points = b.mesh.vertices;
    b.input.triangles = b.mesh.triangles;
  } else {
    sample_faces(faces, o, b.input);
  }
  b.faces = std::move(faces);
  return b;
}

// ------------------------------------------------------------------ buildings

/// Axis-aligned box [lo, hi]: 6 planes.
inline SynthBuilding sample_box(const Vec3& lo, const Vec3& hi, double spacing = 0.1,
                                bool with_normals = true, double noise_sigma = 0.0,
                                std::uint32_t seed = 1) {
  std::vector<Face> f;
  add_box(f, lo, hi);
  SynthOptions o;
  o.spacing = spacing;
  o.with_normals = with_normals;
  o.noise_sigma = noise_sigma;
  o.seed = seed;
  const Vec3 d = hi - lo;
  return finish(std::move(f), d.x() * d.y() * d.z(), 6, o, false);
}
inline SynthBuilding box(const Vec3& lo, const Vec3& hi, const SynthOptions& o = {},
                         bool mesh = false) {
  std::vector<Face> f;
  add_box(f, lo, hi);
  const Vec3 d = hi - lo;
  return finish(std::move(f), d.x() * d.y() * d.z(), 6, o, mesh);
}

/// Only the roof (top face) of a box, as airborne LiDAR sees it. `volume` is the box's.
inline SynthBuilding roof_only_box(const Vec3& lo, const Vec3& hi, const SynthOptions& o = {}) {
  std::vector<Face> f;
  add_box(f, lo, hi, 1 | 2 | 4 | 8 | 16);
  const Vec3 d = hi - lo;
  SynthBuilding b = finish(std::move(f), d.x() * d.y() * d.z(), 1, o, false);
  b.input.ground_z = lo.z();
  b.input.has_ground_z = true;
  return b;
}

/// The walls and floor of an S::L x S::W x S::H box whose front wall (y = 0)
/// has S::windows windows recessed S::depth (S::win_x(k), S::win_w, S::win_z,
/// S::win_h); the roof is the caller's.
template <class S>
void add_box_with_windows(std::vector<Face>& f) {
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  add_box(f, Vec3(0, 0, 0), Vec3(S::L, S::W, S::H), 4 | 32);  // without front wall and roof
  std::vector<std::array<double, 4>> holes;
  for (int k = 0; k < S::windows; ++k)
    holes.push_back({S::win_x(k), S::win_x(k) + S::win_w, S::win_z, S::win_z + S::win_h});
  add_rect(f, Vec3(0, 0, 0), X, S::L, Z, S::H, holes);  // front wall (normal -y)
  for (int k = 0; k < S::windows; ++k) {
    const double a = S::win_x(k), b = a + S::win_w, c = S::win_z, d = c + S::win_h, dp = S::depth;
    add_rect(f, Vec3(a, dp, c), X, S::win_w, Z, S::win_h);  // back, -y
    add_rect(f, Vec3(a, 0, c), Y, dp, Z, S::win_h);         // side x=a, +x
    add_rect(f, Vec3(b, 0, c), Z, S::win_h, Y, dp);         // side x=b, -x
    add_rect(f, Vec3(a, 0, c), X, S::win_w, Y, dp);         // sill z=c, +z
    add_rect(f, Vec3(a, 0, d), Y, dp, X, S::win_w);         // lintel z=d, -z
  }
}

/// Box 12 x 8 x 6 m with a 1 x 1 x 2 m chimney on the roof (x 8..9, y 5..6) and
/// 4 recessed windows 1.2 x 1.5 m, 0.3 m deep, in the wall y = 0 (x = 1.5 + 2.5k,
/// z 2..3.5). Planes: 6 (box) + 5 (chimney) + 4 x 5 (windows) = 31.
struct ChimneyWindowsSpec {
  static constexpr double L = 12, W = 8, H = 6;
  static constexpr double win_w = 1.2, win_h = 1.5, win_z = 2.0, depth = 0.3;
  static constexpr int windows = 4;
  static double win_x(int k) { return 1.5 + 2.5 * k; }
  static constexpr double cx0 = 8, cx1 = 9, cy0 = 5, cy1 = 6, ch = 2;
};
inline SynthBuilding chimney_windows(const SynthOptions& o = {}, bool mesh = false) {
  using S = ChimneyWindowsSpec;
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY();
  std::vector<Face> f;
  add_box_with_windows<S>(f);
  add_rect(f, Vec3(0, 0, S::H), X, S::L, Y, S::W,
           {{S::cx0, S::cx1, S::cy0, S::cy1}});  // roof with hole
  add_box(f, Vec3(S::cx0, S::cy0, S::H), Vec3(S::cx1, S::cy1, S::H + S::ch),
          16);  // chimney, no bottom
  const double vol = S::L * S::W * S::H - S::windows * S::win_w * S::win_h * S::depth +
                     (S::cx1 - S::cx0) * (S::cy1 - S::cy0) * S::ch;
  return finish(std::move(f), vol, 6 + 5 + 5 * S::windows, o, mesh);
}

/// L-shaped flat-roof block: footprint (0,0)-(10,0)-(10,4)-(4,4)-(4,10)-(0,10), height 5. 8 planes.
inline SynthBuilding l_shape(const SynthOptions& o = {}, bool mesh = false) {
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  const double H = 5;
  std::vector<Face> f;
  add_rect(f, Vec3(0, 0, 0), X, 10, Z, H);  // y=0, -y
  add_rect(f, Vec3(10, 0, 0), Y, 4, Z, H);  // x=10, +x
  add_rect(f, Vec3(4, 4, 0), Z, H, X, 6);   // y=4 (x 4..10), +y
  add_rect(f, Vec3(4, 4, 0), Y, 6, Z, H);   // x=4 (y 4..10), +x
  add_rect(f, Vec3(0, 10, 0), Z, H, X, 4);  // y=10, +y
  add_rect(f, Vec3(0, 0, 0), Z, H, Y, 10);  // x=0, -x
  add_rect(f, Vec3(0, 0, 0), Y, 4, X, 10);  // floor, -z
  add_rect(f, Vec3(0, 4, 0), Y, 6, X, 4);
  add_rect(f, Vec3(0, 0, H), X, 10, Y, 4);  // roof, +z
  add_rect(f, Vec3(0, 4, H), X, 4, Y, 6);
  return finish(std::move(f), (40.0 + 24.0) * H, 8, o, mesh);
}

/// Gable-roof house 10 (x) x 8 (y), eaves 5 m, ridge 8 m along x at y = 4, with a
/// flat-topped dormer on the south roof: x 3..6, front wall at y = 1 (roof z 5.75),
/// top z = 7.25 reaching the roof at y = 3. Planes: 4 walls (gable ends are
/// pentagons) + floor + 2 roofs + dormer (front, 2 sides, top) = 11.
inline SynthBuilding gable_dormer(const SynthOptions& o = {}, bool mesh = false) {
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  const double Wx = 10, Dy = 8, H = 5, R = 3;
  const double dx0 = 3, dx1 = 6, yf = 1, zt = 7.25;
  const double zf = H + R * yf / (Dy / 2), yb = (zt - H) * (Dy / 2) / R;
  std::vector<Face> f;
  add_rect(f, Vec3(0, 0, 0), X, Wx, Z, H);   // y=0 wall, -y
  add_rect(f, Vec3(0, Dy, 0), Z, H, X, Wx);  // y=8 wall, +y
  add_rect(f, Vec3(0, 0, 0), Y, Dy, X, Wx);  // floor, -z
  add_polygon(f, {Vec3(0, 0, 0), Vec3(0, 0, H), Vec3(0, Dy / 2, H + R), Vec3(0, Dy, H),
                  Vec3(0, Dy, 0)});  // -x
  add_polygon(f, {Vec3(Wx, Dy, 0), Vec3(Wx, Dy, H), Vec3(Wx, Dy / 2, H + R), Vec3(Wx, 0, H),
                  Vec3(Wx, 0, 0)});                          // +x
  const double sl = std::sqrt((Dy / 2) * (Dy / 2) + R * R);  // slope length
  const Vec3 up_s = Vec3(0, Dy / 2, R) / sl, up_n = Vec3(0, -Dy / 2, R) / sl;
  // South roof (e1 = x, e2 = up the slope), with the dormer's footprint as a hole.
  add_rect(f, Vec3(0, 0, H), X, Wx, up_s, sl, {{dx0, dx1, yf / (Dy / 2) * sl, yb / (Dy / 2) * sl}});
  add_rect(f, Vec3(0, Dy, H), up_n, sl, X, Wx);  // north roof
  // Dormer.
  add_rect(f, Vec3(dx0, yf, zf), X, dx1 - dx0, Z, zt - zf);                   // front, -y
  add_polygon(f, {Vec3(dx0, yf, zf), Vec3(dx0, yf, zt), Vec3(dx0, yb, zt)});  // side x=3, -x
  add_polygon(f, {Vec3(dx1, yf, zf), Vec3(dx1, yb, zt), Vec3(dx1, yf, zt)});  // side x=6, +x
  add_rect(f, Vec3(dx0, yf, zt), X, dx1 - dx0, Y, yb - yf);                   // top, +z
  const double vol = Wx * Dy * H + Wx * 0.5 * Dy * R + (dx1 - dx0) * 0.5 * (yb - yf) * (zt - zf);
  return finish(std::move(f), vol, 11, o, mesh);
}

/// Flat-roof house 14 x 10 x 6 m with two dormers (roof boxes 2.5 x 1.6 x
/// 1.2 m = 4.8 m^3 at x 2..4.5 and 7..9.5, y 6..7.6), a chimney 0.8 x 0.8 x
/// 1.5 m = 0.96 m^3 (x 11..11.8, y 2..2.8) and 4 recessed windows 1.2 x 1.5 m,
/// 0.3 m deep (0.54 m^3) in the wall y = 0 (x = 1.5 + 3k, z 2..3.5). Planes:
/// 6 + 2 x 5 + 5 + 4 x 5 = 41.
struct DormerHouseSpec {
  static constexpr double L = 14, W = 10, H = 6;
  static constexpr double dx0[2] = {2, 7}, dw = 2.5, dy0 = 6, dd = 1.6, dh = 1.2;
  static constexpr double cx0 = 11, cy0 = 2, cs = 0.8, ch = 1.5;
  static constexpr double win_w = 1.2, win_h = 1.5, win_z = 2.0, depth = 0.3;
  static constexpr int windows = 4;
  static double win_x(int k) { return 1.5 + 3.0 * k; }
};
inline SynthBuilding dormer_house(const SynthOptions& o = {}, bool mesh = false) {
  using S = DormerHouseSpec;
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY();
  std::vector<Face> f;
  add_box_with_windows<S>(f);
  add_rect(f, Vec3(0, 0, S::H), X, S::L, Y, S::W,
           {{S::dx0[0], S::dx0[0] + S::dw, S::dy0, S::dy0 + S::dd},
            {S::dx0[1], S::dx0[1] + S::dw, S::dy0, S::dy0 + S::dd},
            {S::cx0, S::cx0 + S::cs, S::cy0, S::cy0 + S::cs}});  // roof with holes
  for (double x0 : S::dx0)
    add_box(f, Vec3(x0, S::dy0, S::H), Vec3(x0 + S::dw, S::dy0 + S::dd, S::H + S::dh), 16);
  add_box(f, Vec3(S::cx0, S::cy0, S::H), Vec3(S::cx0 + S::cs, S::cy0 + S::cs, S::H + S::ch), 16);
  const double vol = S::L * S::W * S::H + 2 * S::dw * S::dd * S::dh + S::cs * S::cs * S::ch -
                     S::windows * S::win_w * S::win_h * S::depth;
  return finish(std::move(f), vol, 6 + 2 * 5 + 5 + 5 * S::windows, o, mesh);
}

}  // namespace citylod::test
