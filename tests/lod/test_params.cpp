#include "citylod/lod/lod.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <stdexcept>

using namespace citylod::lod;

TEST(LodParams, DefaultsAreThePapers) {
  const LodParams p;
  EXPECT_DOUBLE_EQ(p.planes.epsilon, 0.15);
  EXPECT_DOUBLE_EQ(p.planes.max_angle_deg, 40.0);
  EXPECT_EQ(p.planes.min_region_size, 15);
  EXPECT_DOUBLE_EQ(p.alpha.alpha, 7.0);
  EXPECT_DOUBLE_EQ(p.cluster.area_bandwidth, 2.0);
  EXPECT_DOUBLE_EQ(p.cluster.volume_bandwidth, 4.0);
  EXPECT_EQ(p.cluster.volume_scale,
            VolumeScale::Ratio);                    // ours: the paper gives no unit (a factor)
  EXPECT_FALSE(p.ioview.covered_only);              // ours: the paper's rule fails cgal's e2 target
  EXPECT_EQ(p.ioview.uncovered, Uncovered::Noise);  // ours: used with covered_only only
  EXPECT_DOUBLE_EQ(p.regularization.principal_angle_deg, 5.0);
  EXPECT_DOUBLE_EQ(p.regularization.principal_distance, 0.01);
  EXPECT_DOUBLE_EQ(p.regularization.secondary_angle_deg, 15.0);
  EXPECT_DOUBLE_EQ(p.regularization.secondary_distance, 0.01);
  EXPECT_DOUBLE_EQ(p.regularization.vertical_host_deg, 5.0);
  EXPECT_EQ(p.tree.merge_k, 10);
  EXPECT_DOUBLE_EQ(p.tree.label_volume_ratio, 0.65);
  EXPECT_DOUBLE_EQ(p.tree.interpolation_ratio, 0.80);
  EXPECT_DOUBLE_EQ(p.tree.interpolation_floor, 0.02);  // ours, not the paper's
  EXPECT_EQ(p.labels.rays_per_cell, 100);
  EXPECT_NO_THROW(p.validate());
}

TEST(LodParams, SetByDottedName) {
  LodParams p;
  p.set("planes.epsilon", "0.2");
  p.set("alpha.alpha", "3.5");
  p.set("tree.merge_k", "4");
  p.set("tree.interpolation_ratio", "0.9");
  p.set("labels.rays_per_cell", "50");
  p.set("regularization.enabled", "false");
  p.set("closure.enabled", "0");
  EXPECT_DOUBLE_EQ(p.planes.epsilon, 0.2);
  EXPECT_DOUBLE_EQ(p.alpha.alpha, 3.5);
  EXPECT_EQ(p.tree.merge_k, 4);
  EXPECT_DOUBLE_EQ(p.tree.interpolation_ratio, 0.9);
  EXPECT_EQ(p.labels.rays_per_cell, 50);
  EXPECT_FALSE(p.regularization.enabled);
  EXPECT_FALSE(p.closure.enabled);
  EXPECT_NO_THROW(p.validate());
}

TEST(LodParams, SetRejectsUnknownAndMalformed) {
  LodParams p;
  EXPECT_THROW(p.set("planes.epsilonx", "1"), std::invalid_argument);
  EXPECT_THROW(p.set("epsilon", "1"), std::invalid_argument);
  // Threads are how a building runs (LodExecution), not what the method computes.
  EXPECT_THROW(p.set("threads", "3"), std::invalid_argument);
  EXPECT_THROW(p.set("planes.epsilon", "abc"), std::invalid_argument);
  EXPECT_THROW(p.set("planes.epsilon", "1.0x"), std::invalid_argument);
  EXPECT_THROW(p.set("tree.merge_k", "2.5"), std::invalid_argument);
  EXPECT_THROW(p.set("regularization.enabled", "maybe"), std::invalid_argument);
  EXPECT_DOUBLE_EQ(p.planes.epsilon, 0.15);
}

