// Tests of the exact adaptive BSP and its watertight surface extraction.
#include "bsp.hpp"
#include "bsp_impl.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <thread>

using citylod::lod::PolygonMesh;
using citylod::lod::TriangleMesh;
using citylod::lod::Vec3;
using citylod::lod::detail::Bsp;
using citylod::lod::detail::BspPolygon;
using citylod::lod::detail::BspSurface;
using citylod::lod::detail::ExtractCache;

namespace {

// axis-aligned rectangle on plane coordinate `axis` == v, spanning [a0,a1] x [b0,b1] on the other
// two axes (cyclic)
BspPolygon rect(int axis, double v, double a0, double a1, double b0, double b1, int prim) {
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;
  std::vector<Vec3> pts(4, Vec3::Zero());
  const double uv[4][2] = {{a0, b0}, {a1, b0}, {a1, b1}, {a0, b1}};
  for (int i = 0; i < 4; ++i) {
    pts[i][axis] = v;
    pts[i][u] = uv[i][0];
    pts[i][w] = uv[i][1];
  }
  BspPolygon p;
  p.polygon = pts;
  p.primitive = prim;
  p.plane = {0, 0, 0, -v};
  p.plane[axis] = 1;
  return p;
}

// the 6 faces of an axis-aligned box
std::vector<BspPolygon> box_faces(const Vec3& lo, const Vec3& hi, int prim0) {
  std::vector<BspPolygon> out;
  const int order[3] = {2, 0, 1};
  for (int axis : order) {
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    out.push_back(rect(axis, lo[axis], lo[u], hi[u], lo[w], hi[w], prim0++));
    out.push_back(rect(axis, hi[axis], lo[u], hi[u], lo[w], hi[w], prim0++));
  }
  return out;
}

struct MeshReport {
  bool closed = true;       // every undirected edge used by exactly 2 triangles
  bool oriented = true;     // every directed edge used once
  bool degenerate = false;  // repeated index in a triangle
  int edges = 0;
  int pinched = 0;  // vertices whose triangles form more than one fan through edges at the vertex
};

MeshReport check_mesh(const TriangleMesh& m) {
  MeshReport r;
  std::map<std::pair<int, int>, int> und, dir;
  for (const auto& t : m.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) r.degenerate = true;
    for (int e = 0; e < 3; ++e) {
      const int a = t[e], b = t[(e + 1) % 3];
      ++dir[{a, b}];
      ++und[{std::min(a, b), std::max(a, b)}];
    }
  }
  for (const auto& [e, n] : und)
    if (n != 2) r.closed = false;
  for (const auto& [e, n] : dir)
    if (n != 1) r.oriented = false;
  r.edges = int(und.size());
  // Fans around each vertex: triangles at v joined when they share an edge (v, w).
  std::map<int, std::vector<size_t>> around;
  for (size_t t = 0; t < m.triangles.size(); ++t)
    for (int v : m.triangles[t]) around[v].push_back(t);
  for (const auto& [v, ts] : around) {
    std::vector<size_t> parent(ts.size());
    for (size_t i = 0; i < ts.size(); ++i) parent[i] = i;
    std::function<size_t(size_t)> find = [&](size_t x) {
      return parent[x] == x ? x : parent[x] = find(parent[x]);
    };
    std::map<int, size_t> by_other;
    for (size_t i = 0; i < ts.size(); ++i)
      for (int w : m.triangles[ts[i]]) {
        if (w == v) continue;
        auto it = by_other.find(w);
        if (it == by_other.end())
          by_other[w] = i;
        else
          parent[find(i)] = find(it->second);
      }
    size_t fans = 0;
    for (size_t i = 0; i < ts.size(); ++i) fans += find(i) == i;
    r.pinched += fans > 1;
  }
  return r;
}

// Polygon mesh closedness: every directed edge of the face loops appears once, and its reverse
// once.
bool polygon_mesh_closed(const PolygonMesh& m) {
  std::map<std::pair<int, int>, int> dir;
  for (const auto& f : m.faces)
    for (size_t i = 0; i < f.size(); ++i) ++dir[{f[i], f[(i + 1) % f.size()]}];
  for (const auto& [e, n] : dir) {
    if (n != 1) return false;
    auto it = dir.find({e.second, e.first});
    if (it == dir.end() || it->second != 1) return false;
  }
  return true;
}

double mesh_volume(const TriangleMesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]));
  return v / 6.0;
}

double sum_inside_volume(const Bsp& bsp, const std::vector<int>& part,
                         const std::vector<char>& in) {
  double v = 0;
  for (size_t i = 0; i < part.size(); ++i)
    if (in[i]) v += bsp.nodes()[part[i]].volume;
  return v;
}

std::vector<char> label_by(const Bsp& bsp, const std::vector<int>& part,
                           const std::function<bool(const Vec3&)>& f) {
  std::vector<char> in;
  for (int n : part) in.push_back(f(bsp.nodes()[n].center) ? 1 : 0);
  return in;
}

bool in_box(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return (p.array() > lo.array()).all() && (p.array() < hi.array()).all();
}

