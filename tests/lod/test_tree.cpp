// The LOD-Tree (paper Section 4.2): build_tree's LOD-nodes over a BSP (clusters
// of fewer than K primitives per structure merged into one multi-branch node),
// the in-volumes per level, and traverse(), Algorithm 1, with exact answers on
// a small house: the 10 m data box, a 6 m cube of six principal planes (level
// set S0) and a 2 x 2 x 1 m chimney of five planes on its roof (one cluster of
// one structure, level set S1).
#include "bsp.hpp"
#include "grouping.hpp"
#include "tree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace citylod::lod::detail {
namespace {

// Axis-aligned rectangle on the plane coordinate `axis` == v, spanning [a0,a1]
// x [b0,b1] on the other two axes (cyclic), as the BSP polygon of `prim`.
BspPolygon rect(int axis, double v, double a0, double a1, double b0, double b1, int prim) {
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;
  const double uv[4][2] = {{a0, b0}, {a1, b0}, {a1, b1}, {a0, b1}};
  BspPolygon p;
  for (const auto& c : uv) {
    Vec3 q = Vec3::Zero();
    q[axis] = v;
    q[u] = c[0];
    q[w] = c[1];
    p.polygon.push_back(q);
  }
  p.plane = {0, 0, 0, -v};
  p.plane[size_t(axis)] = 1;
  p.primitive = prim;
  return p;
}

bool inside_box(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return (p.array() > lo.array()).all() && (p.array() < hi.array()).all();
}

const Vec3 kCubeLo(2, 2, 2), kCubeHi(8, 8, 8);        // the house (S0)
const Vec3 kChimneyLo(4, 4, 8), kChimneyHi(6, 6, 9);  // on its roof (S1)

/// The house's BSP, primitives, grouping and per-level leaf labels.
struct House {
  Bsp bsp;
  SortedPrimitives sorted;
  Grouping grouping;
  std::vector<std::vector<char>> leaf_labels;

