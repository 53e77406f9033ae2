// End-to-end tests of the LOD-Tree method on synthetic buildings with exact answers.
#include "support/lod_models.hpp"
#include "support/synthetic.hpp"

#include "citylod/lod/lod.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace citylod;
using namespace citylod::lod;
using citylod::test::SynthOptions;

namespace {

using test::first_anchor;
using test::has_note;
using test::last_anchor;
int count(const LodResult& r, ModelKind k) {
  return test::count_models(r, k);
}

/// Every model closed, oriented, edge-manifold, without self-intersections;
/// face counts non-decreasing along the candidate set.
void expect_valid_models(const LodResult& r) {
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  ASSERT_FALSE(r.models.empty());
  size_t last_faces = 0;
  for (const auto& m : r.models) {
    SCOPED_TRACE("model step " + std::to_string(m.step) + " " + to_string(m.kind));
    test::expect_closed_solid(m);
    EXPECT_GE(m.polygons.faces.size(), last_faces);
    last_faces = m.polygons.faces.size();
  }
}

LodParams fast_params() {
  LodParams p;
  p.metrics.samples = 4000;
  return p;
}

}  // namespace

TEST(LodPipeline, BoxIsOnePrincipalStructure) {
  const auto b = test::box(Vec3(0, 0, 0), Vec3(10, 6, 4));
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(r.stats.planes_detected, 6);
  EXPECT_EQ(r.stats.principal, 6);
  EXPECT_EQ(r.stats.level_sets, 0);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
  EXPECT_EQ(last_anchor(r)->polygons.faces.size(), 6u);
  EXPECT_EQ(last_anchor(r)->mesh.triangles.size(), 12u);
  EXPECT_LT(last_anchor(r)->e2, 0.5);
}

TEST(LodPipeline, ChimneyAndWindowsAreSecondary) {
  const auto b = test::chimney_windows();
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(r.stats.principal, 6);
  EXPECT_EQ(r.stats.add_ons, 1);
  EXPECT_EQ(r.stats.cut_outs, 4);
  // chimney (2 m^3) and windows (0.54 m^3) are within a factor 4 (ln 4 on ln V): one level set
  EXPECT_EQ(r.stats.level_sets, 1);
  EXPECT_GE(count(r, ModelKind::anchor), 2);
  const LodModel* coarse = first_anchor(r);
  const LodModel* fine = last_anchor(r);
  ASSERT_TRUE(coarse && fine && coarse != fine);
  // first anchor: the main body only (a box: 6 polygons, the box volume)
  using S = test::ChimneyWindowsSpec;
  EXPECT_EQ(coarse->polygons.faces.size(), 6u);
  EXPECT_NEAR(coarse->volume, S::L * S::W * S::H, 0.01 * S::L * S::W * S::H);
  // finest anchor: with the chimney and the windows
  EXPECT_NEAR(fine->volume, b.volume, 0.01 * b.volume);
  EXPECT_GT(fine->polygons.faces.size(), 6u + 4u + 4u * 5u);
}

TEST(LodPipeline, LShapeIsClosedWithExactVolume) {
  const auto b = test::l_shape();
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(r.stats.principal, 8);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
  EXPECT_EQ(last_anchor(r)->polygons.faces.size(), 8u);
}

TEST(LodPipeline, GableRoofWithDormer) {
  const auto b = test::gable_dormer();
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(r.stats.principal, 7);  // 4 walls + floor + 2 roof planes
  EXPECT_EQ(r.stats.add_ons, 1);
  EXPECT_GE(count(r, ModelKind::anchor), 2);
  EXPECT_NEAR(first_anchor(r)->volume, b.volume - 3 * 0.5 * (3.0 - 1.0) * 1.5, 0.02 * b.volume);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
}

TEST(LodPipeline, MeshInputGivesTheSameAnchors) {
  SynthOptions o;
  o.refine_levels = 3;  // region growing needs enough faces on the small window planes
  const auto b = test::chimney_windows(o, /*mesh=*/true);
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_GE(count(r, ModelKind::anchor), 2);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
}