TEST(LodParams, ValidateNamesTheParameter) {
  auto expect_bad = [](const char* name, const char* value) {
    LodParams p;
    try {
      p.set(name, value);  // a mode's unknown word is refused here
      p.validate();
      ADD_FAILURE() << name << "=" << value << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  expect_bad("planes.epsilon", "0");
  expect_bad("planes.epsilon", "-1");
  expect_bad("planes.max_angle_deg", "0");
  expect_bad("planes.max_angle_deg", "91");
  expect_bad("planes.min_region_size", "2");
  expect_bad("alpha.alpha", "0");
  expect_bad("tree.interpolation_ratio", "1.5");
  expect_bad("tree.label_volume_ratio", "0");
  expect_bad("labels.rays_per_cell", "0");
  expect_bad("tree.merge_k", "0");
  expect_bad("regularization.principal_angle_deg", "100");
  expect_bad("closure.outline_alpha", "-2");
  expect_bad("closure.terrain", "keep");
  expect_bad("closure.plinth_depth", "0");
  expect_bad("closure.wall_snap", "-0.1");
  expect_bad("closure.unknown_ground_depth", "-1");
  expect_bad("airborne.wall_fraction_max", "0");
  expect_bad("ioview.uncovered", "drop");
  // the edges of the ranges, and rules that read another parameter
  expect_bad("bsp.bbox_enlarge", "1.01");
  expect_bad("tree.interpolation_floor", "1");
  expect_bad("orient.margin", "1");
  expect_bad("orient.rays", "1");
  expect_bad("colour.max_angle_deg", "90.5");
  expect_bad("airborne.mode", "maybe");
  expect_bad("cluster.volume_scale", "m2");
  expect_bad("labels.origins_per_cell", "101");  // > labels.rays_per_cell (100)
  expect_bad("cluster.volume_bandwidth", "1");   // a factor (volume_scale = ratio) must be > 1
  auto expect_good = [](const char* name, const char* value) {
    LodParams p;
    p.set(name, value);
    EXPECT_NO_THROW(p.validate()) << name << "=" << value;
  };
  expect_good("bsp.bbox_enlarge", "1");
  expect_good("tree.interpolation_floor", "0");
  expect_good("colour.max_angle_deg", "0");
  expect_good("labels.origins_per_cell", "100");
  {
    LodParams p;  // m3: the bandwidth is a volume, any positive value
    p.set("cluster.volume_scale", "m3");
    p.set("cluster.volume_bandwidth", "0.5");
    EXPECT_NO_THROW(p.validate());
  }
}

TEST(LodParams, ItemsRoundTrip) {
  LodParams p;
  const auto items = p.items();
  std::set<std::string> names;
  for (const auto& kv : items)
    EXPECT_TRUE(names.insert(kv.first).second) << "duplicate " << kv.first;
  for (const char* n : {"planes.epsilon",
                        "alpha.alpha",
                        "tree.merge_k",
                        "tree.interpolation_ratio",
                        "labels.rays_per_cell",
                        "regularization.enabled",
                        "closure.outline_alpha",
                        "metrics.samples",
                        "bsp.max_cells",
                        "budget.time_budget_s",
                        "normals.k_neighbors",
                        "bsp.baseline",
                        "tree.interpolation_floor",
                        "airborne.mode",
                        "airborne.step_min",
                        "airborne.step_min_raw",
                        "airborne.block",
                        "colour.enabled",
                        "colour.distance",
                        "colour.max_angle_deg",
                        "closure.wall_profile",
                        "closure.wall_snap",
                        "colour.min_points",
                        "airborne.plane_merge_distance",
                        "airborne.plane_merge_angle_deg"})
    EXPECT_TRUE(names.count(n)) << n;
  EXPECT_EQ(items.size(), 67u);  // one per field of every parameter struct
  // Every listed item can be set back to its listed value, unchanged.
  LodParams q;
  q.set("planes.epsilon", "0.3");
  for (const auto& kv : items) q.set(kv.first, kv.second);
  EXPECT_EQ(q.items(), items);
  EXPECT_EQ(items.front().first, "normals.k_neighbors");
  EXPECT_EQ(items.back().first, "colour.max_angle_deg");
  EXPECT_FALSE(names.count("threads"));
}

// describe() is items() with each parameter's unit, rule (or the words a mode
// takes) and doc: what `citylod lod --help` lists.
TEST(LodParams, DescribeGivesUnitRuleAndDocOfEveryItem) {
  LodParams p;
  p.set("planes.epsilon", "0.25");
  const auto items = p.items();
  const auto info = p.describe();
  ASSERT_EQ(info.size(), items.size());
  std::map<std::string, ParamInfo> by;
  for (std::size_t i = 0; i < info.size(); ++i) {
    EXPECT_EQ(info[i].name, items[i].first);
    EXPECT_EQ(info[i].value, items[i].second);
    by[info[i].name] = info[i];
  }
  EXPECT_EQ(by["planes.epsilon"].value, "0.25");
  EXPECT_EQ(by["planes.epsilon"].unit, "m");
  EXPECT_EQ(by["planes.epsilon"].rule, "must be > 0");
  EXPECT_EQ(by["planes.max_angle_deg"].unit, "deg");
  EXPECT_EQ(by["planes.max_angle_deg"].rule, "must be in (0, 90]");
  EXPECT_EQ(by["tree.merge_k"].rule, "must be >= 1");
  EXPECT_EQ(by["closure.terrain"].unit, "");
  EXPECT_EQ(by["closure.terrain"].rule, "'plinth' or 'cut'");
  EXPECT_EQ(by["airborne.mode"].rule, "'auto', 'on' or 'off'");
  EXPECT_EQ(by["bsp.baseline"].rule, "true or false");
  EXPECT_EQ(by["labels.origins_per_cell"].rule, "must be in [1, labels.rays_per_cell]");
  EXPECT_EQ(by["planes.epsilon"].doc, "max point-to-plane distance of a plane's inliers");
  // every number has a unit and a rule; every switch and mode its words; every
  // parameter a one-line doc that fits the help's table
  for (const auto& d : info) {
    EXPECT_FALSE(d.rule.empty()) << d.name;
    EXPECT_FALSE(d.doc.empty()) << d.name;
    EXPECT_LE(d.doc.size(), 80u) << d.name;
    EXPECT_EQ(d.doc.find('\n'), std::string::npos) << d.name;
    if (d.value != "true" && d.value != "false" && d.value.find_first_of("0123456789") == 0) {
      EXPECT_FALSE(d.unit.empty()) << d.name;
    }
  }
}

TEST(LodParams, ModesAreEnumsWithTheirWords) {
  LodParams p;
  EXPECT_EQ(p.closure.terrain, Terrain::Plinth);
  p.set("closure.terrain", "cut");
  EXPECT_EQ(p.closure.terrain, Terrain::Cut);
  p.set("airborne.mode", "off");
  EXPECT_EQ(p.airborne.mode, AirborneMode::Off);
  p.set("ioview.uncovered", "s0");
  EXPECT_EQ(p.ioview.uncovered, Uncovered::S0);
  p.set("cluster.volume_scale", "m3");
  EXPECT_EQ(p.cluster.volume_scale, VolumeScale::M3);
  EXPECT_STREQ(to_string(AirborneMode::Auto), "auto");
  EXPECT_STREQ(to_string(Uncovered::Last), "last");
  try {
    p.set("closure.terrain", "keep");
    ADD_FAILURE() << "closure.terrain=keep accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "parameter closure.terrain: must be 'plinth' or 'cut', got 'keep'");
  }
  EXPECT_EQ(p.closure.terrain, Terrain::Cut);  // unchanged
}

TEST(LodParams, ModelKindNames) {
  EXPECT_STREQ(to_string(ModelKind::anchor), "anchor");
  EXPECT_STREQ(to_string(ModelKind::interpolation), "interpolation");
  EXPECT_STREQ(to_string(ModelKind::fallback), "fallback");
}
