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

std::vector<std::size_t> remove_collinear_spikes(
    std::vector<std::vector<std::uint32_t>>& faces,
    const std::vector<std::array<std::int64_t, 3>>& points) {
  using I = __int128;
  auto at = [&](std::uint32_t q) { return points[q]; };
  auto collinear_tip = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
    const auto a = at(i), b = at(j), c = at(k);
    const I u[3] = {I(a[0]) - b[0], I(a[1]) - b[1], I(a[2]) - b[2]};
    const I v[3] = {I(c[0]) - b[0], I(c[1]) - b[1], I(c[2]) - b[2]};
    const bool line =
        u[1] * v[2] == u[2] * v[1] && u[2] * v[0] == u[0] * v[2] && u[0] * v[1] == u[1] * v[0];
    return line && u[0] * v[0] + u[1] * v[1] + u[2] * v[2] > 0;
  };
  auto dist2 = [&](std::uint32_t i, std::uint32_t j) {
    const auto a = at(i), b = at(j);
    I d = 0;
    for (int k = 0; k < 3; ++k)
      d += (I(a[std::size_t(k)]) - b[std::size_t(k)]) * (I(a[std::size_t(k)]) - b[std::size_t(k)]);
    return d;
  };
  // Puts `m` between the ends of the directed edge a -> b of some face; false if none has it.
  auto insert_on_edge = [&](std::uint32_t a, std::uint32_t b, std::uint32_t m) {
    for (auto& g : faces)
      for (std::size_t x = 0; x < g.size(); ++x)
        if (g[x] == a && g[(x + 1) % g.size()] == b) {
          g.insert(g.begin() + long(x + 1), m);
          return true;
        }
    return false;
  };
  for (std::size_t guard = 0, changed = 1; changed && guard < 4 * faces.size() + 16; ++guard) {
    changed = 0;
    for (auto& f : faces) {
      for (std::size_t x = 0; f.size() >= 3 && x < f.size(); ++x) {
        const std::size_t n = f.size();
        const std::uint32_t i = f[(x + n - 1) % n], j = f[x], k = f[(x + 1) % n];
        if (i == j || j == k) continue;
        if (i == k) {  // a spike onto one vertex: drop the tip and the return
          f.erase(f.begin() + long(x));
          f.erase(f.begin() + long(x < f.size() ? x : 0));
          changed = 1;
          break;
        }
        if (!collinear_tip(i, j, k)) continue;
        // the nearer of i, k lies between j and the farther one
        const bool k_nearer = dist2(k, j) < dist2(i, j);
        if (!(k_nearer ? insert_on_edge(j, i, k) : insert_on_edge(k, j, i))) continue;
        // (the insertion may have been into f itself: find j again)
        f.erase(std::find(f.begin(), f.end(), j));
        changed = 1;
        break;
      }
    }
  }
  std::vector<std::size_t> kept;
  std::vector<std::vector<std::uint32_t>> out;
  for (std::size_t fi = 0; fi < faces.size(); ++fi)
    if (faces[fi].size() >= 3) {
      kept.push_back(fi);
      out.push_back(std::move(faces[fi]));
    }
  faces = std::move(out);
  return kept;
}

}  // namespace citylod::io
