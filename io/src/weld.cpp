#include "citylod/io/weld.hpp"

#include <algorithm>
#include <cstdlib>
#include <map>
#include <numeric>
#include <stdexcept>

namespace citylod::io {

std::vector<NearPair> near_pairs(const std::vector<std::array<std::int64_t, 3>>& points,
                                 std::uint32_t r) {
  std::vector<std::uint32_t> by_x(points.size());
  std::iota(by_x.begin(), by_x.end(), 0u);
  std::sort(by_x.begin(), by_x.end(), [&](std::uint32_t a, std::uint32_t b) {
    return points[a] < points[b] || (points[a] == points[b] && a < b);
  });
  std::vector<NearPair> out;
  const std::int64_t rr = std::int64_t(r);
  for (std::size_t i = 0; i < by_x.size(); ++i) {
    const auto& p = points[by_x[i]];
    for (std::size_t j = i + 1; j < by_x.size() && points[by_x[j]][0] - p[0] <= rr; ++j) {
      const auto& q = points[by_x[j]];
      const std::int64_t dy = std::llabs(q[1] - p[1]), dz = std::llabs(q[2] - p[2]);
      if (dy <= rr && dz <= rr)
        out.push_back({by_x[i], by_x[j], std::uint32_t(std::max({q[0] - p[0], dy, dz}))});
    }
  }
  return out;
}

std::vector<std::uint32_t> weld(const std::vector<NearPair>& pairs, std::uint32_t r,
                                const std::vector<std::uint32_t>& rank) {
  std::vector<std::uint32_t> parent(rank.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const NearPair& p : pairs) {
    if (p.d > r) continue;
    if (p.a >= rank.size() || p.b >= rank.size()) throw std::out_of_range("weld: pair index");
    const std::uint32_t x = find(p.a), y = find(p.b);
    if (x == y) continue;
    if (rank[x] < rank[y])  // the root stays the lowest rank of its cluster
      parent[y] = x;
    else
      parent[x] = y;
  }
  std::vector<std::uint32_t> out(rank.size());
  for (std::uint32_t i = 0; i < out.size(); ++i) out[i] = find(i);
  return out;
}

std::vector<std::array<std::uint32_t, 3>> drop_collapsed_and_fins(
    const std::vector<std::array<std::uint32_t, 3>>& triangles, std::vector<std::size_t>& from) {
  auto canonical = [](std::array<std::uint32_t, 3> t) {  // rotated: the smallest id first
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    return t;
  };
  std::vector<std::array<std::uint32_t, 3>> out;
  std::vector<std::size_t> src;
  std::vector<char> dead;
  std::map<std::array<std::uint32_t, 3>, std::size_t> seen;
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const auto& t = triangles[i];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    const auto opp = seen.find(canonical({t[0], t[2], t[1]}));
    if (opp != seen.end() && !dead[opp->second]) {
      dead[opp->second] = 1;  // a fin: both go
      seen.erase(opp);
      continue;
    }
    seen[canonical(t)] = out.size();
    out.push_back(t);
    src.push_back(i);
    dead.push_back(0);
  }
  std::vector<std::array<std::uint32_t, 3>> kept;
  from.clear();
  for (std::size_t i = 0; i < out.size(); ++i)
    if (!dead[i]) {
      kept.push_back(out[i]);
      from.push_back(src[i]);
    }
  return kept;
}

}  // namespace citylod::io
