// IO-View analysis (paper Section 4.1): regions of the labelled partition,
// principal primitives and secondary structures; primitives matched to the
// BSP's planes.
#include "ioview.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

namespace citylod::lod::detail {
namespace {

/// Point-in-alpha-shape queries for one primitive, on a uniform 2D grid.
class AlphaCover {
 public:
  explicit AlphaCover(const Primitive& p) : prim_(p) {
    for (const auto& t : p.alpha_tris) {
      std::array<Vec2, 3> q;
      for (int k = 0; k < 3; ++k) q[k] = project(t[k]);
      tris_.push_back(q);
    }
    if (tris_.empty()) return;
    lo_ = hi_ = tris_[0][0];
    for (const auto& t : tris_)
      for (const auto& q : t) {
        lo_ = lo_.cwiseMin(q);
        hi_ = hi_.cwiseMax(q);
      }
    const Vec2 ext = (hi_ - lo_).cwiseMax(Vec2(1e-6, 1e-6));
    const double target_cells = std::max<double>(1.0, double(tris_.size()) / 2.0);
    cell_ = std::max(1e-3, std::sqrt(ext.x() * ext.y() / target_cells));
    nx_ = std::min(2048, int(ext.x() / cell_) + 1);
    ny_ = std::min(2048, int(ext.y() / cell_) + 1);
    cell_ = std::max(ext.x() / nx_, ext.y() / ny_) * (1.0 + 1e-9);
    grid_.assign(size_t(nx_) * size_t(ny_), {});
    for (size_t i = 0; i < tris_.size(); ++i) {
      Vec2 a = tris_[i][0].cwiseMin(tris_[i][1]).cwiseMin(tris_[i][2]);
      Vec2 b = tris_[i][0].cwiseMax(tris_[i][1]).cwiseMax(tris_[i][2]);
      const int x0 = cx(a.x()), x1 = cx(b.x()), y0 = cy(a.y()), y1 = cy(b.y());
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) grid_[size_t(y) * size_t(nx_) + size_t(x)].push_back(int(i));
    }
  }

  bool contains(const Vec3& x) const {
    if (tris_.empty()) return false;
    const Vec2 q = project(x);
    if (q.x() < lo_.x() - 1e-6 || q.y() < lo_.y() - 1e-6 || q.x() > hi_.x() + 1e-6 ||
        q.y() > hi_.y() + 1e-6)
      return false;
    for (int i : grid_[size_t(cy(q.y())) * size_t(nx_) + size_t(cx(q.x()))]) {
      const auto& t = tris_[size_t(i)];
      const double d1 = cross(t[0], t[1], q), d2 = cross(t[1], t[2], q), d3 = cross(t[2], t[0], q);
      const double eps = -1e-9;
      const bool neg = (d1 < eps) || (d2 < eps) || (d3 < eps);
      const bool pos = (d1 > -eps) || (d2 > -eps) || (d3 > -eps);
      if (!(neg && pos)) return true;
    }
    return false;
  }

  /// Fraction of sample points of a convex polygon covered by the alpha-shape.
  double coverage(const std::vector<Vec3>& poly) const {
    if (poly.size() < 3 || tris_.empty()) return 0.0;
    Vec3 c = Vec3::Zero();
    for (const auto& v : poly) c += v;
    c /= double(poly.size());
    int hit = contains(c) ? 1 : 0, total = 1;
    const size_t step = std::max<size_t>(1, poly.size() / 8);
    for (size_t i = 0; i < poly.size(); i += step) {
      hit += contains(c + 0.6 * (poly[i] - c)) ? 1 : 0;
      ++total;
    }
    return double(hit) / total;
  }

 private:
  Vec2 project(const Vec3& x) const {
    const Vec3 r = x - prim_.centroid;
    return Vec2(r.dot(prim_.u), r.dot(prim_.v));
  }
  static double cross(const Vec2& a, const Vec2& b, const Vec2& q) {
    return (b.x() - a.x()) * (q.y() - a.y()) - (b.y() - a.y()) * (q.x() - a.x());
  }
  int cx(double x) const { return std::clamp(int((x - lo_.x()) / cell_), 0, nx_ - 1); }
  int cy(double y) const { return std::clamp(int((y - lo_.y()) / cell_), 0, ny_ - 1); }

  const Primitive& prim_;
  std::vector<std::array<Vec2, 3>> tris_;
  Vec2 lo_ = Vec2::Zero(), hi_ = Vec2::Zero();
  double cell_ = 1.0;
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> grid_;
};

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
    return x;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
  }
};