void expect_good_surface(const BspSurface& s, const char* what) {
  const MeshReport r = check_mesh(s.triangles);
  EXPECT_TRUE(r.closed) << what;
  EXPECT_TRUE(r.oriented) << what;
  EXPECT_FALSE(r.degenerate) << what;
  EXPECT_TRUE(polygon_mesh_closed(s.polygons)) << what;
  EXPECT_EQ(s.polygons.vertices.size(), s.triangles.vertices.size()) << what;
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

TEST(Bsp, OneSplitGivesThreeNodes) {
  const Vec3 lo(0, 0, 0), hi(2, 1, 1);
  std::vector<BspPolygon> polys{rect(0, 0.5, -1, 2, -1, 2, 7)};
  Bsp bsp(lo, hi, polys, 0);
  ASSERT_EQ(bsp.nodes().size(), 3u);
  EXPECT_FALSE(bsp.cap_hit());
  EXPECT_EQ(bsp.planes().size(), 7u);
  const auto& n = bsp.nodes();
  EXPECT_EQ(n[0].split_primitive, 7);
  EXPECT_EQ(n[0].split_plane, 6);
  EXPECT_EQ(n[0].children[0], 1);
  EXPECT_EQ(n[0].children[1], 2);
  EXPECT_EQ(n[1].parent, 0);
  EXPECT_EQ(n[1].depth, 1);
  EXPECT_NEAR(n[0].volume, 2.0, 1e-12);
  EXPECT_NEAR(n[1].volume, 0.5, 1e-12);  // x < 0.5: negative side of x - 0.5
  EXPECT_NEAR(n[2].volume, 1.5, 1e-12);
  EXPECT_NEAR(n[1].volume + n[2].volume, n[0].volume, 1e-12);
  EXPECT_NEAR(n[1].center.x(), 0.25, 1e-12);
  EXPECT_EQ(bsp.leaves(), (std::vector<int>{1, 2}));
  EXPECT_EQ(bsp.cell_vertices(1).size(), 8u);

  const auto adj = bsp.adjacency(bsp.leaves());
  ASSERT_EQ(adj.size(), 1u);
  EXPECT_EQ(adj[0].a, 1);
  EXPECT_EQ(adj[0].b, 2);
  EXPECT_EQ(adj[0].plane, 6);
  EXPECT_NEAR(adj[0].area, 1.0, 1e-12);
  EXPECT_EQ(adj[0].polygon.size(), 4u);
}

TEST(Bsp, TiltedSplitVolumesSum) {
  const Vec3 lo(0, 0, 0), hi(1, 1, 1);
  // plane x + 2y + 3z = 2.5 through the whole box
  Vec3 n(1, 2, 3);
  const double nn = n.norm();
  BspPolygon p;
  p.primitive = 0;
  p.plane = {1 / nn, 2 / nn, 3 / nn, -2.5 / nn};
  // big polygon in the plane
  const Vec3 c = n * (2.5 / (nn * nn));
  const Vec3 a = n.unitOrthogonal(), b = n.normalized().cross(a);
  for (int i = 0; i < 6; ++i) {
    const double t = 2 * M_PI * i / 6;
    p.polygon.push_back(c + 10 * (std::cos(t) * a + std::sin(t) * b));
  }
  Bsp bsp(lo, hi, {p}, 0);
  ASSERT_EQ(bsp.nodes().size(), 3u);
  const auto& N = bsp.nodes();
  EXPECT_NEAR(N[1].volume + N[2].volume, 1.0, 1e-12);
  // whole box as a partition, and the two leaves: both extract to a closed surface of volume 1
  for (const std::vector<int>& part : {std::vector<int>{0}, std::vector<int>{1, 2}}) {
    const auto s = bsp.extract(part, std::vector<char>(part.size(), 1));
    expect_good_surface(s, "tilted");
    EXPECT_NEAR(mesh_volume(s.triangles), 1.0, 1e-12);
    EXPECT_EQ(s.merged_regions, 6);
  }
  const auto s1 = bsp.extract({1, 2}, {1, 0});
  expect_good_surface(s1, "tilted lower");
  EXPECT_NEAR(mesh_volume(s1.triangles), N[1].volume, 1e-12);
}

TEST(Bsp, CubeInsideEnlargedBox) {
  const Vec3 lo(-1, -1, -1), hi(2, 2, 2);
  Bsp bsp(lo, hi, box_faces(Vec3(0, 0, 0), Vec3(1, 1, 1), 0), 0);
  const auto leaves = bsp.leaves();
  EXPECT_EQ(leaves.size(), 7u);
  EXPECT_EQ(bsp.planes().size(), 12u);
  int cube = -1;
  double total = 0;
  for (int l : leaves) {
    total += bsp.nodes()[l].volume;
    if (in_box(bsp.nodes()[l].center, Vec3(0, 0, 0), Vec3(1, 1, 1))) {
      EXPECT_EQ(cube, -1);
      cube = l;
    }
  }
  EXPECT_NEAR(total, 27.0, 1e-9);
  ASSERT_GE(cube, 0);
  EXPECT_NEAR(bsp.nodes()[cube].volume, 1.0, 1e-9);
  EXPECT_EQ(bsp.cell_vertices(cube).size(), 8u);

  const BspSurface s = bsp.extract({cube}, {1});
  expect_good_surface(s, "cube");
  EXPECT_EQ(s.merged_regions, 6);
  EXPECT_EQ(s.polygons.faces.size(), 6u);
  for (const auto& f : s.polygons.faces) EXPECT_EQ(f.size(), 4u);
  EXPECT_EQ(s.triangles.triangles.size(), 12u);
  EXPECT_EQ(s.triangles.vertices.size(), 8u);
  EXPECT_NEAR(mesh_volume(s.triangles), 1.0, 1e-12);
  EXPECT_EQ(s.labels_flipped, 0);

  // the same from the full leaf partition
  const auto in =
      label_by(bsp, leaves, [](const Vec3& p) { return in_box(p, Vec3(0, 0, 0), Vec3(1, 1, 1)); });
  const BspSurface s2 = bsp.extract(leaves, in);
  expect_good_surface(s2, "cube (leaves)");
  EXPECT_EQ(s2.merged_regions, 6);
  EXPECT_EQ(s2.triangles.triangles.size(), 12u);

  // the cube leaf has exactly 6 interfaces of area 1
  int ncube = 0;
  for (const auto& itf : bsp.adjacency(leaves))
    if (itf.a == cube || itf.b == cube) {
      ++ncube;
      EXPECT_NEAR(itf.area, 1.0, 1e-12);
    }
  EXPECT_EQ(ncube, 6);

  // complement: everything but the cube -> box with a cubic cavity, two shells
  std::vector<char> out(in.size());
  for (size_t i = 0; i < in.size(); ++i) out[i] = !in[i];
  const BspSurface s3 = bsp.extract(leaves, out);
  expect_good_surface(s3, "cavity");
  EXPECT_NEAR(mesh_volume(s3.triangles), 26.0, 1e-12);
  EXPECT_EQ(s3.merged_regions, 12);
}

TEST(Bsp, SmallPolygonsSplitOnlyTheCellsTheyCross) {
  const Vec3 lo(0, 0, 0), hi(4, 4, 4);
  std::vector<BspPolygon> polys{
      rect(0, 2.0, -1, 5, -1, 5, 0),        // x = 2 through everything: 2 leaves
      rect(1, 1.0, 0.5, 1.5, 0.5, 1.5, 1),  // y = 1, z in [.5,1.5], x in [.5,1.5]: only x<2 -> 3
      rect(2, 3.0, 1.0, 3.0, 0.0, 4.0, 2),  // z = 3, x in [1,3], y in [0,4]: 3 cells -> 6
      rect(2, 1.0, 2.5, 3.5, 0.5, 1.5, 3),  // z = 1, x in [2.5,3.5]: only x>2, z<3 -> 7
      rect(0, 1.0, 2.0, 3.0, 3.5, 3.9, 4),  // x = 1, y in [2,3], z in [3.5,3.9]: x<2, y>1, z>3 -> 8
      rect(0, 3.0, 5.0, 6.0, 1.0, 2.0, 5),  // outside the box: nothing
  };
  // note rect() spans (u,w) = cyclic axes: for axis 0 (x) u = y, w = z; axis 1 (y): u = z, w = x;
  // axis 2: u = x, w = y
  Bsp bsp(lo, hi, polys, 0);
  EXPECT_EQ(bsp.leaves().size(), 8u);
  double total = 0;
  for (int l : bsp.leaves()) total += bsp.nodes()[l].volume;
  EXPECT_NEAR(total, 64.0, 1e-9);
  std::set<int> prims;
  for (const auto& n : bsp.nodes())
    if (!n.is_leaf()) prims.insert(n.split_primitive);
  EXPECT_EQ(prims, (std::set<int>{0, 1, 2, 3, 4}));

  // cap: at most 4 leaves
  Bsp capped(lo, hi, polys, 4);
  EXPECT_TRUE(capped.cap_hit());
  EXPECT_EQ(capped.leaves().size(), 4u);
  Bsp exact_cap(lo, hi, polys, 8);
  EXPECT_FALSE(exact_cap.cap_hit());
  EXPECT_EQ(exact_cap.leaves().size(), 8u);
}

TEST(Bsp, LShapePrism) {
  // L in xy: [0,2]x[0,1] U [0,1]x[1,2], z in [0,1]
  auto inL = [](const Vec3& p) {
    if (p.z() <= 0 || p.z() >= 1) return false;
    return (p.x() > 0 && p.x() < 2 && p.y() > 0 && p.y() < 1) ||
           (p.x() > 0 && p.x() < 1 && p.y() > 0 && p.y() < 2);
  };
  std::vector<BspPolygon> polys{
      rect(2, 0, 0, 2, 0, 1, 0), rect(2, 0, 0, 1, 1, 2, 1),  // bottom (two convex parts)
      rect(2, 1, 0, 2, 0, 1, 2), rect(2, 1, 0, 1, 1, 2, 3),  // top
      rect(0, 0, 0, 2, 0, 1, 4),                             // x = 0, y 0..2
      rect(1, 0, 0, 1, 0, 2, 5),                             // y = 0, (z,x) = z 0..1, x 0..2
      rect(0, 2, 0, 1, 0, 1, 6),                             // x = 2, y 0..1
      rect(1, 1, 0, 1, 1, 2, 7),                             // y = 1, x 1..2
      rect(0, 1, 1, 2, 0, 1, 8),                             // x = 1, y 1..2
      rect(1, 2, 0, 1, 0, 1, 9),                             // y = 2, x 0..1
  };
  Bsp bsp(Vec3(-1, -1, -1), Vec3(3, 3, 2), polys, 0);
  const auto leaves = bsp.leaves();
  const auto in = label_by(bsp, leaves, inL);
  EXPECT_NEAR(sum_inside_volume(bsp, leaves, in), 3.0, 1e-9);
  const double t0 = now_s();
  const BspSurface s = bsp.extract(leaves, in);
  std::printf("[ L-shape ] %zu leaves, extract %.2f ms\n", leaves.size(), 1e3 * (now_s() - t0));
  expect_good_surface(s, "L");
  EXPECT_EQ(s.merged_regions, 8);
  EXPECT_EQ(s.polygons.faces.size(), 8u);
  EXPECT_EQ(s.labels_flipped, 0);
  EXPECT_NEAR(mesh_volume(s.triangles), 3.0, 1e-12);
  // L-shaped top and bottom have 6 corners; the 6 walls are rectangles
  std::multiset<size_t> sizes;
  for (const auto& f : s.polygons.faces) sizes.insert(f.size());
  EXPECT_EQ(sizes, (std::multiset<size_t>{4, 4, 4, 4, 4, 4, 6, 6}));
  EXPECT_EQ(s.polygons.vertices.size(), 12u);
}

TEST(Bsp, TJunctionBoxOnBox) {
  // big box [0,4]x[0,4]x[0,2], small box [0,1]x[0,1]x[2,3] on its corner (shares the walls x=0,
  // y=0)
  const Vec3 blo(0, 0, 0), bhi(4, 4, 2), slo(0, 0, 2), shi(1, 1, 3);
  auto polys = box_faces(blo, bhi, 0);
  auto small = box_faces(slo, shi, 6);
  polys.insert(polys.end(), small.begin(), small.end());
  Bsp bsp(Vec3(-1, -1, -1), Vec3(5, 5, 4), polys, 0);
  const auto leaves = bsp.leaves();
  const auto in = label_by(
      bsp, leaves, [&](const Vec3& p) { return in_box(p, blo, bhi) || in_box(p, slo, shi); });
  EXPECT_NEAR(sum_inside_volume(bsp, leaves, in), 33.0, 1e-9);
  const BspSurface s = bsp.extract(leaves, in);
  expect_good_surface(s, "T-junction");
  EXPECT_NEAR(mesh_volume(s.triangles), 33.0, 1e-12);
  // bottom, x=0 (merged L), y=0 (merged L), x=4, y=4, top of big (L), small: x=1, y=1, top
  EXPECT_EQ(s.merged_regions, 9);
  EXPECT_EQ(s.labels_flipped, 0);

  // small box in the middle of the top: the big top has a hole
  const Vec3 mlo(1, 1, 2), mhi(2, 2, 3);
  auto polys2 = box_faces(blo, bhi, 0);
  auto mid = box_faces(mlo, mhi, 6);
  polys2.insert(polys2.end(), mid.begin(), mid.end());
  Bsp bsp2(Vec3(-1, -1, -1), Vec3(5, 5, 4), polys2, 0);
  const auto l2 = bsp2.leaves();
  const auto in2 =
      label_by(bsp2, l2, [&](const Vec3& p) { return in_box(p, blo, bhi) || in_box(p, mlo, mhi); });
  const BspSurface s2 = bsp2.extract(l2, in2);
  expect_good_surface(s2, "T-junction hole");
  EXPECT_NEAR(mesh_volume(s2.triangles), 33.0, 1e-12);
  EXPECT_EQ(s2.merged_regions, 11);  // 6 + 5, the top with a hole counts once
}

TEST(Bsp, WindowCutout) {
  // a house box with a recessed window cut into the wall y = 0
  const Vec3 blo(0, 0, 0), bhi(4, 4, 3), wlo(1, 0, 1), whi(2, 0.5, 2);
  auto polys = box_faces(blo, bhi, 0);
  polys.push_back(rect(1, 0.5, 1, 2, 1, 2, 6));   // back of the recess: y = 0.5, (z,x)
  polys.push_back(rect(0, 1, 0, 0.5, 1, 2, 7));   // x = 1, (y,z)
  polys.push_back(rect(0, 2, 0, 0.5, 1, 2, 8));   // x = 2
  polys.push_back(rect(2, 1, 1, 2, 0, 0.5, 9));   // z = 1, (x,y)
  polys.push_back(rect(2, 2, 1, 2, 0, 0.5, 10));  // z = 2
  Bsp bsp(Vec3(-1, -1, -1), Vec3(5, 5, 4), polys, 0);
  const auto leaves = bsp.leaves();
  const auto in = label_by(
      bsp, leaves, [&](const Vec3& p) { return in_box(p, blo, bhi) && !in_box(p, wlo, whi); });
  EXPECT_NEAR(sum_inside_volume(bsp, leaves, in), 47.5, 1e-9);
  const BspSurface s = bsp.extract(leaves, in);
  expect_good_surface(s, "window");
  EXPECT_NEAR(mesh_volume(s.triangles), 47.5, 1e-12);
  EXPECT_EQ(s.merged_regions, 11);  // 6 outer (the wall y=0 with a hole) + 5 recess faces
  EXPECT_EQ(s.labels_flipped, 0);
}

TEST(Bsp, DiagonalCubesNonManifoldEdgeRepaired) {
  const Vec3 alo(0, 0, 0), ahi(1, 1, 1), blo(1, 1, 0), bhi(2, 2, 1);
  auto polys = box_faces(alo, ahi, 0);
  auto b = box_faces(blo, bhi, 6);
  polys.insert(polys.end(), b.begin(), b.end());
  Bsp bsp(Vec3(-1, -1, -1), Vec3(3, 3, 2), polys, 0);
  const auto leaves = bsp.leaves();
  const auto in = label_by(
      bsp, leaves, [&](const Vec3& p) { return in_box(p, alo, ahi) || in_box(p, blo, bhi); });
  const BspSurface s = bsp.extract(leaves, in);
  expect_good_surface(s, "diagonal");
  EXPECT_EQ(s.labels_flipped, 1);
  ASSERT_EQ(s.inside.size(), in.size());
  EXPECT_NEAR(mesh_volume(s.triangles), sum_inside_volume(bsp, leaves, s.inside), 1e-12);
  EXPECT_GT(mesh_volume(s.triangles), 2.0);
}

// airborne.plane_merge_distance: a wall 0.5 mm beside another, tilted 0.5 degrees
// (they cross inside the box), cuts wedges thinner than a validator's snap;
// with the merge it takes the first wall's plane and cuts nothing new, and a
// wall 0.2 m away (beyond the distance) or tilted 10 degrees (beyond the
// angle) still cuts.
TEST(Bsp, NearlyCoincidentSupportsMerged) {
  const Vec3 lo(0, 0, 0), hi(4, 4, 4);
  const std::vector<BspPolygon> base{rect(2, 1.0, 0, 4, 0, 4, 0), rect(0, 2.0, 0, 4, 0, 4, 1)};
  const auto wall_at = [&](double x, double tilt_deg) {
    const double t = std::tan(tilt_deg * M_PI / 180.0);
    BspPolygon w;  // x = at + t * (y - 2), over y in [0, 4], z in [0, 4]
    w.polygon = {Vec3(x - 2 * t, 0, 0), Vec3(x + 2 * t, 4, 0), Vec3(x + 2 * t, 4, 4),
                 Vec3(x - 2 * t, 0, 4)};
    const Vec3 n = Vec3(1, -t, 0).normalized();
    w.plane = {n.x(), n.y(), 0, -n.dot(Vec3(x, 2, 0))};
    w.primitive = 2;
    return w;
  };
  const citylod::lod::detail::PlaneMerge merge{0.05, 3 * M_PI / 180.0};
  const Bsp plain(lo, hi, base, 0, merge);
  EXPECT_EQ(plain.leaves().size(), 4u);
  std::vector<BspPolygon> near = base;
  near.push_back(wall_at(2.0005, 0.5));
  const Bsp exact(lo, hi, near, 0);
  EXPECT_EQ(exact.leaves().size(), 8u);  // the wedges on both sides of the crossing, both slabs
  const Bsp merged(lo, hi, near, 0, merge);
  EXPECT_EQ(merged.leaves().size(), 4u);
  EXPECT_EQ(merged.planes().size(), plain.planes().size());
  std::vector<BspPolygon> far = base, tilted = base;
  far.push_back(wall_at(2.2, 0.5));  // on the x > 2 side only: splits its 2 cells
  EXPECT_EQ(Bsp(lo, hi, far, 0, merge).leaves().size(), 6u);
  tilted.push_back(wall_at(2.0, 10.0));  // crosses x = 2 at y = 2: splits all 4
  EXPECT_EQ(Bsp(lo, hi, tilted, 0, merge).leaves().size(), 8u);
}

TEST(Bsp, CoplanarDuplicatesMerged) {
  const Vec3 lo(0, 0, 0), hi(4, 4, 4);
  std::vector<BspPolygon> one{rect(2, 1.0, 0.5, 2.5, 0.5, 2.5, 0), rect(0, 3.0, 0, 4, 0, 4, 1)};
  std::vector<BspPolygon> dup = one;
  BspPolygon d = rect(2, 1.0, 0.0, 3.0, 1.0, 2.0, 2);  // same plane, overlapping
  d.plane[3] += 1e-13;                                 // within the merge tolerance
  dup.insert(dup.begin() + 1, d);
  Bsp a(lo, hi, one, 0), b(lo, hi, dup, 0);
  EXPECT_EQ(a.planes().size(), 8u);
  EXPECT_EQ(b.planes().size(), 8u);  // the duplicate plane is merged
  EXPECT_EQ(a.leaves().size(), b.leaves().size());
  EXPECT_EQ(a.leaves().size(), 4u);
  // the duplicate's piece lies on the split plane: consumed, never splits
  for (const auto& n : b.nodes()) {
    if (!n.is_leaf()) {
      EXPECT_NE(n.split_primitive, 2);
    }
  }
}

namespace {

std::vector<BspPolygon> random_polygons(int n, unsigned seed, double L) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<BspPolygon> out;
  for (int i = 0; i < n; ++i) {
    if (i % 2 == 0) {
      const int axis = int(U(rng) * 3) % 3;
      // snap to a coarse grid so that coplanar / collinear coincidences happen
      auto g = [&]() { return std::round(U(rng) * 8) / 8 * L; };
      double a0 = g(), a1 = g(), b0 = g(), b1 = g();
      if (a0 > a1) std::swap(a0, a1);
      if (b0 > b1) std::swap(b0, b1);
      if (a1 - a0 < 0.1 * L) a1 = a0 + 0.25 * L;
      if (b1 - b0 < 0.1 * L) b1 = b0 + 0.25 * L;
      out.push_back(rect(axis, g(), a0, a1, b0, b1, i));
    } else {
      Vec3 n(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
      if (n.norm() < 1e-3) n = Vec3(1, 1, 1);
      n.normalize();
      const Vec3 c(U(rng) * L, U(rng) * L, U(rng) * L);
      const Vec3 a = n.unitOrthogonal(), b = n.cross(a);
      const double r = (0.2 + 0.5 * U(rng)) * L;
      const int k = 3 + int(U(rng) * 5);
      std::vector<Vec3> pts;
      for (int j = 0; j < k; ++j) {
        const double t = 2 * M_PI * j / k + 0.3 * U(rng);
        pts.push_back(c + r * (std::cos(t) * a + std::sin(t) * b));
      }
      BspPolygon p;
      p.polygon = pts;
      p.primitive = i;
      p.plane = {n.x(), n.y(), n.z(), -n.dot(c)};
      out.push_back(p);
    }
  }
  return out;
}

}  // namespace

TEST(Bsp, RandomStressClosedOrientedVolume) {
  const double L = 10;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    const auto polys = random_polygons(50, seed, L);
    const double t0 = now_s();
    Bsp bsp(Vec3(0, 0, 0), Vec3(L, L, L), polys, 0);
    const double t1 = now_s();
    const auto leaves = bsp.leaves();
    double total = 0;
    for (int l : leaves) total += bsp.nodes()[l].volume;
    EXPECT_NEAR(total, L * L * L, 1e-9 * L * L * L);
    std::mt19937 rng(seed * 77);
    std::vector<char> in(leaves.size());
    // half the seeds: random labels; the others: a blob (more realistic, fewer repairs)
    for (size_t i = 0; i < leaves.size(); ++i) {
      const Vec3 c = bsp.nodes()[leaves[i]].center;
      in[i] = (seed % 2) ? char(rng() % 2) : char((c - Vec3(5, 5, 5)).norm() < 3.5);
    }
    const double t2 = now_s();
    const BspSurface s = bsp.extract(leaves, in);
    const double t3 = now_s();
    std::printf(
        "[ stress %u ] %zu leaves in %.1f ms (%.0f leaves/s); extract %zu tris, %d regions, %d "
        "flipped in %.1f ms\n",
        seed, leaves.size(), 1e3 * (t1 - t0), leaves.size() / (t1 - t0),
        s.triangles.triangles.size(), s.merged_regions, s.labels_flipped, 1e3 * (t3 - t2));
    expect_good_surface(s, "stress");
    const double vin = sum_inside_volume(bsp, leaves, s.inside);
    EXPECT_NEAR(mesh_volume(s.triangles), vin, 1e-6 * std::max(1.0, vin)) << "seed " << seed;
    // random cut of the tree: some internal nodes
    if (seed == 2) {
      std::vector<int> cut;
      std::function<void(int)> rec = [&](int n) {
        const auto& N = bsp.nodes()[n];
        if (N.is_leaf() || N.depth >= 4) {
          cut.push_back(n);
          return;
        }
        rec(N.children[0]);
        rec(N.children[1]);
      };
      rec(0);
      std::vector<char> cin;
      for (int n : cut) cin.push_back((bsp.nodes()[n].center - Vec3(5, 5, 5)).norm() < 4);
      const BspSurface sc = bsp.extract(cut, cin);
      expect_good_surface(sc, "cut");
      EXPECT_NEAR(mesh_volume(sc.triangles), sum_inside_volume(bsp, cut, sc.inside),
                  1e-6 * L * L * L);
      double cv = 0;
      for (int n : cut) cv += bsp.nodes()[n].volume;
      EXPECT_NEAR(cv, L * L * L, 1e-9 * L * L * L);
    }
  }
}

