#include "clustering.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace citylod::lod::detail {

std::vector<int> mean_shift_1d(const std::vector<double>& values, double bandwidth) {
  const size_t n = values.size();
  std::vector<int> label(n, 0);
  if (n == 0) return label;
  std::vector<double> sorted(values);
  std::sort(sorted.begin(), sorted.end());
  // prefix sums over sorted values for O(log n) window means
  std::vector<double> prefix(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + sorted[i];
  auto window_mean = [&](double x) {
    const auto lo = std::lower_bound(sorted.begin(), sorted.end(), x - bandwidth) - sorted.begin();
    const auto hi = std::upper_bound(sorted.begin(), sorted.end(), x + bandwidth) - sorted.begin();
    if (hi <= lo) return x;
    return (prefix[static_cast<size_t>(hi)] - prefix[static_cast<size_t>(lo)]) / double(hi - lo);
  };
  std::vector<double> mode(n);
  for (size_t i = 0; i < n; ++i) {
    double x = values[i];
    for (int it = 0; it < 300; ++it) {
      const double m = window_mean(x);
      if (std::abs(m - x) < 1e-9 * std::max(1.0, std::abs(x))) {
        x = m;
        break;
      }
      x = m;
    }
    mode[i] = x;
  }
  // Merge modes closer than the bandwidth (as scikit-learn does), in increasing order.
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return mode[a] < mode[b]; });
  int current = -1;
  double anchor = 0.0;
  for (size_t idx : order) {
    if (current < 0 || mode[idx] - anchor > bandwidth) {
      ++current;
      anchor = mode[idx];
    }
    label[idx] = current;
  }
  return label;
}

}  // namespace citylod::lod::detail
