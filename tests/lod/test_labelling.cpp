// Tests of the ray labelling: the BVH gives CGAL's AABB_tree::first_intersection
// decisions (the reference below is the labeller as it was before the BVH).
#include "labelling.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using citylod::lod::Vec3;
using citylod::lod::detail::LevelTriangles;
using citylod::lod::detail::RayLabeller;

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using TriIter = std::vector<Triangle>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, TriIter>>>;

// the labeller's directions (labelling.cpp: sphere_directions)
std::vector<Vec3> directions(int n) {
  std::vector<Vec3> dirs;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  const double ct = std::cos(0.1234), st = std::sin(0.1234);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i + 0.0371;
    Vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    d = Vec3(d.x(), ct * d.y() - st * d.z(), st * d.y() + ct * d.z());
    d = Vec3(ct * d.x() + st * d.z(), d.y(), -st * d.x() + ct * d.z());
    dirs.push_back(d.normalized());
  }
  return dirs;
}

// the labels by CGAL's AABB tree (first hit per level, grazing triangles looked through)
std::vector<std::vector<char>> reference(const LevelTriangles& in, int rays,
                                         const std::vector<Vec3>& centres, int L) {
  std::vector<Triangle> tris;
  std::vector<Vec3> normals;
  std::vector<int> level;
  for (size_t i = 0; i < in.triangles.size(); ++i) {
    const auto& t = in.triangles[i];
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
    if (!(n.norm() > 1e-12)) continue;
    tris.emplace_back(Point(t[0].x(), t[0].y(), t[0].z()), Point(t[1].x(), t[1].y(), t[1].z()),
                      Point(t[2].x(), t[2].y(), t[2].z()));
    normals.push_back(n.normalized());
    level.push_back(in.level[i]);
  }
  Tree tree(tris.cbegin(), tris.cend());
  const auto dirs = directions(rays);
  std::vector<std::vector<char>> out;
  for (const auto& o : centres) {
    std::vector<int> votes(size_t(L), 0);
    for (const auto& u : dirs) {
      const K::Ray_3 ray(Point(o.x(), o.y(), o.z()), K::Vector_3(u.x(), u.y(), u.z()));
      int bound = L;
      std::vector<int> grazing;
      while (bound > 0) {
        const auto skip = [&](TriIter it) {
          const int id = int(it - tris.cbegin());
          return level[size_t(id)] >= bound ||
                 std::find(grazing.begin(), grazing.end(), id) != grazing.end();
        };
        const auto hit = tree.first_intersection(ray, skip);
        if (!hit) break;
        const int id = int(hit->second - tris.cbegin());
        if (!boost::get<Point>(&hit->first)) {
          grazing.push_back(id);
          continue;
        }
        const int lv = level[size_t(id)];
        for (int k = lv; k < bound; ++k) votes[size_t(k)] += normals[size_t(id)].dot(u) > 0 ? 1 : 0;
        bound = lv;
      }
    }
    std::vector<char> l(static_cast<size_t>(L));
    for (int k = 0; k < L; ++k) l[size_t(k)] = 2 * votes[size_t(k)] > rays ? 1 : 0;
    out.push_back(l);
  }
  return out;
}

// the 12 triangles of a box, CCW seen from outside
void add_box(LevelTriangles& t, const Vec3& lo, const Vec3& hi, int level) {
  const auto c = [&](int i) {
    return Vec3(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  };
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    t.triangles.push_back({c(q[0]), c(q[1]), c(q[2])});
    t.triangles.push_back({c(q[0]), c(q[2]), c(q[3])});
    t.level.push_back(level);
    t.level.push_back(level);
  }
}

}  // namespace

TEST(RayLabeller, BoxesInsideOutsideExactly) {
  LevelTriangles t;
  add_box(t, Vec3(0, 0, 0), Vec3(4, 3, 2), 0);
  const RayLabeller lab(t, 100);
  const auto l =
      lab.label(std::vector<Vec3>{Vec3(2, 1.5, 1), Vec3(6, 1.5, 1), Vec3(2, 1.5, -3)}, 1, 1);
  ASSERT_EQ(l.size(), 3u);
  EXPECT_EQ(l[0][0], 1);
  EXPECT_EQ(l[1][0], 0);
  EXPECT_EQ(l[2][0], 0);
  // every ray from the centre hits the box from inside; none from below hits it facing away
  const auto up = lab.half_space_votes(Vec3(2, 1.5, 1), Vec3(0, 0, 1));
  EXPECT_EQ(up.first, up.second);
  EXPECT_GT(up.second, 0);
  const auto below = lab.half_space_votes(Vec3(2, 1.5, -3), Vec3(0, 0, 1));
  EXPECT_EQ(below.first, 0);
}

TEST(RayLabeller, SameLabelsAsCgalAabbTree) {
  // two levels of boxes sharing face planes, plus random triangles; origins on
  // a grid that puts many of them exactly on the shared planes and edges
  LevelTriangles t;
  add_box(t, Vec3(0, 0, 0), Vec3(4, 3, 2), 0);
  add_box(t, Vec3(1, 1, 2), Vec3(3, 3, 3), 1);
  add_box(t, Vec3(4, 0, 0), Vec3(5, 1, 1), 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 6.0);
  for (int i = 0; i < 300; ++i) {
    const Vec3 a(U(rng), U(rng), U(rng) * 0.5);
    const Vec3 b = a + Vec3(U(rng), U(rng), U(rng)) * 0.2;
    const Vec3 c = a + Vec3(U(rng), U(rng), U(rng)) * 0.2;
    t.triangles.push_back({a, b, c});
    t.level.push_back(i % 2);
  }
  t.triangles.push_back({Vec3(1, 1, 1), Vec3(2, 2, 2), Vec3(3, 3, 3)});  // degenerate: dropped
  t.level.push_back(0);
  std::vector<Vec3> centres;
  for (double x = -0.5; x <= 5.5; x += 0.5)
    for (double y = -0.5; y <= 3.5; y += 0.5)
      for (double z = -0.5; z <= 3.5; z += 0.5) centres.emplace_back(x, y, z);
  const int rays = 60;
  const RayLabeller lab(t, rays);
  const auto want = reference(t, rays, centres, 2);
  for (int threads : {1, 2}) {
    const auto got = lab.label(centres, 2, threads);
    ASSERT_EQ(got.size(), want.size());
    int in = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i], want[i]) << "cell " << i << " at " << centres[i].transpose();
      in += got[i][1];
    }
    EXPECT_GT(in, 20);  // the scene has inside cells at both levels
  }
}
