// euclidean_clusters (tiler/segment.hpp): the connected sets of points closer than
// the tolerance, as PCL's EuclideanClusterExtraction finds and orders them, checked
// against the test's own scan of every pair.
#include "citylod/tiler/segment.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

namespace citylod::tiler {
namespace {

using Pts = std::vector<std::array<float, 3>>;

/// The clusters by a scan of all pairs (union-find), in seed order, each ascending,
/// filtered and sorted as PCL does.
std::vector<std::vector<std::uint32_t>> reference(const Pts& p, double tol, std::size_t min_size) {
  const double t = double(float(tol));
  const float r2 = float(t * t);
  std::vector<std::uint32_t> parent(p.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (std::uint32_t a = 0; a < p.size(); ++a)
    for (std::uint32_t b = a + 1; b < p.size(); ++b) {
      float d = 0, e;
      for (std::size_t k = 0; k < 3; ++k) {
        e = p[a][k] - p[b][k];
        d += e * e;
      }
      if (d < r2) parent[find(a)] = find(b);
    }
  std::vector<std::vector<std::uint32_t>> out;
  std::vector<int> slot(p.size(), -1);
  for (std::uint32_t i = 0; i < p.size(); ++i) {  // clusters in the order of their lowest index
    const std::uint32_t r = find(i);
    if (slot[r] < 0) {
      slot[r] = int(out.size());
      out.emplace_back();
    }
    out[std::size_t(slot[r])].push_back(i);
  }
  out.erase(
      std::remove_if(out.begin(), out.end(), [&](const auto& c) { return c.size() < min_size; }),
      out.end());
  std::sort(out.rbegin(), out.rend(),
            [](const auto& a, const auto& b) { return a.size() < b.size(); });
  return out;
}

TEST(EuclideanClusters, SameAsAScanOfEveryPair) {
  std::uint64_t s = 7;
  auto rnd = [&]() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return float(double(s >> 11) / double(1ULL << 53));
  };
  for (const double tol : {0.5, 1.0, 2.5}) {
    Pts p;
    for (int i = 0; i < 1500; ++i) p.push_back({60 * rnd() - 30, 40 * rnd() - 20, 0.0f});
    // chains of points exactly one tolerance apart (not neighbours: the test is <) and
    // just under it (neighbours), across cell borders and negative coordinates
    const float t = float(tol);
    for (int i = 0; i < 20; ++i) p.push_back({-5.0f + float(i) * t, 33.0f, 0.0f});
    for (int i = 0; i < 20; ++i) p.push_back({-5.0f + float(i) * t * 0.999f, 36.0f, 0.0f});
    for (const std::size_t min_size : {std::size_t(1), std::size_t(3), std::size_t(30)}) {
      const auto got = euclidean_clusters(p, tol, min_size);
      EXPECT_EQ(got, reference(p, tol, min_size)) << "tolerance " << tol << ", min " << min_size;
    }
  }
  EXPECT_TRUE(euclidean_clusters({}, 1.0, 1).empty());
}

TEST(EuclideanClusters, TwoBlocksAndAChain) {
  Pts p;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) p.push_back({float(i), float(j), 0});        // 25 points, 1 m apart
  for (int i = 0; i < 3; ++i) p.push_back({20.0f + 0.9f * float(i), 0, 0});  // 3 points
  p.push_back({50, 50, 0});                                                  // alone
  const auto c = euclidean_clusters(p, 1.0, 2);  // 1 m apart: not neighbours (< 1 m)
  EXPECT_EQ(c, (std::vector<std::vector<std::uint32_t>>{{25, 26, 27}}));
  const auto d = euclidean_clusters(p, 1.01, 2);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].size(), 25u);  // the largest first
  EXPECT_EQ(d[1], (std::vector<std::uint32_t>{25, 26, 27}));
}

}  // namespace
}  // namespace citylod::tiler
