#include "citylod/lod/box_tree.hpp"

#include <stdexcept>

namespace citylod::lod {

BoxTree::BoxTree(std::vector<Box> lo, std::vector<Box> hi)
    : lo_(std::move(lo)), hi_(std::move(hi)) {
  if (lo_.size() != hi_.size()) throw std::invalid_argument("BoxTree: lo and hi differ in size");
  if (lo_.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("BoxTree: too many boxes");
  order_.resize(lo_.size());
  for (std::size_t i = 0; i < order_.size(); ++i) order_[i] = std::uint32_t(i);
  if (!order_.empty()) build(0, order_.size());
}

BoxTree BoxTree::of_points(const std::vector<Box>& points) {
  return BoxTree(points, points);
}

std::uint32_t BoxTree::build(std::size_t first, std::size_t last) {
  // Depth <= log2(n / 4) + 1: the query's stack of 128 holds any size.
  Node n;
  Box clo, chi;
  for (std::size_t k = 0; k < 3; ++k) {
    n.lo[k] = clo[k] = std::numeric_limits<double>::infinity();
    n.hi[k] = chi[k] = -std::numeric_limits<double>::infinity();
  }
  for (std::size_t j = first; j < last; ++j) {
    const std::uint32_t i = order_[j];
    for (std::size_t k = 0; k < 3; ++k) {
      n.lo[k] = std::min(n.lo[k], lo_[i][k]);
      n.hi[k] = std::max(n.hi[k], hi_[i][k]);
      const double c = 0.5 * (lo_[i][k] + hi_[i][k]);
      clo[k] = std::min(clo[k], c);
      chi[k] = std::max(chi[k], c);
    }
  }
  const std::uint32_t id = std::uint32_t(nodes_.size());
  nodes_.push_back(n);
  if (last - first <= 4) {
    nodes_[id].first = std::uint32_t(first);
    nodes_[id].count = std::uint32_t(last - first);
    return id;
  }
  std::size_t axis = 0;
  for (std::size_t k = 1; k < 3; ++k)
    if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
  const std::size_t mid = (first + last) / 2;
  std::nth_element(order_.begin() + long(first), order_.begin() + long(mid),
                   order_.begin() + long(last), [&](std::uint32_t x, std::uint32_t y) {
                     const double cx = lo_[x][axis] + hi_[x][axis],
                                  cy = lo_[y][axis] + hi_[y][axis];
                     return cx < cy || (cx == cy && x < y);
                   });
  const std::uint32_t l = build(first, mid);
  const std::uint32_t r = build(mid, last);
  nodes_[id].left = l;
  nodes_[id].right = r;
  return id;
}

}  // namespace citylod::lod
