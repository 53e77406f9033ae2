#include "lattice.hpp"

#include <cmath>

namespace citylod::geo::detail {

namespace {

/// Lagrange weights of the nodes at t = 0, 1/2, 1 for a parameter t.
inline void weights(double t, double w[3]) {
  w[0] = 2.0 * (t - 0.5) * (t - 1.0);
  w[1] = -4.0 * t * (t - 1.0);
  w[2] = 2.0 * t * (t - 0.5);
}

constexpr double kIndexLimit = double(1 << 29);          // |cell index|: node keys stay in 32 bits
constexpr std::size_t kMaxCells = std::size_t(1) << 16;  // cache bound (~30 MB)

}  // namespace

Lattice::Lattice(double cell, double height, double tolerance)
    : cell_(cell), height_(height), tolerance_(tolerance) {}

std::size_t Lattice::fast_cells() const {
  return cells_.size();
}
std::size_t Lattice::exact_cells() const {
  return exact_cells_;
}

Eigen::Vector3d Lattice::interpolate(const Cell& c, const Eigen::Vector3d& p) const {
  double wu[3], wv[3];
  weights(p.x() / cell_ - double(c.cx), wu);
  weights(p.y() / cell_ - double(c.cy), wv);
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double w = wu[i] * wv[j];
      a += w * c.nodes[i][j].a;
      b += w * c.nodes[i][j].b;
    }
  return a + p.z() * b;
}

void Lattice::prepare(const std::vector<std::pair<std::int64_t, std::int64_t>>& fresh,
                      const Exact& exact) {
  const double half = 0.5 * cell_;
  // The exact map at the nodes not known yet (two heights each) and at each cell's
  // check points, in one batch.
  std::vector<std::pair<std::int64_t, std::int64_t>> new_nodes;
  for (const auto& [cx, cy] : fresh)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const std::uint64_t k = key(2 * cx + i, 2 * cy + j);
        if (nodes_.emplace(k, Node{}).second) new_nodes.emplace_back(2 * cx + i, 2 * cy + j);
      }
  const double check_z = 0.37 * height_;
  const Eigen::Index nn = Eigen::Index(new_nodes.size()), nc = Eigen::Index(fresh.size());
  Eigen::Matrix3Xd m(3, 2 * nn + 3 * nc);
  for (Eigen::Index k = 0; k < nn; ++k) {
    const double x = double(new_nodes[size_t(k)].first) * half;
    const double y = double(new_nodes[size_t(k)].second) * half;
    m.col(2 * k) = Eigen::Vector3d(x, y, 0.0);
    m.col(2 * k + 1) = Eigen::Vector3d(x, y, height_);
  }
  for (Eigen::Index k = 0; k < nc; ++k) {
    const double x0 = double(fresh[size_t(k)].first) * cell_;
    const double y0 = double(fresh[size_t(k)].second) * cell_;
    m.col(2 * nn + 3 * k) = Eigen::Vector3d(x0 + 0.25 * cell_, y0 + 0.25 * cell_, 0.0);
    m.col(2 * nn + 3 * k + 1) = Eigen::Vector3d(x0 + 0.25 * cell_, y0 + 0.25 * cell_, height_);
    m.col(2 * nn + 3 * k + 2) = Eigen::Vector3d(x0 + 0.75 * cell_, y0 + 0.75 * cell_, check_z);
  }
  const Eigen::Matrix3Xd in = m;
  try {
    exact(m);
  } catch (const std::exception&) {  // some do not transform: each on its own
    for (Eigen::Index k = 0; k < m.cols(); ++k) {
      m.col(k) = in.col(k);
      try {
        exact(m.col(k));
      } catch (const std::exception&) {
        m.col(k).setConstant(std::nan(""));
      }
    }
  }
  for (Eigen::Index k = 0; k < nn; ++k) {
    Node& n = nodes_[key(new_nodes[size_t(k)].first, new_nodes[size_t(k)].second)];
    n.a = m.col(2 * k);
    n.b = (m.col(2 * k + 1) - m.col(2 * k)) / height_;
    n.ok = n.a.allFinite() && n.b.allFinite();
  }
  for (Eigen::Index k = 0; k < nc; ++k) {
    Cell c;
    c.cx = fresh[size_t(k)].first;
    c.cy = fresh[size_t(k)].second;
    bool ok = true;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        c.nodes[i][j] = nodes_.at(key(2 * c.cx + i, 2 * c.cy + j));
        ok = ok && c.nodes[i][j].ok;
      }
    for (int q = 0; q < 3 && ok; ++q) {
      const Eigen::Vector3d want = m.col(2 * nn + 3 * k + q);
      ok = want.allFinite() &&
           (interpolate(c, in.col(2 * nn + 3 * k + q)) - want).norm() <= tolerance_;
    }
    const std::uint64_t ck = key(c.cx, c.cy);
    if (ok) {
      cell_index_[ck] = int(cells_.size());
      cells_.push_back(c);
    } else {
      cell_index_[ck] = -1;
      ++exact_cells_;
    }
  }
}

void Lattice::apply(Eigen::Ref<Eigen::Matrix3Xd> p, const Exact& exact) {
  if (cells_.size() > kMaxCells) {  // results do not depend on what is cached
    nodes_.clear();
    cell_index_.clear();
    cells_.clear();
  }
  const Eigen::Index n = p.cols();
  std::vector<int> cell_of(size_t(n), -1);  // index into cells_, -1: exact
  std::vector<std::pair<std::int64_t, std::int64_t>> fresh;
  std::vector<std::uint64_t> keys(size_t(n), 0);
  std::vector<char> lattice(size_t(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double x = p(0, i), y = p(1, i), z = p(2, i);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;
    const double fx = std::floor(x / cell_), fy = std::floor(y / cell_);
    if (std::abs(fx) > kIndexLimit || std::abs(fy) > kIndexLimit) continue;
    const std::int64_t cx = std::int64_t(fx), cy = std::int64_t(fy);
    keys[size_t(i)] = key(cx, cy);
    lattice[size_t(i)] = 1;
    if (cell_index_.emplace(keys[size_t(i)], -2).second) fresh.emplace_back(cx, cy);
  }
  if (!fresh.empty()) prepare(fresh, exact);
  std::vector<Eigen::Index> slow;
  std::uint64_t last_key = 0;
  int last = -3;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (lattice[size_t(i)]) {
      if (last == -3 || keys[size_t(i)] != last_key) {
        last_key = keys[size_t(i)];
        last = cell_index_.at(last_key);
      }
      cell_of[size_t(i)] = last;
    }
    if (cell_of[size_t(i)] < 0) slow.push_back(i);
  }
  if (!slow.empty()) {
    Eigen::Matrix3Xd q(3, Eigen::Index(slow.size()));
    for (size_t k = 0; k < slow.size(); ++k) q.col(Eigen::Index(k)) = p.col(slow[k]);
    try {
      exact(q);
    } catch (const std::exception&) {
      exact(p);  // the same error, naming the point by its place in the whole batch
      return;
    }
    for (size_t k = 0; k < slow.size(); ++k) p.col(slow[k]) = q.col(Eigen::Index(k));
  }
  for (Eigen::Index i = 0; i < n; ++i)
    if (cell_of[size_t(i)] >= 0)
      p.col(i) = interpolate(cells_[size_t(cell_of[size_t(i)])], p.col(i));
}

}  // namespace citylod::geo::detail