TEST(LodPipeline, RobustToNoise) {
  SynthOptions o;
  o.noise_sigma = 0.1;
  o.seed = 7;
  const auto clean = build_lod_tree(test::chimney_windows().input, fast_params());
  const auto b = test::chimney_windows(o);
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(count(r, ModelKind::anchor), count(clean, ModelKind::anchor));
  EXPECT_EQ(first_anchor(r)->polygons.faces.size(), first_anchor(clean)->polygons.faces.size());
  EXPECT_NEAR(first_anchor(r)->volume, first_anchor(clean)->volume,
              0.02 * first_anchor(clean)->volume);
}

TEST(LodPipeline, NormalsEstimatedWhenMissing) {
  SynthOptions o;
  o.with_normals = false;
  const auto b = test::l_shape(o);
  const LodResult r = build_lod_tree(b.input, fast_params());
  EXPECT_TRUE(r.stats.normals_estimated);
  expect_valid_models(r);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
}

TEST(LodPipeline, RoofOnlyLidarIsClosedByInferredWalls) {
  const auto b = test::roof_only_box(Vec3(0, 0, 0), Vec3(12, 8, 6));
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_TRUE(r.stats.walls_inferred);
  EXPECT_NEAR(last_anchor(r)->volume, 12 * 8 * 6, 0.05 * 12 * 8 * 6);
}

TEST(LodPipeline, DeterministicWhateverTheThreadCount) {
  const auto b = test::chimney_windows();
  const LodParams p = fast_params();
  LodExecution two;
  two.threads = 2;
  const LodResult a = build_lod_tree(b.input, p);
  const LodResult c = build_lod_tree(b.input, p);
  const LodResult d = build_lod_tree(b.input, p, two);
  for (const LodResult* other : {&c, &d}) {
    ASSERT_EQ(a.models.size(), other->models.size());
    for (size_t i = 0; i < a.models.size(); ++i) {
      EXPECT_EQ(a.models[i].mesh.vertices, other->models[i].mesh.vertices);
      EXPECT_EQ(a.models[i].mesh.triangles, other->models[i].mesh.triangles);
      EXPECT_EQ(a.models[i].polygons.faces, other->models[i].polygons.faces);
    }
  }
}

TEST(LodPipeline, BadInputFailsCleanlyOrFallsBack) {
  BuildingInput empty;
  EXPECT_THROW(build_lod_tree(empty, fast_params()), LodError);

  BuildingInput nan;
  nan.points = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(NAN, 1, 0)};
  EXPECT_THROW(build_lod_tree(nan, fast_params()), LodError);

  BuildingInput few;  // fewer than 15 points: fallback box
  for (int i = 0; i < 10; ++i) few.points.emplace_back(i % 3, i / 3, (i * 7) % 4);
  const LodResult r1 = build_lod_tree(few, fast_params());
  EXPECT_EQ(r1.status, lod::Status::fallback);
  ASSERT_EQ(r1.models.size(), 1u);
  EXPECT_TRUE(check_mesh(r1.models[0].mesh).closed);

  BuildingInput single_plane;  // one plane: fallback, never a crash
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) single_plane.points.emplace_back(i * 0.2, j * 0.2, 3.0);
  const LodResult r2 = build_lod_tree(single_plane, fast_params());
  EXPECT_FALSE(r2.models.empty());
  for (const auto& m : r2.models) EXPECT_TRUE(check_mesh(m.mesh).closed);

  BuildingInput collinear;  // no area in plan view: a clear error
  for (int i = 0; i < 100; ++i) collinear.points.emplace_back(i * 0.1, 0, 0);
  EXPECT_THROW(build_lod_tree(collinear, fast_params()), LodError);
}

