// io/weld.hpp: integer vertices within r steps welded into their lowest rank,
// collapsed triangles and zero-volume fins dropped.
#include "citylod/io/weld.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <tuple>

namespace citylod::io {
namespace {

std::set<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> as_set(
    const std::vector<NearPair>& pairs) {
  std::set<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> s;
  for (const auto& p : pairs) s.insert({std::min(p.a, p.b), std::max(p.a, p.b), p.d});
  return s;
}

TEST(Weld, NearPairsAreEveryPairWithinRStepsOnEveryAxis) {
  const std::vector<std::array<std::int64_t, 3>> pts = {
      {0, 0, 0}, {1, 0, 0}, {3, 0, 0}, {1, 2, 0}, {1, 0, -2}, {100, 100, 100}, {0, 0, 0}};
  EXPECT_EQ(as_set(near_pairs(pts, 0)), (decltype(as_set({})){{0, 6, 0}}));
  EXPECT_EQ(as_set(near_pairs(pts, 1)), (decltype(as_set({})){{0, 1, 1}, {0, 6, 0}, {1, 6, 1}}));
  EXPECT_EQ(as_set(near_pairs(pts, 2)), (decltype(as_set({})){{0, 1, 1},
                                                              {0, 3, 2},
                                                              {0, 4, 2},
                                                              {0, 6, 0},
                                                              {1, 2, 2},
                                                              {1, 3, 2},
                                                              {1, 4, 2},
                                                              {1, 6, 1},
                                                              {2, 3, 2},
                                                              {2, 4, 2},
                                                              {3, 4, 2},
                                                              {3, 6, 2},
                                                              {4, 6, 2}}));
  EXPECT_EQ(near_pairs(pts, 2).size(), 13u);  // each pair once
}

TEST(Weld, ClustersJoinTransitivelyIntoTheirLowestRank) {
  // a chain 0 - 1 - 2 one step apart, 3 two steps from 2, 4 alone
  const std::vector<std::array<std::int64_t, 3>> pts = {
      {0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {4, 0, 0}, {50, 0, 0}};
  const auto pairs = near_pairs(pts, 2);
  const std::vector<std::uint32_t> by_index = {0, 1, 2, 3, 4}, reversed = {4, 3, 2, 1, 0};
  EXPECT_EQ(weld(pairs, 0, by_index), (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(weld(pairs, 1, by_index), (std::vector<std::uint32_t>{0, 0, 0, 3, 4}));
  EXPECT_EQ(weld(pairs, 2, by_index), (std::vector<std::uint32_t>{0, 0, 0, 0, 4}));
  EXPECT_EQ(weld(pairs, 1, reversed), (std::vector<std::uint32_t>{2, 2, 2, 3, 4}));
  EXPECT_EQ(weld(pairs, 2, reversed), (std::vector<std::uint32_t>{3, 3, 3, 3, 4}));
}

TEST(Weld, CollapsedTrianglesAndFinsGo) {
  const std::vector<std::array<std::uint32_t, 3>> tris = {
      {0, 1, 2},              // kept
      {3, 3, 4},              // collapsed
      {5, 6, 7},              // a fin with the next one (reversed, rotated): both go
      {6, 5, 7},  {1, 2, 0},  // the same triangle as the first, rotated: kept (no fin)
      {8, 9, 10}, {9, 8, 10}, {10, 9, 8}};  // a fin, then the reverse of its first again: kept
  std::vector<std::size_t> from;
  const auto kept = drop_collapsed_and_fins(tris, from);
  EXPECT_EQ(kept, (std::vector<std::array<std::uint32_t, 3>>{{0, 1, 2}, {1, 2, 0}, {10, 9, 8}}));
  EXPECT_EQ(from, (std::vector<std::size_t>{0, 4, 7}));
}

}  // namespace
}  // namespace citylod::io