TEST(Bsp, Deterministic) {
  const auto polys = random_polygons(40, 11, 10);
  Bsp a(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0), b(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    EXPECT_EQ(a.nodes()[i].children, b.nodes()[i].children);
    EXPECT_EQ(a.nodes()[i].split_plane, b.nodes()[i].split_plane);
    EXPECT_EQ(a.nodes()[i].volume, b.nodes()[i].volume);
  }
  const auto leaves = a.leaves();
  std::vector<char> in;
  for (int l : leaves) in.push_back((a.nodes()[l].center - Vec3(5, 5, 5)).norm() < 3);
  const auto sa = a.extract(leaves, in), sb = b.extract(leaves, in);
  EXPECT_EQ(sa.triangles.vertices, sb.triangles.vertices);
  EXPECT_EQ(sa.triangles.triangles, sb.triangles.triangles);
  EXPECT_EQ(sa.polygons.faces, sb.polygons.faces);
  const auto ia = a.adjacency(leaves), ib = b.adjacency(leaves);
  ASSERT_EQ(ia.size(), ib.size());
  for (size_t i = 0; i < ia.size(); ++i) {
    EXPECT_EQ(ia[i].a, ib[i].a);
    EXPECT_EQ(ia[i].b, ib[i].b);
    EXPECT_EQ(ia[i].area, ib[i].area);
  }
}