TEST(LodPipeline, TimeBudgetGivesARecordedFallback) {
  LodParams p = fast_params();
  p.budget.time_budget_s = 1e-6;
  const LodResult r = build_lod_tree(test::chimney_windows().input, p);
  EXPECT_EQ(r.status, lod::Status::fallback);
  EXPECT_NE(r.reason.find("budget"), std::string::npos) << r.reason;
  ASSERT_EQ(r.models.size(), 1u);
  EXPECT_TRUE(check_mesh(r.models[0].mesh).closed);
}

// Cancelling (the progress callback returns false) stops the building with
// LodCancelled from the stage it was in: no fallback model is made first.
TEST(LodPipeline, CancelThrowsFromTheStageWithoutAFallback) {
  struct Seen {
    std::vector<std::string> stages;
  } seen;
  const ProgressFn stop_at_traversal = [](double, const char* stage, void* user) {
    static_cast<Seen*>(user)->stages.push_back(stage);
    return std::string(stage) != "traversal";
  };
  try {
    build_lod_tree(test::chimney_windows().input, fast_params(), {1, stop_at_traversal, &seen});
    ADD_FAILURE() << "a cancelled building returned a result";
  } catch (const LodCancelled& e) {
    EXPECT_EQ(e.stage(), "traversal");
    EXPECT_NE(std::string(e.what()).find("cancelled"), std::string::npos) << e.what();
  }
  ASSERT_FALSE(seen.stages.empty());
  EXPECT_EQ(seen.stages.back(), "traversal");  // nothing ran after the cancel (no metrics)
  // A callback that never cancels changes nothing.
  const ProgressFn go_on = [](double, const char*, void*) { return true; };
  const LodResult r =
      build_lod_tree(test::chimney_windows().input, fast_params(), {1, go_on, nullptr});
  EXPECT_EQ(r.status, lod::Status::ok) << r.reason;
}

// A wall whose input normals point into the building (as on patches of real
// scans) is turned round before IO-View; the model is the box.
TEST(LodPipeline, WallWithInwardNormalsIsTurnedRound) {
  const Vec3 lo(0, 0, 0), hi(10, 6, 4);
  auto b = test::box(lo, hi);
  int flipped = 0;
  for (size_t i = 0; i < b.input.points.size(); ++i)
    if (std::abs(b.input.points[i].x() - hi.x()) < 1e-9) {
      b.input.normals[i] = -b.input.normals[i];
      ++flipped;
    }
  ASSERT_GT(flipped, 100);
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_EQ(r.stats.planes_turned, 1);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(last_anchor(r)->volume, b.volume, 0.01 * b.volume);
  EXPECT_EQ(last_anchor(r)->polygons.faces.size(), 6u);
  // The correctly oriented box has nothing to turn round.
  EXPECT_EQ(build_lod_tree(test::box(lo, hi).input, fast_params()).stats.planes_turned, 0);
}

// A facade scan has no floor: a base plane closes it at the lowest sample,
// even when floors inside are seen through windows (they stop at the walls,
// short of the scene's bounding box, so they are not terrain).
TEST(LodPipeline, OpenBottomIsClosedAtTheLowestSample) {
  std::vector<test::Face> f;
  test::add_box(f, Vec3(0, 0, 0), Vec3(10, 6, 6), 16);  // no bottom
  test::add_rect(f, Vec3(2, 1.5, 1.2), Vec3::UnitX(), 6, Vec3::UnitY(),
                 3);  // interior floor (lowest quarter), faces up
  const auto b = test::finish(std::move(f), 360.0, 6, SynthOptions{}, false);
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  EXPECT_TRUE(has_note(r, "base plane"));
  ASSERT_NE(last_anchor(r), nullptr);
  const double lowest = test::input_box(b.input).lo.z();
  EXPECT_NEAR(test::lowest_z(*last_anchor(r)), lowest, 1e-6);
  EXPECT_LT(lowest, 0.1);
}

static LodParams terrain_params(Terrain mode) {
  LodParams p = fast_params();
  p.closure.terrain = mode;
  return p;
}

