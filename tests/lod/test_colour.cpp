// (ours) Input colours onto the models' faces: exact answers on planar faces.
#include "support/synthetic.hpp"

#include "citylod/lod/lod.hpp"
#include "colour.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace citylod;
using namespace citylod::lod;

namespace {

const Rgba8 kNone{0, 0, 0, 0};

/// Two coplanar roof squares sharing an edge (x 0..2 and 2..4, z = 3), a
/// separate roof square at z = 3 (x 6..8: same plane, no shared edge) and a
/// wall square (x = 0, y 0..2, z 0..2), as four faces.
struct Faces {
  std::vector<Vec3> v{{0, 0, 3}, {2, 0, 3}, {2, 2, 3}, {0, 2, 3}, {4, 0, 3}, {4, 2, 3}, {6, 0, 3},
                      {8, 0, 3}, {8, 2, 3}, {6, 2, 3}, {0, 0, 0}, {0, 2, 0}, {0, 2, 2}, {0, 0, 2}};
  std::vector<std::vector<int>> f{{0, 1, 2, 3}, {1, 4, 5, 2}, {6, 7, 8, 9}, {10, 13, 12, 11}};
};

/// Points with normals and colours.
struct Cloud {
  std::vector<Vec3> points, normals;
  std::vector<Rgb8> colors;
  std::vector<Rgba8> faces(const std::vector<Vec3>& v, const std::vector<std::vector<int>>& f,
                           const ColourParams& p = {}) const {
    return detail::ColourSource(points, normals, colors, p).faces(v, f);
  }
};

void add(Cloud& in, const Vec3& p, const Rgb8& c, const Vec3& n = Vec3::UnitZ()) {
  in.points.push_back(p);
  in.normals.push_back(n);
  in.colors.push_back(c);
}

}  // namespace

TEST(Colour, PlaneRegionGetsTheMedianOfItsPoints) {
  Cloud in;
  // five points on the first roof square: median per channel (10..250 -> 30)
  const std::uint8_t r[] = {10, 250, 30, 20, 40};
  for (int i = 0; i < 5; ++i) add(in, Vec3(0.3 + 0.3 * i, 1.0, 3.05), {r[i], 0, 200});
  // three points on the separate square: fewer than min_points -> no colour
  for (int i = 0; i < 3; ++i) add(in, Vec3(7.0, 0.5 + 0.5 * i, 3.0), {0, 255, 0});
  // six points on the wall, one too far from its plane (not counted)
  for (int i = 0; i < 6; ++i) add(in, Vec3(0.02, 0.3 * (i + 1), 1.0), {0, 0, 255}, -Vec3::UnitX());
  add(in, Vec3(0.5, 1.0, 1.0), {255, 255, 255}, -Vec3::UnitX());
  ColourParams p;
  p.distance = 0.15;
  const Faces F;
  const std::vector<Rgba8> c = in.faces(F.v, F.f, p);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c[0], (Rgba8{30, 0, 200, 255}));
  EXPECT_EQ(c[1], (Rgba8{30, 0, 200, 255}));  // same region: shares the edge, no points of its own
  EXPECT_EQ(c[2], kNone);                     // same plane but no shared edge, 3 points
  EXPECT_EQ(c[3], (Rgba8{0, 0, 255, 255}));   // the far white point is not counted

  ColourParams three = p;
  three.min_points = 3;
  EXPECT_EQ(in.faces(F.v, F.f, three)[2], (Rgba8{0, 255, 0, 255}));
}

TEST(Colour, NearestPlaneTakesAPointBothFacesHold) {
  Cloud in;
  // near the roof/wall corner line x = 0, z = 2 of a box: within 0.15 m of
  // both planes, inside both polygons, normals of neither; the nearer plane
  // takes each point
  const std::vector<Vec3> v{{0, 0, 2}, {2, 0, 2}, {2, 2, 2}, {0, 2, 2},
                            {0, 0, 0}, {0, 2, 0}, {0, 2, 2}, {0, 0, 2}};
  const std::vector<std::vector<int>> f{{0, 1, 2, 3}, {4, 7, 6, 5}};
  const Vec3 diagonal = Vec3(-1, 0, 1).normalized();
  for (int i = 0; i < 5; ++i) add(in, Vec3(0.10, 0.2 + 0.3 * i, 1.97), {255, 0, 0}, diagonal);
  for (int i = 0; i < 5; ++i) add(in, Vec3(0.02, 0.2 + 0.3 * i, 1.90), {0, 0, 255}, diagonal);
  const std::vector<Rgba8> c = in.faces(v, f);
  EXPECT_EQ(c[0], (Rgba8{255, 0, 0, 255}));
  EXPECT_EQ(c[1], (Rgba8{0, 0, 255, 255}));
}