namespace {

// Building-like polygons: axis-aligned rectangles on a grid, gable roof pairs
// (two planes through a common ridge line, sometimes on the box boundary),
// tilted polygons, and near-duplicate planes (offset 1e-13, merged).
std::vector<BspPolygon> building_like(unsigned seed, int n, double L, int kind) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<BspPolygon> out;
  auto g = [&](int q) { return std::round(U(rng) * q) / q * L; };
  for (int i = 0; int(out.size()) < n; ++i) {
    const int t = kind == 0 ? i % 3 : int(U(rng) * 3);
    if (t == 0) {
      const int axis = int(U(rng) * 3) % 3;
      double a0 = g(6), a1 = g(6), b0 = g(6), b1 = g(6);
      if (a0 > a1) std::swap(a0, a1);
      if (b0 > b1) std::swap(b0, b1);
      if (a1 - a0 < 0.1 * L) a1 = a0 + 0.3 * L;
      if (b1 - b0 < 0.1 * L) b1 = b0 + 0.3 * L;
      out.push_back(rect(axis, g(6), a0, a1, b0, b1, i));
    } else if (t == 1) {
      const double xr = g(6), h = g(6), s = 0.5 + U(rng), y0 = g(6), y1 = y0 + 0.4 * L;
      for (int side : {-1, 1}) {
        Vec3 nrm(s * side, 0, 1);
        nrm.normalize();
        BspPolygon p;
        p.polygon = {Vec3(xr, y0, h), Vec3(xr + side * 0.3 * L, y0, h - s * 0.3 * L),
                     Vec3(xr + side * 0.3 * L, y1, h - s * 0.3 * L), Vec3(xr, y1, h)};
        p.primitive = i;
        p.plane = {nrm.x(), nrm.y(), nrm.z(), -nrm.dot(Vec3(xr, 0, h))};
        out.push_back(p);
      }
    } else {
      Vec3 nrm(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5);
      if (nrm.norm() < 1e-3) nrm = Vec3(1, 1, 1);
      nrm.normalize();
      const Vec3 c(g(4), g(4), g(4));
      const Vec3 a = nrm.unitOrthogonal(), b = nrm.cross(a);
      const double r = (0.2 + 0.5 * U(rng)) * L;
      const int k = 3 + int(U(rng) * 5);
      BspPolygon p;
      for (int j = 0; j < k; ++j) {
        const double tt = 2 * M_PI * j / k + 0.3 * U(rng);
        p.polygon.push_back(c + r * (std::cos(tt) * a + std::sin(tt) * b));
      }
      p.primitive = i;
      p.plane = {nrm.x(), nrm.y(), nrm.z(), -nrm.dot(c)};
      out.push_back(p);
      if (U(rng) < 0.2) {
        BspPolygon q = p;
        q.plane[3] += 1e-13;
        for (auto& v : q.polygon) v += 0.1 * a;
        out.push_back(q);
      }
    }
  }
  return out;
}

}  // namespace