// A house standing on a terrain sheet that fills the crop. With
// closure.terrain = cut (city runs) it gets no base under the terrain, but one
// under the house at the terrain's height: the model is the house, down to
// the ground. With the default (plinth) the terrain is kept as the top of a
// plinth 0.5 m deep under the whole scene: the model is all of the input.
TEST(LodPipeline, TerrainSheetIsCutOrKeptAsAPlinth) {
  std::vector<test::Face> f;
  test::add_box(f, Vec3(0, 0, 0), Vec3(10, 6, 4), 16);                         // house, no bottom
  test::add_rect(f, Vec3(-10, -10, 0), Vec3::UnitX(), 30, Vec3::UnitY(), 26);  // terrain, faces up
  const auto b = test::finish(std::move(f), 240.0, 6, SynthOptions{}, false);
  const LodResult r = build_lod_tree(b.input, terrain_params(Terrain::Cut));
  expect_valid_models(r);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(test::lowest_z(*last_anchor(r)), 0.0, 1e-6);
  EXPECT_NEAR(last_anchor(r)->volume, 240.0, 0.01 * 240.0);
  EXPECT_FALSE(has_note(r, "plinth"));

  const LodResult k = build_lod_tree(b.input, terrain_params(Terrain::Plinth));
  expect_valid_models(k);
  ASSERT_NE(last_anchor(k), nullptr);
  EXPECT_TRUE(has_note(k, "plinth"));
  const double lowest = test::input_box(b.input).lo.z();
  EXPECT_NEAR(test::lowest_z(*last_anchor(k)), lowest - 0.5, 1e-6);
  // House 240 m3 + 30 x 26 m terrain, 0.5 m deep (the outline of the samples
  // runs up to half a sample spacing inside the terrain's edge).
  const double plinth = 30 * 26 * (0.0 - (lowest - 0.5));
  EXPECT_NEAR(last_anchor(k)->volume, 240.0 + plinth, 0.02 * (240.0 + plinth));
}

// As cut out of a city mesh: the terrain has a hole where the house stands,
// the house has no floor and its ground floor is mostly open. Rays from the
// ground floor escape downwards through the hole and sideways through the
// openings; the base under the house at the terrain's height keeps it solid
// down to the ground, and nothing goes below the terrain (closure.terrain =
// cut). (The synthetic house also stays solid without that base.)
TEST(LodPipeline, HouseInATerrainHoleIsSolidDownToTheGround) {
  std::vector<test::Face> f;
  // House 10 x 6 x 8 m, no bottom; its long walls are open 0.5-4.5 m high over
  // 8 of their 10 m (shop windows, a garage door: what MVS leaves of a ground floor).
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  test::add_box(f, Vec3(0, 0, 0), Vec3(10, 6, 8), 16 | 4 | 8);
  test::add_rect(f, Vec3(0, 0, 0), X, 10, Z, 8, {{1, 9, 0.5, 4.5}});  // -y wall
  test::add_rect(f, Vec3(0, 6, 0), Z, 8, X, 10, {{0.5, 4.5, 1, 9}});  // +y wall
  test::add_rect(f, Vec3(1, 0.5, 4.5), X, 8, Y, 5);  // first floor, seen through them
  test::add_rect(f, Vec3(-10, -10, 0), X, 30, Y, 26,
                 {{10, 20, 10, 16}});  // terrain minus the house
  const auto b = test::finish(std::move(f), 480.0, 6, SynthOptions{}, false);
  const LodResult r = build_lod_tree(b.input, terrain_params(Terrain::Cut));
  expect_valid_models(r);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(test::lowest_z(*last_anchor(r)), 0.0, 1e-6);
  EXPECT_NEAR(last_anchor(r)->volume, 480.0, 0.01 * 480.0);
}