/// The primitive whose alpha-shape covers each interface best (-1: none on
/// that plane), and that coverage.
struct Owners {
  std::vector<int> owner;
  std::vector<double> cov;
};
Owners interface_owners(const Bsp& bsp, const std::vector<Primitive>& prims,
                        const std::vector<int>& primitive_plane,
                        const std::vector<BspInterface>& interfaces) {
  std::vector<std::vector<int>> plane_prims(bsp.planes().size());
  for (size_t i = 0; i < prims.size(); ++i)
    if (primitive_plane[i] >= 0) plane_prims[size_t(primitive_plane[i])].push_back(int(i));
  std::vector<std::unique_ptr<AlphaCover>> covers(prims.size());
  auto cover = [&](int i) -> const AlphaCover& {
    if (!covers[size_t(i)]) covers[size_t(i)] = std::make_unique<AlphaCover>(prims[size_t(i)]);
    return *covers[size_t(i)];
  };
  Owners o;
  std::vector<int>& owner = o.owner;
  std::vector<double>& owner_cov = o.cov;
  owner.assign(interfaces.size(), -1);
  owner_cov.assign(interfaces.size(), 0.0);
  for (size_t k = 0; k < interfaces.size(); ++k) {
    const auto& f = interfaces[k];
    const auto& cand = plane_prims[size_t(f.plane)];
    double best = -1.0;
    for (int pi : cand) {
      const double c = cover(pi).coverage(f.polygon);
      if (c > best ||
          (c == best && prims[size_t(pi)].alpha_area > prims[size_t(owner[k])].alpha_area)) {
        best = c;
        owner[k] = pi;
      }
    }
    owner_cov[k] = std::max(0.0, best);
  }
  return o;
}

/// Regions: adjacent same-label cells not separated by an alpha-shape merged;
/// the largest inside and outside regions are the cores, the others add-ons
/// and cut-outs.
void merge_regions(const Bsp& bsp, const std::vector<BspInterface>& interfaces, const Owners& o,
                   const std::map<int, int>& index_of, const IoViewParams& p, IoView& v) {
  const size_t n = v.leaves.size();
  const auto& nodes = bsp.nodes();
  const std::vector<int>& owner = o.owner;
  const std::vector<double>& owner_cov = o.cov;
  UnionFind uf(n);
  for (size_t k = 0; k < interfaces.size(); ++k) {
    const auto& f = interfaces[k];
    const int a = index_of.at(f.a), b = index_of.at(f.b);
    if (v.leaf_inside[size_t(a)] != v.leaf_inside[size_t(b)]) continue;
    if (owner[k] >= 0 && owner_cov[k] >= p.separation_coverage) continue;
    uf.unite(a, b);
  }
  std::map<int, int> region_of_root;
  v.leaf_region.assign(n, -1);
  for (size_t i = 0; i < n; ++i) {
    const int r = uf.find(int(i));
    auto it = region_of_root.find(r);
    if (it == region_of_root.end()) {
      it = region_of_root.emplace(r, int(v.regions.size())).first;
      Region reg;
      reg.inside = v.leaf_inside[i] != 0;
      v.regions.push_back(reg);
    }
    v.leaf_region[i] = it->second;
    auto& reg = v.regions[size_t(it->second)];
    reg.leaves.push_back(v.leaves[i]);
    reg.volume += nodes[size_t(v.leaves[i])].volume;
  }
  double best_in = -1, best_out = -1;
  for (size_t r = 0; r < v.regions.size(); ++r) {
    const auto& reg = v.regions[r];
    if (reg.inside && reg.volume > best_in) {
      best_in = reg.volume;
      v.core_in = int(r);
    }
    if (!reg.inside && reg.volume > best_out) {
      best_out = reg.volume;
      v.core_out = int(r);
    }
  }
  for (size_t r = 0; r < v.regions.size(); ++r) {
    auto& reg = v.regions[r];
    reg.kind = int(r) == v.core_in    ? RegionKind::CoreInterior
               : int(r) == v.core_out ? RegionKind::CoreExterior
               : reg.inside           ? RegionKind::AddOn
                                      : RegionKind::CutOut;
  }
}

/// Each region's contact area per primitive: `plane` = the area of its
/// boundary faces on the primitive's plane, `covered` = the part of it the
/// primitive's alpha-shape covers.
struct Contacts {
  std::vector<std::map<int, double>> plane, covered;
};

/// Principal primitives: those whose alpha-shapes separate the core interior
/// from the core exterior over at least `min_principal_area`.
Contacts find_principal(const std::vector<BspInterface>& interfaces, const Owners& o,
                        const std::map<int, int>& index_of, size_t num_prims, const IoViewParams& p,
                        IoView& v) {
  std::vector<double> principal_area(num_prims, 0.0), plane_area(num_prims, 0.0);
  Contacts c;
  c.plane.resize(v.regions.size());
  c.covered.resize(v.regions.size());
  for (size_t k = 0; k < interfaces.size(); ++k) {
    const auto& f = interfaces[k];
    const int pi = o.owner[k];
    if (pi < 0) continue;
    const int ra = v.leaf_region[size_t(index_of.at(f.a))];
    const int rb = v.leaf_region[size_t(index_of.at(f.b))];
    if (ra == rb) continue;
    // The part of the face the primitive's alpha-shape covers (the sampled
    // coverage estimates it): the paper's "alpha-shapes that separate V_in and
    // V_out" (ioview.covered_only); else the whole face on its plane.
    const double covered = f.area * o.cov[k];
    if ((ra == v.core_in && rb == v.core_out) || (ra == v.core_out && rb == v.core_in)) {
      principal_area[size_t(pi)] += p.covered_only ? covered : f.area;
      plane_area[size_t(pi)] += f.area;
    }
    c.plane[size_t(ra)][pi] += f.area;
    c.plane[size_t(rb)][pi] += f.area;
    c.covered[size_t(ra)][pi] += covered;
    c.covered[size_t(rb)][pi] += covered;
  }
  v.principal.assign(num_prims, 0);
  v.on_surface.assign(num_prims, 0);
  for (size_t i = 0; i < num_prims; ++i) {
    v.principal[i] = principal_area[i] >= p.min_principal_area ? 1 : 0;
    v.on_surface[i] = plane_area[i] >= p.min_principal_area ? 1 : 0;
  }
  return c;
}