TEST(Colour, AFaceTakesOnlyPointsWhoseNormalsAgree) {
  // a 2 x 2 m wall (x = 0) and a strip of 8 points along its top, 0.05 m in
  // front of it: a roof edge's returns (normals up) are not the wall's
  // (nearest face, but 90 degrees off); points facing -x are
  const std::vector<Vec3> v{{0, 0, 0}, {0, 2, 0}, {0, 2, 2}, {0, 0, 2}};
  const std::vector<std::vector<int>> f{{0, 3, 2, 1}};
  Cloud up, side, back;
  for (int i = 0; i < 8; ++i) {
    add(up, Vec3(-0.05, 0.125 + 0.25 * i, 1.9), {0, 0, 255});
    add(side, Vec3(-0.05, 0.125 + 0.25 * i, 1.9), {0, 0, 255}, -Vec3::UnitX());
    add(back, Vec3(-0.05, 0.125 + 0.25 * i, 1.9), {0, 0, 255}, Vec3::UnitX());
  }
  EXPECT_EQ(up.faces(v, f)[0], kNone);
  EXPECT_EQ(side.faces(v, f)[0], (Rgba8{0, 0, 255, 255}));
  EXPECT_EQ(back.faces(v, f)[0], kNone);  // facing the other way (the inside of a wall)
  ColourParams any;
  any.max_angle_deg = 90;
  EXPECT_EQ(up.faces(v, f, any)[0], (Rgba8{0, 0, 255, 255}));
}

TEST(Colour, NoColoursNoOutput) {
  Cloud in;
  in.points = {Vec3(0.5, 0.5, 3)};
  in.normals = {Vec3::UnitZ()};
  EXPECT_TRUE(detail::ColourSource(in.points, in.normals, in.colors, {}).empty());
  ColourParams off;
  off.enabled = false;
  in.colors = {{1, 2, 3}};
  EXPECT_FALSE(detail::ColourSource(in.points, in.normals, in.colors, {}).empty());
  EXPECT_TRUE(detail::ColourSource(in.points, in.normals, in.colors, off).empty());
}

/// A two-level flat-roofed building as airborne LiDAR sees it (roofs only:
/// main part x 0..12 at z = 8 in red, annex x 12..20 at z = 4 in green): the
/// finest model's roofs take their own colour, polygons and triangles alike,
/// walls (no points) none; no model has a face of the wrong colour.
TEST(Colour, PipelineColoursEachRoofLevel) {
  std::vector<test::Face> f;
  test::add_box(f, Vec3(0, 0, 0), Vec3(12, 10, 8), 1 | 2 | 4 | 8 | 16);
  test::add_box(f, Vec3(12, 0, 0), Vec3(20, 10, 4), 1 | 2 | 4 | 8 | 16);
  test::SynthOptions o;
  o.spacing = 0.3;
  test::SynthBuilding b = test::finish(std::move(f), 1280.0, 2, o, false);
  b.input.footprint = {Vec2(0, 0), Vec2(20, 0), Vec2(20, 10), Vec2(0, 10)};
  b.input.ground_z = 0.0;
  b.input.has_ground_z = true;
  LodParams p;
  p.metrics.samples = 2000;
  p.closure.footprint_walls = true;
  p.closure.terrain = Terrain::Cut;
  const LodResult plain = build_lod_tree(b.input, p);
  ASSERT_EQ(plain.status, lod::Status::ok) << plain.reason;
  for (const auto& m : plain.models) {
    EXPECT_TRUE(m.polygon_colours.empty());
    EXPECT_TRUE(m.triangle_colours.empty());
  }
  const Rgba8 red{200, 40, 30, 255}, green{20, 160, 40, 255};
  for (const Vec3& q : b.input.points)
    b.input.colors.push_back(q.z() > 6 ? Rgb8{200, 40, 30} : Rgb8{20, 160, 40});
  const LodResult r = build_lod_tree(b.input, p);
  ASSERT_EQ(r.models.size(), plain.models.size());
  // expected colour of a face: by its plane (a roof near 8 or 4), else none
  auto expected = [&](const std::vector<Vec3>& v, const std::vector<int>& face) {
    Vec3 n = Vec3::Zero();
    for (size_t k = 0; k < face.size(); ++k)
      n += v[size_t(face[k])].cross(v[size_t(face[(k + 1) % face.size()])]);
    const double z = v[size_t(face[0])].z();
    if (n.normalized().z() < 0.99) return kNone;
    // (a coarse model's roof within colour.distance = 1 m of a level takes its colour)
    return std::fabs(z - 8) <= 1 ? red : std::fabs(z - 4) <= 1 ? green : kNone;
  };
  for (const auto& m : r.models) {
    SCOPED_TRACE("model " + std::to_string(m.step));
    ASSERT_EQ(m.polygon_colours.size(), m.polygons.faces.size());
    ASSERT_EQ(m.triangle_colours.size(), m.mesh.triangles.size());
    const bool finest = &m == &r.models.back();
    for (size_t i = 0; i < m.mesh.triangles.size(); ++i) {
      const auto& t = m.mesh.triangles[i];
      const Rgba8 e = expected(m.mesh.vertices, {t[0], t[1], t[2]});
      if (finest || m.triangle_colours[i][3]) {
        EXPECT_EQ(m.triangle_colours[i], e) << "triangle " << i;
      }
    }
    for (size_t i = 0; i < m.polygons.faces.size(); ++i) {
      const Rgba8 e = expected(m.polygons.vertices, m.polygons.faces[i]);
      if (finest || m.polygon_colours[i][3]) {
        EXPECT_EQ(m.polygon_colours[i], e) << "polygon " << i;
      }
    }
  }
  const auto& fin = r.models.back();
  EXPECT_NE(std::find(fin.polygon_colours.begin(), fin.polygon_colours.end(), red),
            fin.polygon_colours.end());
  EXPECT_NE(std::find(fin.polygon_colours.begin(), fin.polygon_colours.end(), green),
            fin.polygon_colours.end());
}
