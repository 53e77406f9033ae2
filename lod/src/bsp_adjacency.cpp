// Bsp::adjacency: the interfaces (shared face pieces) between the cells of a
// partition, from the faces' double coordinates.
#include "bsp_impl.hpp"

#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <tuple>
#include <utility>

namespace citylod::lod::detail {

using namespace bspi;

namespace {

constexpr double kInterfaceMinArea = 1e-9;

using Poly2 = std::vector<Eigen::Vector2d>;

double area2(const Poly2& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& w = p[(i + 1) % p.size()];
    a += u.x() * w.y() - u.y() * w.x();
  }
  return 0.5 * a;
}

// Convex clipping (Sutherland-Hodgman); both CCW.
Poly2 clip_convex(const Poly2& subject, const Poly2& clip) {
  Poly2 out = subject;
  for (size_t i = 0; i < clip.size() && !out.empty(); ++i) {
    const auto& a = clip[i];
    const auto& b = clip[(i + 1) % clip.size()];
    const Eigen::Vector2d d = b - a;
    auto side = [&](const Eigen::Vector2d& p) {
      return d.x() * (p.y() - a.y()) - d.y() * (p.x() - a.x());
    };
    Poly2 in = std::move(out);
    out.clear();
    for (size_t j = 0; j < in.size(); ++j) {
      const auto& p = in[j];
      const auto& q = in[(j + 1) % in.size()];
      const double sp = side(p), sq = side(q);
      if (sp >= 0) out.push_back(p);
      if ((sp > 0 && sq < 0) || (sp < 0 && sq > 0)) out.push_back(p + (q - p) * (sp / (sp - sq)));
    }
  }
  return out;
}

}  // namespace

std::vector<BspInterface> Bsp::adjacency(const std::vector<int>& partition) const {
  const Impl& I = *impl_;
  struct FRef {
    int node, face;
    bool pos;
  };
  std::map<int, std::vector<FRef>> byplane;
  for (int nid : partition) {
    if (nid < 0 || nid >= int(I.cells.size())) throw std::out_of_range("Bsp::adjacency: node id");
    const Cell& c = I.cells[nid];
    for (size_t f = 0; f < c.faces.size(); ++f) {
      const int pl = c.faces[f].poly.plane;
      if (pl < 6) continue;  // box boundary: no neighbour
      byplane[pl].push_back({nid, int(f), c.faces[f].cell_pos});
    }
  }
  std::vector<BspInterface> out;
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, int>;
  for (const auto& [pl, refs] : byplane) {
    const auto& c = I.dplanes[pl];
    int k = 0;
    for (int t = 1; t < 3; ++t)
      if (std::abs(c[t]) > std::abs(c[k])) k = t;
    const int u = (k + 1) % 3, w = (k + 2) % 3;
    std::vector<Poly2> p2(refs.size());
    std::vector<Box> ba, bb;
    for (size_t r = 0; r < refs.size(); ++r) {
      const auto& L = I.cells[refs[r].node].faces[refs[r].face].poly.v;
      Poly2& P = p2[r];
      for (int v : L) P.emplace_back(I.verts[v].approx[u], I.verts[v].approx[w]);
      if (area2(P) < 0) std::reverse(P.begin(), P.end());
      double lo2[2] = {1e300, 1e300}, hi2[2] = {-1e300, -1e300};
      for (const auto& p : P)
        for (int t = 0; t < 2; ++t)
          lo2[t] = std::min(lo2[t], p[t]), hi2[t] = std::max(hi2[t], p[t]);
      (refs[r].pos ? bb : ba).emplace_back(lo2, hi2, int(r));
    }
    if (ba.empty() || bb.empty()) continue;
    std::vector<std::pair<int, int>> pairs;
    CGAL::box_intersection_d(
        ba.begin(), ba.end(), bb.begin(), bb.end(),
        [&](const Box& x, const Box& y) { pairs.emplace_back(x.info(), y.info()); });
    for (const auto& [ra, rb] : pairs) {
      // ra: cell on the negative side (a); rb: cell on the positive side (b)
      Poly2 inter = clip_convex(p2[ra], p2[rb]);
      if (inter.size() < 3) continue;
      const double area = std::abs(area2(inter)) / std::abs(c[k]);
      if (!(area > kInterfaceMinArea)) continue;
      BspInterface itf;
      itf.a = refs[ra].node;
      itf.b = refs[rb].node;
      itf.plane = pl;
      itf.area = area;
      for (const auto& q : inter) {
        Vec3 x;
        x[u] = q.x();
        x[w] = q.y();
        x[k] = -(c[u] * q.x() + c[w] * q.y() + c[3]) / c[k];
        itf.polygon.push_back(x);
      }
      // CCW around +normal
      if (c[k] < 0) std::reverse(itf.polygon.begin(), itf.polygon.end());
      out.push_back(std::move(itf));
    }
  }
  std::sort(out.begin(), out.end(), [](const BspInterface& x, const BspInterface& y) {
    return std::tie(x.a, x.b, x.plane) < std::tie(y.a, y.b, y.plane);
  });
  return out;
}

}  // namespace citylod::lod::detail
