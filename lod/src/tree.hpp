// Internal: the LOD-Tree (paper Section 4.2): multi-branch LOD-nodes over the
// BSP of the scale-sorted primitives, per-level labels, diff-values, and the
// priority-queue traversal (Algorithm 1) yielding anchor and interpolation
// candidates.
#pragma once

#include "bsp.hpp"
#include "citylod/lod/lod.hpp"
#include "grouping.hpp"

#include <chrono>
#include <vector>

namespace citylod::lod::detail {

struct LodNode {
  int bsp = -1;               ///< BSP node this LOD-node starts at (its polyhedron)
  int level = 0;              ///< level set of the primitives splitting it (num_levels for leaves)
  int cuts = 0;               ///< BSP splits merged into this node
  std::vector<int> children;  ///< LOD-node ids
  bool is_leaf() const { return children.empty(); }
};

struct LodTree {
  std::vector<LodNode> nodes;            ///< nodes[0] is the root
  int num_levels = 1;                    ///< N_l + 1
  std::vector<std::vector<double>> vin;  ///< [bsp node][level]: in-volume of its leaves (m^3)
  std::vector<std::vector<char>> label;  ///< [bsp node][level]: leaf labels (leaves only)
  int bsp_internal_nodes = 0;
};

/// Builds the LOD-Tree: BSP nodes split by primitives of one cluster with fewer
/// than K primitives per structure are merged into one multi-branch LOD-node.
/// `leaf_labels[i][k]` labels bsp.leaves()[i] at level k.
LodTree build_tree(const Bsp& bsp, const SortedPrimitives& sorted, const Grouping& grouping,
                   const std::vector<std::vector<char>>& leaf_labels, const TreeParams& p);

/// One candidate model as a labelled cut of the tree.
struct Candidate {
  ModelKind kind = ModelKind::anchor;
  int level = 0;
  int step = 0;
  int cuts = 0;
  double diff_sum = 0.0;
  std::vector<int> partition;  ///< BSP node ids
  std::vector<char> inside;    ///< label per partition entry
};

/// Algorithm 1: priority-queue traversal by diff-value. Throws LodError
/// ("budget") when `deadline` passes.
std::vector<Candidate> traverse(const LodTree& tree, const Bsp& bsp, const TreeParams& p,
                                std::chrono::steady_clock::time_point deadline);

}  // namespace citylod::lod::detail
