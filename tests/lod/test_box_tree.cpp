// lod::BoxTree: the least distance over all primitives, whatever the tree.
#include "citylod/lod/box_tree.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace citylod::lod {
namespace {

using Box = BoxTree::Box;

double d2(const Box& a, const Box& b) {
  double s = 0;
  for (std::size_t k = 0; k < 3; ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  return s;
}

/// Deterministic numbers in [0, 1).
struct Lcg {
  std::uint64_t s = 12345;
  double next() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(s >> 11) / double(1ULL << 53);
  }
};

TEST(BoxTree, NearestPointIsTheScansMinimum) {
  Lcg r;
  std::vector<Box> pts(3000);
  for (auto& p : pts) p = {100 * r.next(), 50 * r.next(), 10 * r.next()};
  const BoxTree tree = BoxTree::of_points(pts);
  EXPECT_EQ(tree.size(), pts.size());
  for (int q = 0; q < 500; ++q) {
    const Box p = {120 * r.next() - 10, 70 * r.next() - 10, 30 * r.next() - 10};
    double best = std::numeric_limits<double>::infinity();
    std::uint32_t arg = 0;
    for (std::uint32_t i = 0; i < pts.size(); ++i)
      if (d2(p, pts[i]) < best) best = d2(p, pts[i]), arg = i;
    std::uint32_t which = 99999;
    EXPECT_EQ(tree.nearest2(
                  p, [&](std::uint32_t i) { return d2(p, pts[i]); }, &which),
              best);
    EXPECT_EQ(which, arg);
    // a hint (any primitive) changes nothing but the work
    const std::uint32_t hint = std::uint32_t(q * 7 % 3000);
    which = 99999;
    EXPECT_EQ(tree.nearest2(
                  p, [&](std::uint32_t i) { return d2(p, pts[i]); }, &which, hint),
              best);
    EXPECT_EQ(which, arg);
  }
}

TEST(BoxTree, BoxesOfSegmentsAndTies) {
  // Segments along x at y = 0, 1, 2, ... : the distance to a segment is at
  // least that to its box. Two equal segments: the lower index wins.
  std::vector<Box> lo, hi;
  for (int i = 0; i < 40; ++i) {
    lo.push_back({0.0, double(i / 2), 0.0});  // pairs of identical segments
    hi.push_back({5.0, double(i / 2), 0.0});
  }
  const BoxTree tree(lo, hi);
  auto seg = [&](const Box& p, std::uint32_t i) {
    const double x = std::min(std::max(p[0], 0.0), 5.0);
    return d2(p, {x, lo[i][1], 0.0});
  };
  std::uint32_t which = 0;
  const Box p = {7.0, 6.2, 1.0};
  EXPECT_DOUBLE_EQ(tree.nearest2(
                       p, [&](std::uint32_t i) { return seg(p, i); }, &which),
                   4.0 + 0.04 + 1.0);
  EXPECT_EQ(which, 12u);  // segments 12 and 13 lie at y = 6
  tree.nearest2(
      p, [&](std::uint32_t i) { return seg(p, i); }, &which, 13);
  EXPECT_EQ(which, 12u);  // hinted at the equal segment of higher index: still 12
  // an empty tree
  const BoxTree none({}, {});
  which = 7;
  EXPECT_EQ(none.nearest2(
                p, [](std::uint32_t) { return 0.0; }, &which),
            std::numeric_limits<double>::infinity());
  EXPECT_EQ(which, 7u);
  EXPECT_THROW(BoxTree({{0, 0, 0}}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace citylod::lod
