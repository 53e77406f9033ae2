// lod::check_solid: a solid as val3dity judges it at its default tolerances
// (snap 1 mm, planarity 1 cm / 20 degrees), on solids with exact answers.
#include "citylod/lod/validity.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace citylod::lod {
namespace {

/// Unit-ish box [0,a]x[0,b]x[0,c]: 6 outward quads (corner i: x if i&1, y if i&2, z if i&4).
PolygonSolid box(double a = 10, double b = 8, double c = 6) {
  PolygonSolid s;
  for (int i = 0; i < 8; ++i)
    s.vertices.emplace_back((i & 1) ? a : 0, (i & 2) ? b : 0, (i & 4) ? c : 0);
  s.shells = {{{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}};
  return s;
}

TEST(Validity, ABoxIsValid) {
  const SolidCheck c = check_solid(box());
  EXPECT_TRUE(c.valid()) << c.error << " " << c.detail;
  EXPECT_DOUBLE_EQ(min_vertex_distance(box()), 6.0);
}

TEST(Validity, InsideOutIsWrongOrientation) {
  PolygonSolid s = box();
  for (auto& f : s.shells[0]) std::reverse(f.begin(), f.end());
  EXPECT_EQ(check_solid(s).error, 307);
}

TEST(Validity, AMissingFaceIsNotClosed) {
  PolygonSolid s = box();
  s.shells[0].pop_back();
  EXPECT_EQ(check_solid(s).error, 302);
  s.shells[0].resize(3);
  EXPECT_EQ(check_solid(s).error, 301);
}

TEST(Validity, TwoBoxesInOneShellAreTwoComponents) {
  PolygonSolid s = box();
  const PolygonSolid b = box();
  for (const auto& v : b.vertices) s.vertices.push_back(v + Vec3(20, 0, 0));
  for (auto f : b.shells[0]) {
    for (int& i : f) i += 8;
    s.shells[0].push_back(f);
  }
  EXPECT_EQ(check_solid(s).error, 305);
}

// A T-junction vertex 0.3 mm from a corner, on the top face's edge and on the
// wall's: exactly closed, but the validator snaps it onto the corner and the
// two rings repeat a point.
TEST(Validity, VerticesWithinTheSnapToleranceRepeatAPoint) {
  PolygonSolid s = box();
  s.vertices.emplace_back(0, 8 - 0.0003, 6);  // 8: on edge 6 (0,8,6) - 4 (0,0,6)
  s.shells[0][1] = {4, 5, 7, 6, 8};           // top
  s.shells[0][4] = {0, 4, 8, 6, 2};           // west wall (x = 0)
  const SolidCheck c = check_solid(s);
  EXPECT_EQ(c.error, 102);
  EXPECT_EQ(c.face, 1);
  EXPECT_NEAR(min_vertex_distance(s), 0.0003, 1e-12);
  // 1.5 mm away it is a vertex of its own
  s.vertices[8] = Vec3(0, 8 - 0.0015, 6);
  EXPECT_TRUE(check_solid(s).valid()) << check_solid(s).detail;
  // a tolerance of 2 mm snaps it again
  Tolerances t;
  t.snap = 0.002;
  EXPECT_EQ(check_solid(s, t).error, 102);
}

// Snapping also closes: a corner split in two copies 0.5 mm apart (each face
// uses one) is one vertex to the validator.
TEST(Validity, ASubMillimetreGapIsClosedBySnapping) {
  PolygonSolid s = box();
  s.vertices.push_back(s.vertices[7] + Vec3(0.0005, 0, 0));  // 8: a copy of corner 7
  s.shells[0][5] = {1, 3, 8, 5};                             // east wall uses the copy
  EXPECT_TRUE(check_solid(s).valid()) << check_solid(s).detail;
  Tolerances exact;
  exact.snap = 0;
  EXPECT_EQ(check_solid(s, exact).error, 302);
}

TEST(Validity, ANonPlanarFace) {
  PolygonSolid s = box();
  s.vertices[7] += Vec3(0, 0, 0.1);  // the top's corner 10 cm up: 2.5 cm off its plane
  const SolidCheck c = check_solid(s);
  EXPECT_EQ(c.error, 203);
  EXPECT_EQ(c.face, 1);
  s = box();
  s.vertices[7] += Vec3(0, 0, 0.02);  // 5 mm off the fitted plane: within 1 cm
  EXPECT_NE(check_solid(s).error, 203);
}

// A face within 1 cm of its plane whose triangulation folds: a 1 m x 1 cm
// strip with one corner 8 mm up (its triangles' normals ~39 degrees apart).
TEST(Validity, AFoldIsNonPlanarByNormals) {
  PolygonSolid s;
  s.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 0.01, 0), Vec3(0, 0.01, 0.008)};
  s.shells = {{{0, 1, 2, 3}, {0, 1, 2}, {0, 2, 3}, {1, 2, 3}}};
  const SolidCheck c = check_solid(s);
  EXPECT_EQ(c.error, 204) << c.detail;
  EXPECT_EQ(c.face, 0);
  Tolerances loose;
  loose.planarity_normals_deg = 45;
  EXPECT_NE(check_solid(s, loose).error, 204);
}

TEST(Validity, ASelfIntersectingRingAndACollapsedTriangle) {
  PolygonSolid s = box();
  s.shells[0][1] = {4, 5, 6, 7};  // top as a bowtie
  EXPECT_EQ(check_solid(s).error, 104);
  s = box();
  s.vertices.emplace_back(5, 0, 0);  // 8: on the edge 0-1
  s.shells[0].push_back({0, 8, 1});  // a triangle on a line
  EXPECT_EQ(check_solid(s).error, 104);
  s.shells[0].back() = {0, 1, 0};  // repeats a point
  EXPECT_EQ(check_solid(s).error, 102);
  s.shells[0].back() = {0, 1};
  EXPECT_EQ(check_solid(s).error, 101);
}

}  // namespace
}  // namespace citylod::lod
