// Bounding-volume hierarchy over axis-aligned boxes for nearest queries: the
// least squared distance from a point to a set of primitives (points,
// triangles), each measured exactly by the caller's function. Used by the LOD
// engine's e1/e2 (lod/src/fidelity.cpp) and the tiler's Hausdorff distances
// between models (tiler/src/assemble/model_choice.cpp). No CGAL.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace citylod::lod {

/// Median splits on the widest axis of the boxes' centres, leaves of at most 4
/// boxes; a query visits the nearer child first and skips a box farther than
/// the best distance so far. The answer is the minimum of `dist` over all
/// primitives — the value a scan of all of them gives, whatever the tree —
/// because `dist(i)` is never less than the distance to box i (it is skipped
/// with a 1e-9 relative slack for rounding). Ties go to the lower index.
class BoxTree {
 public:
  using Box = std::array<double, 3>;
  static constexpr std::uint32_t kNoHint = ~std::uint32_t(0);
  /// Box i is [lo[i], hi[i]] (lo <= hi per axis).
  BoxTree(std::vector<Box> lo, std::vector<Box> hi);
  /// Boxes of points (zero size).
  static BoxTree of_points(const std::vector<Box>& points);

  std::size_t size() const { return lo_.size(); }

  /// min over i of dist(i), a squared distance from `p` to primitive i that is
  /// >= the squared distance from `p` to box i; its index in `*which` (if not
  /// null; unchanged when the tree is empty). +inf for an empty tree. `hint`: a
  /// primitive likely to be near (e.g. the previous query's answer), measured first
  /// so that more boxes are skipped; the answer does not depend on it.
  template <typename Dist>
  double nearest2(const Box& p, const Dist& dist, std::uint32_t* which = nullptr,
                  std::uint32_t hint = kNoHint) const {
    double best = std::numeric_limits<double>::infinity();
    std::uint32_t arg = 0;
    bool found = false;
    if (nodes_.empty()) return best;
    if (hint < lo_.size()) {
      best = dist(hint);
      arg = hint;
      found = true;
    }
    std::uint32_t stack[128];
    std::size_t top = 0;
    stack[top++] = 0;
    while (top) {
      const Node& n = nodes_[stack[--top]];
      if (skip(box_d2(n.lo, n.hi, p), best)) continue;
      if (n.count) {
        for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
          const std::uint32_t i = order_[k];
          if (n.count > 1 && skip(box_d2(lo_[i], hi_[i], p), best)) continue;
          const double d = dist(i);
          if (d < best || (d == best && found && i < arg)) {
            best = d;
            arg = i;
            found = true;
          }
        }
        continue;
      }
      const Node &l = nodes_[n.left], &r = nodes_[n.right];
      const bool left_first = box_d2(l.lo, l.hi, p) <= box_d2(r.lo, r.hi, p);
      stack[top++] = left_first ? n.right : n.left;
      stack[top++] = left_first ? n.left : n.right;
    }
    if (which && found) *which = arg;
    return best;
  }

 private:
  struct Node {
    Box lo, hi;
    std::uint32_t left = 0, right = 0, first = 0, count = 0;
  };

  static bool skip(double box, double best) { return box > best * (1 + 1e-9) + 1e-20; }
  static double box_d2(const Box& lo, const Box& hi, const Box& p) {
    double d = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      const double e = std::max({lo[k] - p[k], 0.0, p[k] - hi[k]});
      d += e * e;
    }
    return d;
  }
  std::uint32_t build(std::size_t first, std::size_t last);

  std::vector<Box> lo_, hi_;
  std::vector<std::uint32_t> order_;
  std::vector<Node> nodes_;
};

}  // namespace citylod::lod