// The BSP's first six cuts lie 0.25 m outside the data's bounding box and
// every cell beyond them is out: no model, coarse or fine, reaches further
// into the padded box (5 % of the diagonal). Before, thin cells straddling the
// data's bounds could be labelled in (a 3 m rod on cgal_building's finest
// model) and coarse nodes overhung the data (7.7 m on AHN3_13856).
TEST(LodPipeline, NoModelReachesBeyondTheDataBox) {
  for (const auto& b : {test::chimney_windows(), test::gable_dormer(), test::l_shape()}) {
    Vec3 lo = b.input.points.front(), hi = lo;
    for (const auto& p : b.input.points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const LodResult r = build_lod_tree(b.input, fast_params());
    expect_valid_models(r);
    ASSERT_FALSE(r.models.empty());
    // (+ 1 cm: the data box also holds the planes' hulls, whose projected
    // inliers can stick out of the points' box by millimetres)
    for (const auto& m : r.models)
      for (const auto& v : m.mesh.vertices) {
        EXPECT_LE((lo - v).maxCoeff(), 0.26);
        EXPECT_LE((v - hi).maxCoeff(), 0.26);
      }
  }
}

// A plinth under a sloping terrain follows the slope: the walls along the
// scene's outline reach up to the terrain, not to its highest point.
TEST(LodPipeline, PlinthFollowsASlopingTerrain) {
  std::vector<test::Face> f;
  const Vec3 Y = Vec3::UnitY();
  const Vec3 S =
      Vec3(1, 0, 0.1).normalized();  // terrain: z = -2 + 0.1 (x + 10), 10 % slope along x
  const double L = 30.0 / S.x();
  // House 10 x 6 m on it, walls from the terrain up to z = 4, no bottom.
  test::add_box(f, Vec3(0, 0, -1.0), Vec3(10, 6, 4), 16);
  test::add_rect(f, Vec3(-10, -10, -2.0), S, L, Y, 26, {{10 / S.x(), 20 / S.x(), 10, 16}});
  const auto b = test::finish(std::move(f), 0.0, 6, SynthOptions{}, false);
  const LodResult r = build_lod_tree(b.input, fast_params());
  expect_valid_models(r);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_TRUE(has_note(r, "plinth"));
  // Near the scene's edges the model is no higher than the terrain there.
  int edge_vertices = 0;
  double worst = -1e9;
  for (const auto& v : last_anchor(r)->mesh.vertices) {
    if (v.x() > -8 && v.x() < 18 && v.y() > -8 && v.y() < 14)
      continue;  // the house and its surroundings
    const double terrain = -2.0 + 0.1 * (v.x() + 10);
    EXPECT_LE(v.z(), terrain + 0.3) << v.transpose();
    worst = std::max(worst, v.z() - terrain);
    ++edge_vertices;
  }
  EXPECT_GE(edge_vertices, 8);
  EXPECT_LE(worst, 0.3);
  // Plinth: 30 x 26 m from 0.5 m under the lowest sample (z = -2) up to the
  // terrain (mean z -0.5): 1560 m3; house above the terrain: 60 m2 x 4.5 m =
  // 270 m3. (The outline of the samples runs up to half a sample spacing
  // inside the terrain's edge: -1.8 % measured.)
  EXPECT_NEAR(last_anchor(r)->volume, 1830.0, 0.03 * 1830.0);
}

// Airborne LiDAR hits some walls of a building (a tower's, a facade facing
// the flight line) but not all: the walls that were scanned keep the wall
// heuristic from inferring any. With a footprint and closure.footprint_walls
// (city runs) the footprint's walls close the building anyway.
TEST(LodPipeline, FootprintWallsCloseAPartlyScannedBuilding) {
  std::vector<test::Face> f;
  test::add_box(f, Vec3(0, 0, 0), Vec3(10, 6, 8), 16 | 4 | 8);  // roof and the two x walls only
  auto b = test::finish(std::move(f), 480.0, 3, SynthOptions{}, false);
  b.input.footprint = {Vec2(0, 0), Vec2(10, 0), Vec2(10, 6), Vec2(0, 6)};
  b.input.has_ground_z = true;
  b.input.ground_z = 0.0;
  LodParams p = fast_params();
  p.closure.footprint_walls = true;
  const LodResult r = build_lod_tree(b.input, p);
  expect_valid_models(r);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_TRUE(has_note(r, "walls along the footprint"));
  EXPECT_TRUE(r.stats.walls_inferred);
  EXPECT_NEAR(last_anchor(r)->volume, 480.0, 0.01 * 480.0);
  // Without it the scanned walls count as walls: none is inferred.
  const LodResult q = build_lod_tree(b.input, fast_params());
  EXPECT_FALSE(has_note(q, "walls along the footprint"));
  EXPECT_FALSE(q.stats.walls_inferred);
}

// Caps are recorded decisions (issue 16): planes.max_planes keeps the largest
// planes, and the report says how many were found and left out.
TEST(LodPipeline, PlaneCapIsRecorded) {
  const auto b = test::chimney_windows();
  LodParams p = fast_params();
  const LodResult all = build_lod_tree(b.input, p);
  EXPECT_EQ(all.stats.planes_found, all.stats.planes_detected);
  for (const auto& n : all.stats.notes) EXPECT_EQ(n.find("planes.max_planes"), std::string::npos);
  ASSERT_GT(all.stats.planes_found, 6);
  p.planes.max_planes = 6;
  const LodResult capped = build_lod_tree(b.input, p);
  EXPECT_EQ(capped.stats.planes_found, all.stats.planes_found);
  EXPECT_EQ(capped.stats.planes_detected, 6);
  bool noted = false;
  for (const auto& n : capped.stats.notes)
    noted |= n.find("planes.max_planes = 6 reached: " + std::to_string(all.stats.planes_found) +
                    " planes found") != std::string::npos;
  EXPECT_TRUE(noted);
}

// alpha.alpha reaches IO-View: the shapes of the detected planes are built
// with the user's radius (it used to apply to regularized planes only).
TEST(LodPipeline, AlphaRadiusChangesTheShapes) {
  const auto b = test::chimney_windows();
  LodParams p = fast_params();
  p.regularization.enabled = false;  // only detection builds the shapes
  const LodResult r7 = build_lod_tree(b.input, p);
  p.alpha.alpha = 0.3;  // a few sample spacings: the window openings stay open
  const LodResult r0 = build_lod_tree(b.input, p);
  double a7 = 0, a0 = 0;
  for (const auto& pl : r7.planes) a7 += pl.inferred ? 0 : pl.area;
  for (const auto& pl : r0.planes) a0 += pl.inferred ? 0 : pl.area;
  // Before, detection always used 7 m: the same shapes, the same areas.
  EXPECT_GT(std::abs(a0 - a7), 0.01 * a7);  // 2 % on this house
}

/// A chunk of a city mesh as the split gives it: a mesh without floor (faces refined
/// 3 times) on its footprint, the ground at z = 0; and the parameters of city runs.
static test::SynthBuilding city_mesh_chunk(std::vector<test::Face> f, double volume, int planes,
                                           std::vector<Vec2> footprint) {
  SynthOptions o;
  o.refine_levels = 3;
  auto b = test::finish(std::move(f), volume, planes, o, /*mesh=*/true);
  b.input.footprint = std::move(footprint);
  b.input.has_ground_z = true;
  b.input.ground_z = 0.0;
  return b;
}
static LodParams city_params() {
  LodParams p = fast_params();
  p.closure.footprint_walls = true;
  p.closure.terrain = Terrain::Cut;
  return p;
}

// A row house of a photogrammetry city mesh (issue 15; the proportions of
// mesh_city's b31bdd447): gable roof 4 m along the ridge (x) x 4 m deep,
// eaves 3.5 m, ridge 6.7 m; its two eave walls seen, its gable ends hidden by
// the neighbours (no party walls in the mesh) and no floor. The footprint's
// walls close it; they stand under the roof's profile along their edge (a
// gable, not a rectangle up to the ridge, whose backs would vote the cells
// over the roof slopes inside): 4 x 4 x 3.5 + 4 x 4 x 3.2 / 2 = 81.6 m3. The
// footprint's eave edges lie 4 and 3 mm off the seen walls: those inferred
// walls take the seen walls' planes (closure.wall_snap). On this noise-free
// house the models are valid without it too; on mesh_city 6 solids were not
// (TileCli.MeshCityModelsHaveTheirTrueVolumes).
TEST(LodPipeline, MeshRowHouseWallsFollowTheRoofAndTheSeenWalls) {
  const Vec3 X = Vec3::UnitX(), Z = Vec3::UnitZ();
  const double L = 4, D = 4, H = 3.5, R = 3.2, vol = L * D * H + L * D * R / 2;
  std::vector<test::Face> f;
  test::add_rect(f, Vec3(0, 0, 0), X, L, Z, H);  // y = 0 wall, -y
  test::add_rect(f, Vec3(0, D, 0), Z, H, X, L);  // y = D wall, +y
  const double sl = std::sqrt(D * D / 4 + R * R);
  test::add_rect(f, Vec3(0, 0, H), X, L, Vec3(0, D / 2, R) / sl, sl);   // south roof
  test::add_rect(f, Vec3(0, D, H), Vec3(0, -D / 2, R) / sl, sl, X, L);  // north roof
  const auto b =
      city_mesh_chunk(std::move(f), vol, 4,
                      {Vec2(0, 0.004), Vec2(L, 0.004), Vec2(L, D + 0.003), Vec2(0, D + 0.003)});
  const LodResult r = build_lod_tree(b.input, city_params());
  expect_valid_models(r);
  EXPECT_TRUE(has_note(r, "walls along the footprint"));
  EXPECT_TRUE(has_note(r, "2 inferred walls on the plane of a wall"));
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(last_anchor(r)->volume, vol, 0.01 * vol);
}

// A city-mesh building of two heights in a row (issue 15; like mesh_city's
// b31be22a3): main body x 0..5 (9 m), annex x 5..10 (3 m), 4 m deep, flat
// roofs; the long walls y = 0 and y = 4 hidden by the neighbours, the rest
// seen, no floor. The footprint walls along the long edges follow the roofs'
// profile (9 m over the main body, 3 m over the annex): a wall up to the
// highest roof along the whole edge would fill the annex up to 9 m.
// 5 x 4 x 9 + 5 x 4 x 3 = 240 m3.
TEST(LodPipeline, MeshAnnexIsNotFilledUpToTheMainRoof) {
  std::vector<test::Face> f;
  const Vec3 X = Vec3::UnitX(), Y = Vec3::UnitY(), Z = Vec3::UnitZ();
  test::add_rect(f, Vec3(0, 0, 0), Y, 4, Z, 9);   // x = 0 wall, -x
  test::add_rect(f, Vec3(5, 0, 3), Z, 6, Y, 4);   // step wall x = 5 over the annex, +x
  test::add_rect(f, Vec3(10, 0, 0), Z, 3, Y, 4);  // x = 10 wall, +x
  test::add_rect(f, Vec3(0, 0, 9), X, 5, Y, 4);   // main roof
  test::add_rect(f, Vec3(5, 0, 3), X, 5, Y, 4);   // annex roof
  const auto b =
      city_mesh_chunk(std::move(f), 240.0, 5, {Vec2(0, 0), Vec2(10, 0), Vec2(10, 4), Vec2(0, 4)});
  LodParams p = city_params();
  const LodResult r = build_lod_tree(b.input, p);
  expect_valid_models(r);
  ASSERT_NE(last_anchor(r), nullptr);
  EXPECT_NEAR(last_anchor(r)->volume, 240.0, 0.01 * 240.0);
  // The rectangle walls of before (closure.wall_profile = false): the annex
  // filled up to the main roof, 10 x 4 x 9 = 360 m3.
  p.closure.wall_profile = false;
  const LodResult q = build_lod_tree(b.input, p);
  expect_valid_models(q);
  ASSERT_NE(last_anchor(q), nullptr);
  EXPECT_NEAR(last_anchor(q)->volume, 360.0, 0.01 * 360.0);
}
