// The one 2D polygon toolkit of citylod (header only, no dependency beyond
// the standard library): used by the LOD engine (fallback outlines) and by the
// city pipeline (footprints, assemble). Works on any point type with
// coordinates p[0], p[1] (std::array<double, 2>) or p.x(), p.y() (Eigen).
// A ring is a std::vector of points, closed implicitly (last != first).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>
#include <vector>

namespace citylod::poly2 {

namespace detail {
template <class P, class = void>
struct has_x : std::false_type {};
template <class P>
struct has_x<P, std::void_t<decltype(std::declval<const P&>().x())>> : std::true_type {};
}  // namespace detail

template <class P>
double x_of(const P& p) {
  if constexpr (detail::has_x<P>::value)
    return p.x();
  else
    return p[0];
}
template <class P>
double y_of(const P& p) {
  if constexpr (detail::has_x<P>::value)
    return p.y();
  else
    return p[1];
}

/// z of (a - o) x (b - o): > 0 when o, a, b turn left.
template <class P>
double cross(const P& o, const P& a, const P& b) {
  return (x_of(a) - x_of(o)) * (y_of(b) - y_of(o)) - (y_of(a) - y_of(o)) * (x_of(b) - x_of(o));
}

/// Shoelace area, > 0 when the ring is CCW.
template <class P>
double signed_area(const std::vector<P>& r) {
  double a = 0;
  const std::size_t n = r.size();
  for (std::size_t i = 0; i < n; ++i) {
    const P& p = r[i];
    const P& q = r[(i + 1) % n];
    a += x_of(p) * y_of(q) - x_of(q) * y_of(p);
  }
  return 0.5 * a;
}

/// Even-odd rule.
template <class P>
bool point_in_ring(const std::vector<P>& r, const P& p) {
  bool in = false;
  const std::size_t n = r.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const P& a = r[i];
    const P& b = r[j];
    if ((y_of(a) > y_of(p)) != (y_of(b) > y_of(p))) {
      const double x = x_of(a) + (y_of(p) - y_of(a)) * (x_of(b) - x_of(a)) / (y_of(b) - y_of(a));
      if (x_of(p) < x) in = !in;
    }
  }
  return in;
}

/// Distance from p to the boundary of the ring (+inf for an empty ring).
template <class P>
double distance_to_ring(const std::vector<P>& r, const P& p) {
  double best = std::numeric_limits<double>::infinity();
  const std::size_t n = r.size();
  for (std::size_t i = 0; i < n; ++i) {
    const P& a = r[i];
    const P& b = r[(i + 1) % n];
    const double dx = x_of(b) - x_of(a), dy = y_of(b) - y_of(a);
    const double len2 = dx * dx + dy * dy;
    double t = len2 > 0 ? ((x_of(p) - x_of(a)) * dx + (y_of(p) - y_of(a)) * dy) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    const double ex = x_of(a) + t * dx - x_of(p), ey = y_of(a) + t * dy - y_of(p);
    best = std::min(best, ex * ex + ey * ey);
  }
  return std::sqrt(best);
}

/// 2D convex hull, CCW, no collinear points (Andrew's monotone chain).
template <class P>
std::vector<P> convex_hull(std::vector<P> p) {
  std::sort(p.begin(), p.end(), [](const P& a, const P& b) {
    return x_of(a) != x_of(b) ? x_of(a) < x_of(b) : y_of(a) < y_of(b);
  });
  p.erase(
      std::unique(p.begin(), p.end(),
                  [](const P& a, const P& b) { return x_of(a) == x_of(b) && y_of(a) == y_of(b); }),
      p.end());
  if (p.size() < 3) return p;
  std::vector<P> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  h.resize(k - 1);
  return h;
}

}  // namespace citylod::poly2
