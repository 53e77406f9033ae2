// Level sets (paper Section 4.1, issue 16): the second-stage mean shift on the
// clusters' mean volumes, principal primitives by alpha-shape coverage, and a
// house with dormers, a chimney and windows whose three anchors are known.
#include "support/lod_models.hpp"
#include "support/synthetic.hpp"

#include "bsp.hpp"
#include "citylod/lod/lod.hpp"
#include "grouping.hpp"
#include "ioview.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace citylod;
using namespace citylod::lod;
using namespace citylod::lod::detail;

namespace {

/// IO-View with one structure per (host, projected area, volume) triple, each
/// bounded by one primitive of its own (primitives 0..n-1 are secondary; the
/// hosts are primitives n, n+1, ...).
struct Toy {
  IoView view;
  std::vector<Primitive> prims;
};
Toy toy_view(const std::vector<std::array<double, 3>>& structures, int hosts) {
  Toy t;
  const size_t n = structures.size();
  t.prims.resize(n + size_t(hosts));
  t.view.principal.assign(t.prims.size(), 0);
  for (int h = 0; h < hosts; ++h) t.view.principal[n + size_t(h)] = 1;
  for (size_t i = 0; i < n; ++i) {
    Structure s;
    s.host = int(n) + int(structures[i][0]);
    s.projected_area = structures[i][1];
    s.volume = structures[i][2];
    s.primitives = {int(i)};
    t.prims[i].alpha_area = structures[i][1];
    t.view.structures.push_back(s);
  }
  return t;
}

/// The level set of each structure (by its primitive).
std::vector<int> levels(const Grouping& g, size_t n) {
  std::vector<int> out(n, -1);
  for (const auto& c : g.clusters)
    for (int s : c.structures) out[size_t(s)] = c.level;
  return out;
}

}  // namespace

// Two dormers (4 m^2, 4.8 m^3) and a chimney (0.64 m^2, 0.96 m^3) on the roof
// (host 0), four windows (1.8 m^2, 0.54 m^3) in a wall (host 1).
TEST(LevelSets, VolumesAreReadAsAFactor) {
  const Toy t = toy_view({{0, 4.0, 4.8},
                          {0, 4.0, 4.8},
                          {0, 0.64, 0.96},
                          {1, 1.8, 0.54},
                          {1, 1.8, 0.54},
                          {1, 1.8, 0.54},
                          {1, 1.8, 0.54}},
                         2);
  ClusterParams p;  // the paper's bandwidths 2 and 4; volumes as a factor
  const Grouping g = group_structures(t.view, t.prims, p);
  // stage 1: {dormers}, {chimney} on the roof (4 vs 0.64 m^2), {windows} on the wall
  ASSERT_EQ(g.clusters.size(), 3u);
  EXPECT_EQ(g.num_level_sets, 2);
  // stage 2 on ln V: ln 4.8 = 1.57 is more than ln 4 = 1.39 from the mode of
  // the chimney (ln 0.96 = -0.04) and the windows (ln 0.54 = -0.62)
  EXPECT_EQ(levels(g, 7), (std::vector<int>{1, 1, 2, 2, 2, 2, 2}));
  // clusters by level, then mean volume descending
  EXPECT_EQ(g.clusters[0].structures, (std::vector<int>{0, 1}));
  EXPECT_EQ(g.clusters[1].structures, (std::vector<int>{2}));
  EXPECT_EQ(g.clusters[2].structures, (std::vector<int>{3, 4, 5, 6}));
  // scale-sorted S: no principal primitive here, then level 1, then level 2
  const SortedPrimitives s = sort_primitives(t.prims, t.view, g);
  EXPECT_EQ(s.num_levels, 3);
  EXPECT_EQ(s.level_of[0], 1);
  EXPECT_EQ(s.level_of[2], 2);
  EXPECT_EQ(s.level_of[6], 2);

  // The literal reading (4 m^3 on V) puts all three clusters in one mode.
  p.volume_scale = VolumeScale::M3;
  const Grouping m3 = group_structures(t.view, t.prims, p);
  EXPECT_EQ(m3.num_level_sets, 1);
  EXPECT_EQ(levels(m3, 7), (std::vector<int>(7, 1)));
}

