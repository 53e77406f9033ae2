// The LOD engine on the real buildings of ../shared/data (issue acceptance):
// every candidate model closed, edge-manifold, oriented and free of
// self-intersections; at least 2 anchors and 1 interpolation; the finest
// anchor's e2 recorded (and bounded where we meet the target).
#include "support/lod_models.hpp"
#include "support/ply_min.hpp"

#include "citylod/lod/lod.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

using namespace citylod;
using namespace citylod::lod;

namespace {

std::string data(const std::string& rel) {
  return std::string(CITYLOD_SHARED_DATA) + "/" + rel;
}

/// Recentres on the bbox centre rounded to whole metres, as `citylod lod`
/// does (the engine wants small coordinates). The frame matters at the last
/// digit: region growing on float positions is chaotic at its thresholds, and
/// cgal_building's e2 moves by about +-1 % of itself with a sub-metre shift.
void recentre(BuildingInput& in) {
  const auto box = test::input_box(in);
  const Vec3 c = (0.5 * (box.lo + box.hi)).array().round();
  for (auto& p : in.points) p -= c;
}

/// max_overhang: the engine's data-box cuts lie 0.25 m outside the data (plus
/// the hulls' projections of the inliers, and a plinth's depth).
void check_building(BuildingInput in, double max_finest_e2, double max_overhang) {
  recentre(in);
  LodParams p;
  p.budget.time_budget_s = 0;
  const LodResult r = build_lod_tree(in, p);
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  const auto box = test::input_box(in);
  for (const auto& m : r.models) {
    SCOPED_TRACE("model " + std::to_string(m.step));
    test::expect_closed_solid(m);
    EXPECT_LE(test::overhang(m, box), max_overhang);
  }
  const int anchors = test::count_models(r, ModelKind::anchor);
  const int interps = test::count_models(r, ModelKind::interpolation);
  EXPECT_GE(anchors, 2);
  EXPECT_GE(interps, 1);
  const LodModel* f = test::last_anchor(r);
  ASSERT_NE(f, nullptr);
  std::printf(
      "[%s] %zu models (%d anchors), finest anchor: %zu triangles, e1 %.3f %%, e2 %.3f %%\n",
      in.name.c_str(), r.models.size(), anchors, f->mesh.triangles.size(), f->e1, f->e2);
  EXPECT_LE(f->e2, max_finest_e2);
}

}  // namespace

TEST(LodRealData, Ahn3LidarBuildingWithSawtoothRoofs) {
  const auto path = data("ahn3_building_lod2/AHN3_13856.ply");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_ply_min(path);
  in.name = "AHN3_13856";
  check_building(in, 0.5, 0.5);
}

TEST(LodRealData, CgalBuildingPointCloud) {
  const auto path = data("single_building/cgal_building.ply");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_ply_min(path);
  in.name = "cgal_building";
  // Target 0.5 %, met by a small margin: the engine's e2 (5000 input points,
  // one at a hashed offset per block) is 0.497 %, over all 100k points
  // 0.494 % (BENCHMARKS.md). The same cloud shifted by (0.37, -0.21, 0.13) m
  // gives 0.503 %. ~11 % of the squared error is ~100 points of an attic
  // floor seen through a dormer window, 3 m from any surface; ~30 % interior
  // floors of the ground storey seen through its windows.
  check_building(in, 0.5, 0.5);
}

// Issue 30: City3D's AHN3 00586, a flat shed of 188 roof points spanning 0.16 m,
// no wall, no ground. Its ground was the lowest sample: no height, "no cell
// labelled inside", a fallback. The ground is now a storey under the roof.
TEST(LodRealData, City3dFlatShedWithoutGroundGetsAStorey) {
  const auto path = data("city3d/AHN3/00586.ply");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_ply_min(path);
  recentre(in);
  const auto box = test::input_box(in);
  ASSERT_LT(box.hi.z() - box.lo.z(), 0.2);
  const LodResult r = build_lod_tree(in, LodParams{});
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  const LodModel* f = test::last_anchor(r);
  ASSERT_NE(f, nullptr);
  test::expect_closed_solid(*f);
  EXPECT_NEAR(test::lowest_z(*f), box.lo.z() - LodParams{}.closure.unknown_ground_depth, 1e-6);
  EXPECT_LT(f->e2, 2.0);  // % of the diagonal: the roof is where the points are
}

// Issue 30: City3D's DALES 00284 has 40 % wall samples (a scan, for the rays), but
// the rays label no usable interior: it is modelled again as airborne LiDAR
// instead of falling back to a block.
TEST(LodRealData, City3dScanTheRaysCannotLabelIsModelledAsAirborne) {
  const auto path = data("city3d/Dales3d/00284.ply");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_ply_min(path);
  recentre(in);
  const LodResult r = build_lod_tree(in, LodParams{});
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  EXPECT_TRUE(test::has_note(r, "the rays failed"));
  for (const auto& m : r.models) {  // closed; one anchor is two solids (a multi-solid, noted)
    SCOPED_TRACE("model " + std::to_string(m.step));
    const MeshCheck c = check_mesh(m.mesh);
    EXPECT_TRUE(c.closed && c.edge_manifold && c.oriented && !c.self_intersecting);
  }
  ASSERT_NE(test::last_anchor(r), nullptr);
  // 1.37 % of the 21 m diagonal: 0.289 m, City3D's published model 0.412 m
  EXPECT_LT(test::last_anchor(r)->e2, 1.5);
}

// Issue 30: City3D's AHN3 00513 (a stepped roof) fell back with "fewer than 4
// principal primitives": its roof planes cut the inside into one region per
// step. IO-View again with the inside regions joined models it, and its
// finest fits the points better than the LoD1.2 block.
TEST(LodRealData, City3dSteppedRoofIsOneCoreAndNoModelIsWorseThanTheBlock) {
  const auto path = data("city3d/AHN3/00513.ply");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_ply_min(path);
  recentre(in);
  const LodResult r = build_lod_tree(in, LodParams{});
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  EXPECT_TRUE(test::has_note(r, "the inside regions taken as one core"));
  ASSERT_TRUE(r.stats.block_first);
  for (const auto& m : r.models) {
    SCOPED_TRACE("model " + std::to_string(m.step));
    test::expect_closed_solid(m);
  }
  const LodModel* f = test::last_anchor(r);
  ASSERT_NE(f, nullptr);
  std::printf("[00513] %zu models, block e2 %.3f %%, finest e2 %.3f %%, %d dropped\n",
              r.models.size(), r.models.front().e2, f->e2, r.stats.worse_than_block);
  EXPECT_LE(f->e2, r.models.front().e2);
  EXPECT_LT(f->e2, 1.3);  // % of the diagonal (bench.py: 0.23 m; the old prism fallback 1.04 m)
}

TEST(LodRealData, Easy3dNoisyMeshWithTerrain) {
  const auto path = data("noisy_mesh/easy3d_building.off");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << path;
  auto in = test::read_off_min(path);
  in.name = "easy3d_building";
  // Target 0.5 %: the terrain sheet around the house (~15 % of the input's
  // area) is kept as a plinth 0.5 m deep (closure.terrain = plinth, the
  // default): 0.437 % (400k area samples of the input: 0.442 %); with
  // closure.terrain = cut, 2.4 %.
  check_building(in, 0.5, 1.0);
}
