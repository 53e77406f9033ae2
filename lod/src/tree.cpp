// LOD-Tree construction and traversal (paper Section 4.2, Algorithm 1).
#include "tree.hpp"

#include <algorithm>
#include <map>
#include <set>

namespace citylod::lod::detail {

LodTree build_tree(const Bsp& bsp, const SortedPrimitives& sorted, const Grouping& grouping,
                   const std::vector<std::vector<char>>& leaf_labels, const TreeParams& p) {
  LodTree t;
  t.num_levels = sorted.num_levels;
  const auto& bn = bsp.nodes();
  const size_t L = size_t(t.num_levels);
  t.vin.assign(bn.size(), std::vector<double>(L, 0.0));
  t.label.assign(bn.size(), std::vector<char>(L, 0));
  const auto leaves = bsp.leaves();
  for (size_t i = 0; i < leaves.size(); ++i) t.label[size_t(leaves[i])] = leaf_labels[i];

  // Post-order accumulation of in-volumes (explicit stack).
  {
    std::vector<std::pair<int, bool>> stack{{0, false}};
    while (!stack.empty()) {
      auto [n, done] = stack.back();
      stack.pop_back();
      const auto& node = bn[size_t(n)];
      if (node.is_leaf()) {
        for (size_t k = 0; k < L; ++k)
          t.vin[size_t(n)][k] = t.label[size_t(n)][k] ? node.volume : 0.0;
        continue;
      }
      if (!done) {
        ++t.bsp_internal_nodes;
        stack.push_back({n, true});
        stack.push_back({node.children[1], false});
        stack.push_back({node.children[0], false});
      } else {
        for (size_t k = 0; k < L; ++k)
          t.vin[size_t(n)][k] =
              t.vin[size_t(node.children[0])][k] + t.vin[size_t(node.children[1])][k];
      }
    }
  }

  // Clusters whose primitives are merged into multi-branch LOD-nodes.
  std::vector<char> merge_cluster(grouping.clusters.size(), 0);
  for (size_t c = 0; c < grouping.clusters.size(); ++c) {
    const auto& cl = grouping.clusters[c];
    const double per_structure =
        double(cl.primitives.size()) / double(std::max<size_t>(1, cl.structures.size()));
    merge_cluster[c] = per_structure < double(p.merge_k) ? 1 : 0;
  }
  auto cluster_of_node = [&](int n) {
    const int prim = bn[size_t(n)].split_primitive;
    return prim >= 0 ? sorted.cluster_of[size_t(prim)] : -1;
  };
  auto level_of_node = [&](int n) {
    const int prim = bn[size_t(n)].split_primitive;
    if (prim == kBoxCut) return 0;  // the data-box cuts come first, at level 0
    if (prim < 0) return t.num_levels;
    const int lv = sorted.level_of[size_t(prim)];
    return lv >= 0 ? lv : t.num_levels - 1;
  };

  // Build LOD-nodes top-down (explicit stack), children in BSP order.
  t.nodes.push_back(LodNode{});
  std::vector<std::pair<int, int>> work{{0, 0}};  // (lod node, bsp node)
  while (!work.empty()) {
    auto [ln, b] = work.back();
    work.pop_back();
    t.nodes[size_t(ln)].bsp = b;
    if (bn[size_t(b)].is_leaf()) {
      t.nodes[size_t(ln)].level = t.num_levels;
      continue;
    }
    t.nodes[size_t(ln)].level = level_of_node(b);
    const int cl = cluster_of_node(b);
    const bool merge = cl >= 0 && merge_cluster[size_t(cl)];
    std::vector<int> boundary;
    int cuts = 0;
    std::vector<int> frontier{b};
    while (!frontier.empty()) {  // depth-first, left to right
      const int m = frontier.back();
      frontier.pop_back();
      ++cuts;
      for (int ci = 1; ci >= 0; --ci) {
        const int c = bn[size_t(m)].children[size_t(ci)];
        if (merge && !bn[size_t(c)].is_leaf() && cluster_of_node(c) == cl)
          frontier.push_back(c);
        else
          boundary.push_back(c);
      }
    }
    // boundary was collected in a stack-dependent order; sort by BSP id for determinism
    std::sort(boundary.begin(), boundary.end());
    t.nodes[size_t(ln)].cuts = cuts;
    for (int c : boundary) {
      const int id = int(t.nodes.size());
      t.nodes.push_back(LodNode{});
      t.nodes[size_t(ln)].children.push_back(id);
      work.push_back({id, c});
    }
  }
  return t;
}

namespace {

struct LevelState {
  const LodTree& t;
  const Bsp& bsp;
  double ratio;
  int level = 0;
  bool x(int ln) const {
    const auto& node = t.nodes[size_t(ln)];
    const int b = node.bsp;
    if (node.is_leaf()) return t.label[size_t(b)][size_t(level)] != 0;
    const double V = bsp.nodes()[size_t(b)].volume;
    return V > 0 && t.vin[size_t(b)][size_t(level)] >= ratio * V;
  }
  double d(int ln) const {
    const auto& node = t.nodes[size_t(ln)];
    if (node.is_leaf() || node.level > level) return 0.0;
    const int b = node.bsp;
    const double V = bsp.nodes()[size_t(b)].volume;
    const double vin = t.vin[size_t(b)][size_t(level)];
    return x(ln) ? std::max(0.0, V - vin) : vin;
  }
};

}  // namespace

std::vector<Candidate> traverse(const LodTree& tree, const Bsp& bsp, const TreeParams& p,
                                std::chrono::steady_clock::time_point deadline) {
  std::vector<Candidate> out;
  LevelState st{tree, bsp, p.label_volume_ratio};
  const double eps = 1e-9 * std::max(1e-9, bsp.nodes()[0].volume);
  std::set<int> Q{0};
  std::set<std::pair<double, int>> heap;  // (-d, lod node)
  double sum = 0.0;
  int cuts = 0;
  auto rebuild = [&]() {
    heap.clear();
    sum = 0.0;
    for (int n : Q) {
      const double d = st.d(n);
      if (d > eps) heap.insert({-d, n});
      sum += d;
    }
  };
  auto extract = [&](ModelKind kind) {
    Candidate c;
    c.kind = kind;
    c.level = st.level;
    c.step = int(out.size());
    c.cuts = cuts;
    c.diff_sum = sum < eps ? 0.0 : sum;
    for (int n : Q) {
      c.partition.push_back(tree.nodes[size_t(n)].bsp);
      c.inside.push_back(st.x(n) ? 1 : 0);
    }
    out.push_back(std::move(c));
  };
  auto same_as_last = [&]() {
    if (out.empty()) return false;
    const auto& last = out.back();
    if (last.partition.size() != Q.size()) return false;
    size_t i = 0;
    for (int n : Q) {
      if (last.partition[i] != tree.nodes[size_t(n)].bsp || last.inside[i] != (st.x(n) ? 1 : 0))
        return false;
      ++i;
    }
    return true;
  };

  rebuild();
  double last_sum = sum, level_start_sum = sum;
  while (st.level < tree.num_levels) {
    if (std::chrono::steady_clock::now() > deadline) throw LodBudgetExceeded("traversal");
    if (heap.empty()) {  // DiffSum(Q) == 0: an anchor
      if (!same_as_last()) {
        extract(ModelKind::anchor);
      } else if (out.back().kind == ModelKind::interpolation) {
        out.back().kind =
            ModelKind::anchor;  // the last interpolation already is this level's anchor
        out.back().level = st.level;
        out.back().diff_sum = 0.0;
      }  // else: this level set changes nothing; the previous anchor stands for it
      ++st.level;
      if (st.level < tree.num_levels) {
        rebuild();
        last_sum = level_start_sum = sum;
      }
      continue;
    }
    const int n = heap.begin()->second;
    heap.erase(heap.begin());
    sum -= st.d(n);
    Q.erase(n);
    cuts += tree.nodes[size_t(n)].cuts;
    for (int c : tree.nodes[size_t(n)].children) {
      Q.insert(c);
      const double d = st.d(c);
      if (d > eps) heap.insert({-d, c});
      sum += d;
    }
    if (sum < 0) sum = 0;
    if (!heap.empty() && sum > eps && sum < p.interpolation_ratio * last_sum &&
        sum >= p.interpolation_floor * level_start_sum) {
      extract(ModelKind::interpolation);
      last_sum = sum;
    }
  }
  return out;
}

}  // namespace citylod::lod::detail