  /// `levels` = N_l + 1 (3: one more level set that adds nothing);
  /// `structures`: how many structures the chimney's cluster counts.
  explicit House(int levels = 2, int structures = 1) : bsp(make_bsp()) {
    sorted.order = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
    sorted.level_of = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1};
    sorted.cluster_of = {-1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0};
    sorted.num_levels = levels;
    Grouping::Cluster chimney;
    chimney.host = 0;
    for (int s = 0; s < structures; ++s) chimney.structures.push_back(s);
    chimney.primitives = {6, 7, 8, 9, 10};
    chimney.level = 1;
    grouping.clusters.push_back(chimney);
    grouping.num_level_sets = 1;
    for (int leaf : bsp.leaves()) {
      const Vec3& c = bsp.nodes()[size_t(leaf)].center;
      const char in0 = inside_box(c, kCubeLo, kCubeHi);
      const char in1 = in0 || inside_box(c, kChimneyLo, kChimneyHi);
      std::vector<char> l{in0};
      while (int(l.size()) < levels) l.push_back(in1);
      leaf_labels.push_back(l);
    }
  }
  static Bsp make_bsp() {
    std::vector<BspPolygon> polys = {
        rect(2, 2, 2, 8, 2, 8, 0),  rect(2, 8, 2, 8, 2, 8, 1),  // bottom, roof
        rect(0, 2, 2, 8, 2, 8, 2),  rect(0, 8, 2, 8, 2, 8, 3),  // x walls
        rect(1, 2, 2, 8, 2, 8, 4),  rect(1, 8, 2, 8, 2, 8, 5),  // y walls
        rect(0, 4, 4, 6, 8, 9, 6),  rect(0, 6, 4, 6, 8, 9, 7),  // chimney x walls (y, z)
        rect(1, 4, 8, 9, 4, 6, 8),  rect(1, 6, 8, 9, 4, 6, 9),  // chimney y walls (z, x)
        rect(2, 9, 4, 6, 4, 6, 10),                             // chimney top
    };
    return Bsp(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  }
  LodTree tree(int merge_k = TreeParams{}.merge_k) const {
    TreeParams p;
    p.merge_k = merge_k;
    return build_tree(bsp, sorted, grouping, leaf_labels, p);
  }
  double volume(int bsp_node) const { return bsp.nodes()[size_t(bsp_node)].volume; }
};

std::chrono::steady_clock::time_point no_deadline() {
  return std::chrono::steady_clock::now() + std::chrono::hours(1);
}

std::string kind(const Candidate& c) {
  return to_string(c.kind);
}

/// A candidate's cells as (volume, inside), sorted: what it models, whatever the node ids.
std::vector<std::pair<double, int>> cells(const House& h, const Candidate& c) {
  std::vector<std::pair<double, int>> v;
  for (size_t i = 0; i < c.partition.size(); ++i)
    v.push_back({std::round(h.volume(c.partition[i]) * 1e6) / 1e6, int(c.inside[i])});
  std::sort(v.begin(), v.end());
  return v;
}
using Cells = std::vector<std::pair<double, int>>;

// The cells of the house: below it (z < 2: 200 m^3), beside it (x < 2, x > 8: 120
// each; y < 2, y > 8 within 2 < x < 8: 72 each), the cube (216), and above it
// (z > 8: 200), which the chimney cuts into x < 4, x > 6 (80 each), y < 4, y > 6
// (16 each), the chimney (4) and the air above it (4).
const Cells kLevel0Anchor = {{72, 0}, {72, 0}, {120, 0}, {120, 0}, {200, 0}, {200, 0}, {216, 1}};
const Cells kLeaves = {{4, 0},  {4, 1},  {16, 0},  {16, 0},  {72, 0},  {72, 0},
                       {80, 0}, {80, 0}, {120, 0}, {120, 0}, {200, 0}, {216, 1}};

TEST(LodTree, TheHouseBsp) {
  const House h;
  EXPECT_EQ(h.bsp.nodes().size(), 23u);  // 11 splits, one per primitive
  EXPECT_EQ(h.bsp.leaves().size(), 12u);
  EXPECT_NEAR(h.volume(0), 1000.0, 1e-9);
}

// K = 10: the chimney's cluster has 5 primitives per structure, so its five BSP
// splits are one LOD-node with the six cells as children; the principal planes
// (no cluster) stay binary.
TEST(LodTree, AClusterOfFewerThanKPrimitivesPerStructureIsOneNode) {
  const House h;
  const LodTree t = h.tree();
  EXPECT_EQ(t.num_levels, 2);
  EXPECT_EQ(t.bsp_internal_nodes, 11);
  ASSERT_EQ(t.nodes.size(), 19u);  // 23 BSP nodes, 4 merged away
  EXPECT_EQ(t.nodes[0].bsp, 0);
  int cuts = 0, merged = 0;
  std::vector<int> leaves;
  for (const LodNode& n : t.nodes) {
    cuts += n.cuts;
    if (n.is_leaf()) {
      EXPECT_EQ(n.level, 2);  // leaves: num_levels
      EXPECT_EQ(n.cuts, 0);
      leaves.push_back(n.bsp);
      continue;
    }
    if (n.level == 0) {  // a principal plane's split
      EXPECT_EQ(n.cuts, 1);
      EXPECT_EQ(n.children.size(), 2u);
      continue;
    }
    ++merged;  // the chimney: level 1, five cuts at once, six cells
    EXPECT_EQ(n.level, 1);
    EXPECT_EQ(n.cuts, 5);
    EXPECT_NEAR(h.volume(n.bsp), 200.0, 1e-9);  // the air above the roof
    ASSERT_EQ(n.children.size(), 6u);
    std::vector<int> child_bsp;
    for (int c : n.children) {
      EXPECT_TRUE(t.nodes[size_t(c)].is_leaf());
      child_bsp.push_back(t.nodes[size_t(c)].bsp);
    }
    EXPECT_TRUE(std::is_sorted(child_bsp.begin(), child_bsp.end()));  // BSP order
    std::vector<double> vol;
    for (int b : child_bsp) vol.push_back(std::round(h.volume(b)));
    std::sort(vol.begin(), vol.end());
    EXPECT_EQ(vol, (std::vector<double>{4, 4, 16, 16, 80, 80}));
  }
  EXPECT_EQ(merged, 1);
  EXPECT_EQ(cuts, t.bsp_internal_nodes);  // every BSP split in exactly one LOD-node
  std::sort(leaves.begin(), leaves.end());
  EXPECT_EQ(leaves, h.bsp.leaves());  // the finest nodes are the BSP's leaves
}

// K is a strict bound: 5 primitives per structure merge under K = 6, not under
// K = 5; spread over two structures (2.5 each) they merge under K = 3.
TEST(LodTree, MergingNeedsFewerThanKPrimitivesPerStructure) {
  const House one, two(2, 2);
  EXPECT_EQ(one.tree(6).nodes.size(), 19u);
  EXPECT_EQ(two.tree(3).nodes.size(), 19u);
  EXPECT_EQ(two.tree(2).nodes.size(), 23u);
  const LodTree binary = one.tree(5);
  ASSERT_EQ(binary.nodes.size(), 23u);  // the BSP itself: one LOD-node per BSP node
  std::vector<int> bsp_ids;
  int chimney_nodes = 0;
  for (const LodNode& n : binary.nodes) {
    bsp_ids.push_back(n.bsp);
    if (n.is_leaf()) continue;
    EXPECT_EQ(n.cuts, 1);
    EXPECT_EQ(n.children.size(), 2u);
    chimney_nodes += n.level == 1;
  }
  EXPECT_EQ(chimney_nodes, 5);
  std::sort(bsp_ids.begin(), bsp_ids.end());
  for (int i = 0; i < 23; ++i) EXPECT_EQ(bsp_ids[size_t(i)], i);
}

// vin[n][k]: the volume of n's leaves labelled in at level k.
TEST(LodTree, InVolumesPerLevel) {
  const House h;
  const LodTree t = h.tree();
  ASSERT_EQ(t.vin.size(), h.bsp.nodes().size());
  EXPECT_NEAR(t.vin[0][0], 216.0, 1e-9);  // the cube
  EXPECT_NEAR(t.vin[0][1], 220.0, 1e-9);  // and the chimney
  for (const LodNode& n : t.nodes) {
    if (!n.is_leaf() && n.level == 1) {
      EXPECT_NEAR(t.vin[size_t(n.bsp)][0], 0.0, 1e-9);
      EXPECT_NEAR(t.vin[size_t(n.bsp)][1], 4.0, 1e-9);
    }
  }
  const auto leaves = h.bsp.leaves();
  for (size_t i = 0; i < leaves.size(); ++i) {
    const auto b = size_t(leaves[i]);
    EXPECT_EQ(t.label[b], h.leaf_labels[i]);
    for (int k = 0; k < 2; ++k)
      EXPECT_EQ(t.vin[b][size_t(k)], h.leaf_labels[i][size_t(k)] ? h.volume(leaves[i]) : 0.0);
  }
}

// Algorithm 1 with the paper's defaults (65 %, 80 %). Level 0: the root holds
// 216 of 1000 m^3 in (out, diff 216); cutting the bottom, roof, x walls and the
// first y wall keeps the diff at 216 until the cell 2<x<8, 2<y<10, 2<z<8 (288
// m^3, 75 % in) is labelled in: diff 72 < 80 % of 216, an interpolation model
// after 5 cuts; the last y wall makes the level-0 anchor (6 cuts). Level 1: the
// chimney node (diff 4) is cut at once: the level-1 anchor, all 11 cuts, the
// BSP's leaves with their labels.
TEST(LodTree, TraversalExtractsTheInterpolationAndAnchorsOfEachLevel) {
  const House h;
  const auto c = traverse(h.tree(), h.bsp, TreeParams{}, no_deadline());
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(kind(c[0]), "interpolation");
  EXPECT_EQ(c[0].level, 0);
  EXPECT_EQ(c[0].step, 0);
  EXPECT_EQ(c[0].cuts, 5);
  EXPECT_NEAR(c[0].diff_sum, 72.0, 1e-9);
  EXPECT_EQ(cells(h, c[0]), (Cells{{72, 0}, {120, 0}, {120, 0}, {200, 0}, {200, 0}, {288, 1}}));

  EXPECT_EQ(kind(c[1]), "anchor");
  EXPECT_EQ(c[1].level, 0);
  EXPECT_EQ(c[1].step, 1);
  EXPECT_EQ(c[1].cuts, 6);
  EXPECT_EQ(c[1].diff_sum, 0.0);
  EXPECT_EQ(cells(h, c[1]), kLevel0Anchor);

  EXPECT_EQ(kind(c[2]), "anchor");
  EXPECT_EQ(c[2].level, 1);
  EXPECT_EQ(c[2].step, 2);
  EXPECT_EQ(c[2].cuts, 11);
  EXPECT_EQ(c[2].diff_sum, 0.0);
  EXPECT_EQ(cells(h, c[2]), kLeaves);
  std::vector<int> finest = c[2].partition;
  std::sort(finest.begin(), finest.end());
  EXPECT_EQ(finest, h.bsp.leaves());  // the finest model is the BSP's leaves
  const auto leaves = h.bsp.leaves();
  for (size_t i = 0; i < c[2].partition.size(); ++i) {
    const auto at = std::find(leaves.begin(), leaves.end(), c[2].partition[i]) - leaves.begin();
    EXPECT_EQ(c[2].inside[i], h.leaf_labels[size_t(at)][1]);  // with the last level's labels
  }
}

// The chimney cut split by split (K = 1) keeps the diff at 4 m^3 until its last
// cut: no interpolation, the same candidates.
TEST(LodTree, TheChimneyCutOneByOneGivesTheSameCandidates) {
  const House h;
  const auto merged = traverse(h.tree(), h.bsp, TreeParams{}, no_deadline());
  const auto binary = traverse(h.tree(1), h.bsp, TreeParams{}, no_deadline());
  ASSERT_EQ(binary.size(), merged.size());
  for (size_t i = 0; i < merged.size(); ++i) {
    EXPECT_EQ(binary[i].kind, merged[i].kind);
    EXPECT_EQ(binary[i].cuts, merged[i].cuts);
    EXPECT_EQ(cells(h, binary[i]), cells(h, merged[i]));
  }
}

// A level set that changes no label adds no anchor: the previous one stands.
TEST(LodTree, ALevelThatChangesNothingAddsNoModel) {
  const House h(3);
  const LodTree t = h.tree();
  EXPECT_EQ(t.num_levels, 3);
  for (const LodNode& n : t.nodes) {
    if (n.is_leaf()) {
      EXPECT_EQ(n.level, 3);
    }
  }
  const auto c = traverse(t, h.bsp, TreeParams{}, no_deadline());
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(kind(c[2]), "anchor");
  EXPECT_EQ(c[2].level, 1);
  EXPECT_EQ(cells(h, c[2]), kLeaves);
}

// With a 20 % label ratio every cell holding the cube is in: the diff of a node
// is then its out-volume, 784 m^3 at the root, and each principal cut shrinks
// it below 80 % of the last model's: 584, 384, 264, 144, 72.
TEST(LodTree, InterpolationsFollowTheRatioAndTheFloor) {
  const House h;
  TreeParams p;
  p.label_volume_ratio = 0.2;
  auto summary = [&](const TreeParams& q) {
    std::vector<std::pair<int, double>> v;  // (cuts, diff sum) of the interpolations
    int anchors = 0;
    for (const Candidate& c : traverse(h.tree(), h.bsp, q, no_deadline())) {
      if (kind(c) == "anchor")
        ++anchors;
      else
        v.push_back({c.cuts, std::round(c.diff_sum * 1e6) / 1e6});
    }
    EXPECT_EQ(anchors, 2);
    return v;
  };
  using V = std::vector<std::pair<int, double>>;
  EXPECT_EQ(summary(p), (V{{1, 584}, {2, 384}, {3, 264}, {4, 144}, {5, 72}}));
  const auto c = traverse(h.tree(), h.bsp, p, no_deadline());
  ASSERT_EQ(c.size(), 7u);
  EXPECT_EQ(cells(h, c[0]), (Cells{{200, 0}, {800, 1}}));  // below the cube, and the rest
  EXPECT_EQ(cells(h, c[5]), kLevel0Anchor);
  p.interpolation_ratio = 0.5;  // below half the last model's: 384 (of 784), 144 (of 384)
  EXPECT_EQ(summary(p), (V{{2, 384}, {4, 144}}));
  p.interpolation_ratio = 0.8;
  p.interpolation_floor = 0.2;  // none below 20 % of 784
  EXPECT_EQ(summary(p), (V{{1, 584}, {2, 384}, {3, 264}}));
}

// The data box's cuts (kBoxCut) are level 0 whatever the primitives; a split by a
// primitive in no level set counts as the last level.
TEST(LodTree, BoxCutsAreLevelZero) {
  const std::vector<BspPolygon> polys = {
      rect(2, 9, -1, 11, -1, 11, kBoxCut),  // the data box's top
      rect(0, 5, 0, 10, 0, 9, 0),           // a wall of level set 1
      rect(1, 5, 0, 9, 0, 5, 1),            // a primitive in no level set
  };
  const Bsp bsp(Vec3(0, 0, 0), Vec3(10, 10, 10), polys, 0);
  ASSERT_EQ(bsp.nodes().size(), 7u);
  SortedPrimitives sorted;
  sorted.order = {0, 1};
  sorted.level_of = {1, -1};
  sorted.cluster_of = {-1, -1};
  sorted.num_levels = 3;
  const std::vector<std::vector<char>> labels(bsp.leaves().size(), std::vector<char>(3, 0));
  const LodTree t = build_tree(bsp, sorted, Grouping{}, labels, TreeParams{});
  ASSERT_EQ(t.nodes.size(), 7u);
  for (const LodNode& n : t.nodes) {
    const int prim = bsp.nodes()[size_t(n.bsp)].split_primitive;
    const int want = prim == kBoxCut ? 0 : prim == 0 ? 1 : prim == 1 ? 2 : 3;
    EXPECT_EQ(n.level, want) << "split by " << prim;
  }
  EXPECT_EQ(t.nodes[0].level, 0);
  // nothing inside: no diff anywhere, one (empty) anchor
  const auto c = traverse(t, bsp, TreeParams{}, no_deadline());
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].cuts, 0);
  EXPECT_EQ(c[0].partition, std::vector<int>{0});
}

TEST(LodTree, TraversalThrowsPastTheDeadline) {
  const House h;
  const LodTree t = h.tree();
  try {
    traverse(t, h.bsp, TreeParams{}, std::chrono::steady_clock::now() - std::chrono::seconds(1));
    FAIL() << "no LodError";
  } catch (const LodError& e) {
    EXPECT_EQ(e.stage(), "traversal");
  }
}

}  // namespace
}  // namespace citylod::lod::detail