TEST(LevelSets, ThreeScalesGiveThreeLevelSetsLargestFirst) {
  // an annex (120 m^3), dormers (10 m^3), chimneys (1 m^3), on separate hosts
  const Toy t = toy_view({{0, 30, 120}, {1, 6, 10}, {1, 6, 11}, {2, 1, 1.0}, {2, 1, 1.2}}, 3);
  const Grouping g = group_structures(t.view, t.prims, ClusterParams{});
  EXPECT_EQ(g.num_level_sets, 3);
  EXPECT_EQ(levels(g, 5), (std::vector<int>{1, 2, 2, 3, 3}));
  // the same volumes in litres: the same level sets (the factor has no unit)
  Toy litres = t;
  for (auto& s : litres.view.structures) s.volume *= 1000;
  EXPECT_EQ(levels(group_structures(litres.view, litres.prims, ClusterParams{}), 5), levels(g, 5));
}

TEST(LevelSets, ParamsCheckTheScale) {
  LodParams p;
  EXPECT_EQ(p.cluster.volume_scale, VolumeScale::Ratio);
  p.set("cluster.volume_scale", "m3");
  EXPECT_NO_THROW(p.validate());
  // An unknown word is refused where it is given, naming the choices, and
  // leaves the parameter as it was.
  try {
    p.set("cluster.volume_scale", "auto");
    ADD_FAILURE() << "set() took 'auto'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'ratio' or 'm3'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(p.set("cluster.volume_scale", "log"), std::invalid_argument);
  EXPECT_EQ(p.cluster.volume_scale, VolumeScale::M3);
  p.set("cluster.volume_scale", "ratio");
  p.set("cluster.volume_bandwidth", "0.5");  // a factor below 1 means nothing
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

namespace {

/// Axis-aligned face of the box [0,10]^3 as a primitive; its alpha-shape is
/// the face, or only the small corner triangle when `corner_only`.
Primitive face(int axis, bool hi, bool corner_only) {
  Primitive p;
  p.normal = Vec3::Zero();
  p.normal[axis] = hi ? 1.0 : -1.0;
  p.d = hi ? -10.0 : 0.0;
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;
  auto at = [&](double a, double b) {
    Vec3 x = Vec3::Zero();
    x[axis] = hi ? 10.0 : 0.0;
    x[u] = a;
    x[w] = b;
    return x;
  };
  p.hull = {at(0, 0), at(10, 0), at(10, 10), at(0, 10)};
  p.centroid = at(5, 5);
  plane_frame(p.normal, p.u, p.v);
  if (corner_only)
    p.alpha_tris = {{at(0, 0), at(0.5, 0), at(0, 0.5)}};
  else
    p.alpha_tris = {{at(0, 0), at(10, 0), at(10, 10)}, {at(0, 0), at(10, 10), at(0, 10)}};
  p.hull_area = 100;
  p.alpha_area = corner_only ? 0.125 : 100;
  return p;
}

}  // namespace

// The top face's plane bounds the box but its alpha-shape covers only a
// 0.125 m^2 corner: principal by its plane, not by the paper's rule.
TEST(LevelSets, PrincipalOnlyWhereTheAlphaShapeCovers) {
  std::vector<Primitive> prims;
  for (int axis = 0; axis < 3; ++axis)
    for (int hi = 0; hi < 2; ++hi) prims.push_back(face(axis, hi != 0, axis == 2 && hi));
  std::vector<BspPolygon> polys;
  for (size_t i = 0; i < prims.size(); ++i) {
    const auto& p = prims[i];
    polys.push_back(BspPolygon{{p.normal.x(), p.normal.y(), p.normal.z(), p.d}, p.hull, int(i)});
  }
  const Bsp bsp(Vec3(-2, -2, -2), Vec3(12, 12, 12), polys, 1000);
  std::vector<char> inside;
  for (int l : bsp.leaves()) {
    const Vec3 c = bsp.nodes()[size_t(l)].center;
    inside.push_back((c.array() > 0).all() && (c.array() < 10).all() ? 1 : 0);
  }
  const auto planes = match_planes(bsp, prims);
  IoViewParams p;
  const IoView plane_rule = analyse_io_view(bsp, prims, planes, inside, p);
  EXPECT_EQ(plane_rule.principal, (std::vector<char>{1, 1, 1, 1, 1, 1}));
  EXPECT_EQ(plane_rule.on_surface, (std::vector<char>{1, 1, 1, 1, 1, 1}));
  p.covered_only = true;
  const IoView paper_rule = analyse_io_view(bsp, prims, planes, inside, p);
  EXPECT_EQ(paper_rule.principal, (std::vector<char>{1, 1, 1, 1, 1, 0}));
  // the interface still lies on the top face's plane
  EXPECT_EQ(paper_rule.on_surface, (std::vector<char>{1, 1, 1, 1, 1, 1}));
}

// ioview.uncovered: primitives on the V_in/V_out interface that the paper's
// rule does not make principal and that are in no level set (1 and 4; 2 is in
// S1, 3 is not on the interface) stay out of S, go to S0 after the principal
// primitives, or form a last level set, larger alpha-shape first.
TEST(LevelSets, UncoveredSurfacePrimitivesArePlacedByRule) {
  std::vector<Primitive> prims(5);
  const double areas[5] = {10, 1, 3, 2, 5};
  for (size_t i = 0; i < prims.size(); ++i) prims[i].alpha_area = areas[i];
  IoView view;
  view.principal = {1, 0, 0, 0, 0};
  view.on_surface = {1, 1, 1, 0, 1};
  SortedPrimitives start;
  start.order = {0, 2};
  start.level_of = {0, -1, 1, -1, -1};
  start.cluster_of = {-1, -1, 0, -1, -1};
  start.num_levels = 2;
  SortedPrimitives noise = start, s0 = start, last = start;
  EXPECT_EQ(place_uncovered(prims, view, Uncovered::Noise, noise), 0);
  EXPECT_EQ(noise.order, start.order);
  EXPECT_EQ(noise.level_of, start.level_of);
  EXPECT_EQ(place_uncovered(prims, view, Uncovered::S0, s0), 2);
  EXPECT_EQ(s0.order, (std::vector<int>{0, 4, 1, 2}));
  EXPECT_EQ(s0.level_of, (std::vector<int>{0, 0, 1, -1, 0}));
  EXPECT_EQ(s0.num_levels, 2);
  EXPECT_EQ(place_uncovered(prims, view, Uncovered::Last, last), 2);
  EXPECT_EQ(last.order, (std::vector<int>{0, 2, 4, 1}));
  EXPECT_EQ(last.level_of, (std::vector<int>{0, 2, 1, -1, 2}));
  EXPECT_EQ(last.num_levels, 3);
}

// The house of test::dormer_house: the main body, then the dormers, then the
// chimney with the windows, each an anchor, in that order.
TEST(LevelSets, DormerHouseAnchorsAddStructureLargestFirst) {
  using S = test::DormerHouseSpec;
  const auto b = test::dormer_house();
  LodParams p;
  p.metrics.samples = 4000;
  const LodResult r = build_lod_tree(b.input, p);
  ASSERT_EQ(r.status, lod::Status::ok) << r.reason;
  EXPECT_EQ(r.stats.add_ons, 3);
  EXPECT_EQ(r.stats.cut_outs, 4);
  EXPECT_EQ(r.stats.level_sets, 2);
  // every detected plane in its level set
  for (const auto& pl : r.planes) {
    if (pl.inlier_points.empty() || pl.level < 0) continue;
    Vec3 c = Vec3::Zero();
    for (const auto& x : pl.inlier_points) c += x;
    c /= double(pl.inlier_points.size());
    const bool above = c.z() > S::H + 0.05, recess = c.y() > 0.05 && c.y() < S::depth + 0.05;
    const bool chimney = above && c.x() > S::cx0 - 0.05;
    const int expected = chimney || recess ? 2 : above ? 1 : 0;
    EXPECT_EQ(pl.level, expected) << "plane centred at " << c.transpose();
  }
  std::vector<const LodModel*> anchors;
  for (const auto& m : r.models) {
    test::expect_closed_solid(m);
    if (m.kind == ModelKind::anchor) anchors.push_back(&m);
  }
  ASSERT_EQ(anchors.size(), 3u);
  const double body = S::L * S::W * S::H, dormers = 2 * S::dw * S::dd * S::dh;
  EXPECT_NEAR(anchors[0]->volume, body, 0.05);
  EXPECT_EQ(anchors[0]->polygons.faces.size(), 6u);
  EXPECT_NEAR(anchors[1]->volume, body + dormers, 0.05);
  EXPECT_NEAR(anchors[2]->volume, b.volume, 0.05);
  EXPECT_EQ(anchors[0]->level, 0);
  EXPECT_EQ(anchors[1]->level, 1);
  EXPECT_EQ(anchors[2]->level, 2);
  // the literal reading of the bandwidth (4 m^3) gives one level set
  p.cluster.volume_scale = VolumeScale::M3;
  EXPECT_EQ(build_lod_tree(b.input, p).stats.level_sets, 1);
}