TEST(Bsp, GableRidgeOnBoxFaceThenCut) {
  // regression: an edge lying on 3 planes (ridge on the box top face), its two
  // faces naming different edge planes; the cut by y = 5 must share the vertex
  const double s = 0.76970758677521134, c = 0.63839660937436082;
  BspPolygon r1, r2;
  r1.plane = {-s, 0, c, -5.1011201157849229};
  r1.polygon = {Vec3(1.6666666666666665, 1.6666666666666665, 10),
                Vec3(-1.3333333333333335, 1.6666666666666665, 6.3829338589554663),
                Vec3(-1.3333333333333335, 5.6666666666666661, 6.3829338589554663),
                Vec3(1.6666666666666665, 5.6666666666666661, 10)};
  r2.plane = {s, 0, c, -7.6668120717022941};
  r2.polygon = {Vec3(1.6666666666666665, 1.6666666666666665, 10),
                Vec3(4.6666666666666661, 1.6666666666666665, 6.3829338589554663),
                Vec3(4.6666666666666661, 5.6666666666666661, 6.3829338589554663),
                Vec3(1.6666666666666665, 5.6666666666666661, 10)};
  r1.primitive = r2.primitive = 1;
  std::vector<BspPolygon> polys{
      r1, r2,
      rect(1, 5, 1.6666666666666665, 8.3333333333333339, 1.6666666666666665, 3.333333333333333, 6)};
  Bsp bsp(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  const auto leaves = bsp.leaves();
  double total = 0;
  for (int l : leaves) total += bsp.nodes()[l].volume;
  EXPECT_NEAR(total, 1000.0, 1e-9);
  for (size_t i = 0; i < leaves.size(); ++i) {
    std::vector<char> in(leaves.size(), 0);
    in[i] = 1;
    const auto surf = bsp.extract(leaves, in);
    expect_good_surface(surf, "gable leaf");
    EXPECT_NEAR(mesh_volume(surf.triangles), bsp.nodes()[leaves[i]].volume, 1e-9);
  }
}

TEST(Bsp, BuildingLikeStress) {
  const double L = 10;
  int configs = 0;
  for (unsigned seed = 1; seed <= 12; ++seed)
    for (int kind = 0; kind < 2; ++kind)
      for (int lab = 0; lab < 2; ++lab) {
        const auto polys = building_like(seed * 3 + kind, 25, L, kind);
        Bsp bsp(Vec3(0, 0, 0), Vec3(L, L, L), polys, 0);
        const auto leaves = bsp.leaves();
        std::mt19937 rng(seed * 77 + lab);
        std::vector<char> in(leaves.size());
        for (size_t i = 0; i < leaves.size(); ++i) {
          const Vec3 c = bsp.nodes()[leaves[i]].center;
          in[i] = lab == 0 ? char(rng() % 2)
                           : char((c - Vec3(4, 5, 5)).norm() < 3.0 ||
                                  (c.z() < 4 && c.x() > 3 && c.y() > 2 && c.y() < 7));
        }
        const BspSurface surf = bsp.extract(leaves, in);
        const MeshReport r = check_mesh(surf.triangles);
        ASSERT_TRUE(r.closed && r.oriented && !r.degenerate)
            << "seed " << seed << " kind " << kind << " lab " << lab;
        ASSERT_TRUE(polygon_mesh_closed(surf.polygons))
            << "seed " << seed << " kind " << kind << " lab " << lab;
        // No pinched vertex (two in-cones meeting at a point) survives the repair.
        EXPECT_EQ(r.pinched, 0) << "seed " << seed << " kind " << kind << " lab " << lab;
        const double vin = sum_inside_volume(bsp, leaves, surf.inside);
        ASSERT_NEAR(mesh_volume(surf.triangles), vin, 1e-6 * std::max(1.0, vin)) << "seed " << seed;
        ++configs;
      }
  EXPECT_EQ(configs, 48);
}

TEST(Bsp, ConcurrentExtractFromOneBsp) {
  const auto polys = building_like(5, 30, 10, 0);
  const Bsp bsp(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  const auto leaves = bsp.leaves();
  std::vector<char> in;
  for (int l : leaves) in.push_back((bsp.nodes()[l].center - Vec3(5, 5, 5)).norm() < 3.5);
  const BspSurface ref = bsp.extract(leaves, in);
  std::vector<BspSurface> out(4);
  std::vector<std::thread> th;
  for (int t = 0; t < 4; ++t) th.emplace_back([&, t] { out[t] = bsp.extract(leaves, in); });
  for (auto& x : th) x.join();
  for (const auto& s : out) {
    EXPECT_EQ(s.triangles.vertices, ref.triangles.vertices);
    EXPECT_EQ(s.triangles.triangles, ref.triangles.triangles);
  }
}

// A sequence of extractions sharing an ExtractCache (as the LOD candidates
// do) gives exactly what fresh extractions give, whether consecutive labels
// differ by one cell, by many, or not at all.
TEST(Bsp, ExtractCacheGivesIdenticalSurfaces) {
  const auto polys = building_like(7, 30, 10, 0);
  const Bsp bsp(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  const auto leaves = bsp.leaves();
  std::vector<char> in;
  for (int l : leaves) in.push_back((bsp.nodes()[l].center - Vec3(5, 5, 5)).norm() < 3.0);
  ExtractCache cache;
  std::mt19937 rng(5);
  for (int step = 0; step < 8; ++step) {
    if (step == 3) {
      for (auto& x : in) x = char(rng() % 2);  // many cells change
    } else if (step != 5) {                    // step 5: nothing changes
      for (size_t i = 0; i < in.size(); ++i)
        if (!in[i]) {
          in[i] = 1;  // one more cell in
          break;
        }
    }
    const BspSurface fresh = bsp.extract(leaves, in);
    const BspSurface cached = bsp.extract(leaves, in, &cache);
    EXPECT_EQ(cached.triangles.vertices, fresh.triangles.vertices) << "step " << step;
    EXPECT_EQ(cached.triangles.triangles, fresh.triangles.triangles) << "step " << step;
    EXPECT_EQ(cached.polygons.faces, fresh.polygons.faces) << "step " << step;
    EXPECT_EQ(cached.inside, fresh.inside) << "step " << step;
    expect_good_surface(cached, "cached");
  }
}

// The exact side of a vertex (the point of three table planes) from integer
// determinants is CGAL's exact predicate on the exactly constructed point: for
// planes through the point (side 0), planes a few ulps off it, vertices of both
// signs of the determinant, and coefficients that are not short binary fractions.
TEST(Bsp, ExactSignOfVertexIsCgals) {
  using citylod::lod::detail::bspi::BspData;
  using K = citylod::lod::detail::bspi::K;
  BspData D;
  auto add = [&](std::array<double, 4> c) {
    D.dplanes.push_back(c);
    D.planes.emplace_back(K::FT(c[0]), K::FT(c[1]), K::FT(c[2]), K::FT(c[3]));
    return int(D.dplanes.size()) - 1;
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  auto unit = [&](double d) {
    Vec3 n(U(rng), U(rng), U(rng));
    n.normalize();
    return std::array<double, 4>{n.x(), n.y(), n.z(), d};
  };
  int zeros = 0, pos = 0, neg = 0;
  for (int t = 0; t < 200; ++t) {
    const std::array<int, 3> def{add(unit(U(rng) * 30)), add(unit(U(rng) * 30)),
                                 add(unit(U(rng) * 30))};
    const auto res = CGAL::intersection(D.planes[def[0]], D.planes[def[1]], D.planes[def[2]]);
    const K::Point_3* p = res ? boost::get<K::Point_3>(&*res) : nullptr;
    ASSERT_NE(p, nullptr);
    // a plane through the point, exactly (a box plane through a rational
    // coordinate cannot be written in doubles; a plane through a vertex of the
    // three is: the first plane itself, reversed, and the sum of two)
    std::vector<int> tests{def[0]};
    const auto& c0 = D.dplanes[def[0]];
    tests.push_back(add({-c0[0], -c0[1], -c0[2], -c0[3]}));
    // planes near the point: its double approximation with offsets of a few ulps
    const double x = CGAL::to_double(p->x()), y = CGAL::to_double(p->y()),
                 z = CGAL::to_double(p->z());
    auto ulps = [](double v, int k) {
      for (; k > 0; --k) v = std::nextafter(v, 1e300);
      for (; k < 0; ++k) v = std::nextafter(v, -1e300);
      return v;
    };
    for (int k = -2; k <= 2; ++k) {
      tests.push_back(add({0.6, 0.0, 0.8, ulps(-(0.6 * x + 0.8 * z), k)}));
      tests.push_back(add({0.0, 1.0, 0.0, ulps(-y, k)}));
      tests.push_back(add(unit(U(rng) * 30)));
    }
    for (int P : tests) {
      const int want = int(D.planes[P].oriented_side(*p));
      EXPECT_EQ(D.exact_sign_of(def, P), want) << "trial " << t << " plane " << P;
      zeros += want == 0;
      pos += want > 0;
      neg += want < 0;
    }
  }
  EXPECT_GE(zeros, 400);  // the defining plane and its reverse in every trial
  EXPECT_GT(pos, 1000);
  EXPECT_GT(neg, 1000);
}