/// Secondary structures: the regions other than the cores, each with its host
/// (the principal primitive whose alpha-shape covers the largest part of its
/// boundary) and the secondary primitives
/// that bound it the most.
void find_structures(const Bsp& bsp, const Contacts& contacts, size_t num_prims,
                     const IoViewParams& p, IoView& v) {
  const std::vector<std::map<int, double>>& contact = contacts.plane;
  v.primitive_structure.assign(num_prims, -1);
  std::vector<double> best_contact(num_prims, 0.0);
  std::vector<int> structure_of_region(v.regions.size(), -1);
  for (size_t r = 0; r < v.regions.size(); ++r) {
    const auto& reg = v.regions[r];
    if (reg.kind == RegionKind::CoreInterior || reg.kind == RegionKind::CoreExterior) continue;
    Structure s;
    s.region = int(r);
    s.addon = reg.inside;
    s.volume = reg.volume;
    double host_area = 0.0;
    for (const auto& [pi, area] : (p.covered_only ? contacts.covered : contacts.plane)[r]) {
      if (v.principal[size_t(pi)]) {
        if (area > host_area) {
          host_area = area;
          s.host = pi;
        }
      }
    }
    s.projected_area = host_area > 0 ? host_area : std::cbrt(reg.volume * reg.volume);
    bool first = true;
    for (int leaf : reg.leaves)
      for (const auto& x : bsp.cell_vertices(leaf)) {
        if (first) {
          s.lo = s.hi = x;
          first = false;
        }
        s.lo = s.lo.cwiseMin(x);
        s.hi = s.hi.cwiseMax(x);
      }
    structure_of_region[r] = int(v.structures.size());
    v.structures.push_back(std::move(s));
  }
  // Each secondary primitive goes to the structure it bounds the most.
  for (size_t r = 0; r < v.regions.size(); ++r) {
    const int si = structure_of_region[r];
    if (si < 0) continue;
    for (const auto& [pi, area] : contact[r]) {
      if (v.principal[size_t(pi)]) continue;
      if (area > best_contact[size_t(pi)]) {
        best_contact[size_t(pi)] = area;
        v.primitive_structure[size_t(pi)] = si;
      }
    }
  }
  for (size_t i = 0; i < num_prims; ++i)
    if (v.primitive_structure[i] >= 0)
      v.structures[size_t(v.primitive_structure[i])].primitives.push_back(int(i));
}

}  // namespace

std::vector<int> match_planes(const Bsp& bsp, const std::vector<Primitive>& prims) {
  const auto planes = bsp.planes();
  std::vector<int> out(prims.size(), -1);
  for (size_t i = 0; i < prims.size(); ++i) {
    const Vec3 n = prims[i].normal;
    double best = 1e-6;
    for (size_t j = 0; j < planes.size(); ++j) {
      const Vec3 m(planes[j][0], planes[j][1], planes[j][2]);
      const double s = n.dot(m) >= 0 ? 1.0 : -1.0;
      const double err = (n - s * m).norm() + std::abs(prims[i].d - s * planes[j][3]);
      if (err < best) {
        best = err;
        out[i] = int(j);
      }
    }
  }
  return out;
}

IoView analyse_io_view(const Bsp& bsp, const std::vector<Primitive>& prims,
                       const std::vector<int>& primitive_plane,
                       const std::vector<char>& leaf_inside, const IoViewParams& p) {
  IoView v;
  v.leaves = bsp.leaves();
  v.leaf_inside = leaf_inside;
  const size_t n = v.leaves.size();
  std::map<int, int> index_of;
  for (size_t i = 0; i < n; ++i) index_of[v.leaves[i]] = int(i);
  const auto interfaces = bsp.adjacency(v.leaves);
  const Owners o = interface_owners(bsp, prims, primitive_plane, interfaces);
  merge_regions(bsp, interfaces, o, index_of, p, v);
  const Contacts contacts = find_principal(interfaces, o, index_of, prims.size(), p, v);
  find_structures(bsp, contacts, prims.size(), p, v);
  return v;
}

}  // namespace citylod::lod::detail
