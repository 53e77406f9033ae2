// glb writer, quantization: the positions as stored. int16
// (KHR_mesh_quantization) where it keeps every feature's corners distinct and
// every valid solid valid (snapped when that takes it), float otherwise; for
// meshopt, the EXPONENTIAL filter's bits of the float positions.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <unordered_map>

#include <meshoptimizer.h>

#include "citylod/io/gltf.hpp"
#include "citylod/io/weld.hpp"
#include "gltf_internal.hpp"

namespace citylod::io {

namespace detail {

double quant_extent(const GlbNode& n) {
  double e = 0;
  for (const auto& p : n.rel)
    for (double x : p) e = std::max(e, std::fabs(x));
  return e > 1e-3 ? e : 1e-3;
}

std::set<float> unquantizable(const GlbNode& n) {
  const double e = quant_extent(n);
  std::map<std::array<std::int64_t, 4>, Vec3d> seen;
  std::set<float> bad;
  for (std::size_t i = 0; i < n.rel.size(); ++i) {
    const Vec3d y = to_yup(n.rel[i]);
    const std::array<std::int64_t, 4> key{std::int64_t(n.feature[i]), quant(y[0], e),
                                          quant(y[1], e), quant(y[2], e)};
    const auto [it, added] = seen.emplace(key, n.rel[i]);
    if (!added && it->second != n.rel[i]) bad.insert(n.feature[i]);
  }
  return bad;
}

GlbNode part(const GlbNode& n, const std::set<float>& features, bool in_set) {
  GlbNode out;
  out.name = n.name;
  std::vector<std::uint32_t> map(n.rel.size(), ~0u);
  for (std::size_t i = 0; i < n.rel.size(); ++i)
    if ((features.count(n.feature[i]) != 0) == in_set) {
      map[i] = std::uint32_t(out.rel.size());
      out.rel.push_back(n.rel[i]);
      out.normals.push_back(n.normals[i]);
      out.feature.push_back(n.feature[i]);
      out.colours.push_back(n.colours[i]);
    }
  for (int c = 0; c < kClasses; ++c)
    for (std::uint32_t v : n.indices[size_t(c)])
      if (map[v] != ~0u) out.indices[size_t(c)].push_back(map[v]);
  return out;
}

void exp_encode(const GlbNode& n, int bits, std::vector<std::int32_t>& encoded,
                std::vector<float>& decoded) {
  const std::size_t nv = n.rel.size();
  std::vector<float> pos(nv * 3);
  for (std::size_t i = 0; i < nv; ++i) {
    const Vec3d y = to_yup(n.rel[i]);
    for (int k = 0; k < 3; ++k) pos[i * 3 + size_t(k)] = float(y[size_t(k)]);
  }
  encoded.assign(nv * 3, 0);
  meshopt_encodeFilterExp(encoded.data(), nv, 12, bits, pos.data());
  std::vector<std::int32_t> copy = encoded;
  meshopt_decodeFilterExp(copy.data(), nv, 12);
  decoded.resize(nv * 3);
  std::memcpy(decoded.data(), copy.data(), nv * 12);
}

}  // namespace detail

using detail::exp_encode;
using detail::from_yup;
using detail::kClasses;
using detail::quant;
using detail::quant_extent;
using detail::to_yup;

/// meshopt, float positions (y-up, relative): meshoptimizer's EXPONENTIAL
/// filter with the fewest mantissa bits (of 16, 18, ..., 24) that keep every
/// coordinate within the tolerance and each feature's distinct corners
/// distinct. With `opt.snapped_is_valid` the tolerance is the node's int16
/// step and every valid feature must be a valid solid as decoded at those
/// bits; otherwise (or failing that) the tolerance is 1/256 of the step
/// (about float32 precision: up to the int16 step, unchecked, turned a
/// sub-step sliver of a Delft model self-intersecting). Returns the bits
/// (0: none qualifies, plain float).
int GlbBuilder::Impl::exp_bits(const Node& n, double extent) const {
  std::vector<std::int32_t> encoded;
  std::vector<float> decoded;
  // checked: the int16 step, and the solids checked at the fewest bits
  // within it; failing that (or unchecked) 1/256 of the step
  for (const bool checked : {bool(opt.snapped_is_valid), false}) {
    const double step = checked ? extent / 32767 : extent / 32767 / 256;
    for (int bits = 16; bits <= 24; bits += 2) {
      exp_encode(n, bits, encoded, decoded);
      bool ok = true;
      for (std::size_t i = 0; ok && i < n.rel.size(); ++i) {
        const Vec3d y = to_yup(n.rel[i]);
        for (int k = 0; ok && k < 3; ++k) {
          const float d = decoded[i * 3 + size_t(k)];
          ok = std::isfinite(d) && std::fabs(double(d) - double(float(y[size_t(k)]))) <= step;
        }
      }
      std::map<std::array<float, 4>, Vec3d> seen;
      for (std::size_t i = 0; ok && i < n.rel.size(); ++i) {
        const std::array<float, 4> key{n.feature[i], decoded[i * 3], decoded[i * 3 + 1],
                                       decoded[i * 3 + 2]};
        const auto [it, added] = seen.emplace(key, n.rel[i]);
        ok = added || it->second == n.rel[i];
      }
      if (!ok) continue;
      if (checked && !decoded_solids_valid(n, decoded)) break;
      return bits;
    }
    if (!checked) break;
  }
  return 0;
}

int GlbBuilder::Impl::float_bits(std::size_t ni, const Node& fpart, double extent) const {
  const auto it = float_bits_of.find(ni);
  if (it != float_bits_of.end()) return it->second;
  return float_bits_of[ni] = exp_bits(fpart, extent);
}

/// Whether every valid feature of `n` is a valid solid with the positions
/// `decoded` (y-up, 3 floats a vertex; corners welded by position).
bool GlbBuilder::Impl::decoded_solids_valid(const Node& n,
                                            const std::vector<float>& decoded) const {
  std::map<float, TriangleMesh> meshes;
  std::map<std::array<float, 4>, std::uint32_t> vid;
  auto vertex = [&](std::uint32_t i) {
    const std::array<float, 4> key{n.feature[i], decoded[i * 3], decoded[i * 3 + 1],
                                   decoded[i * 3 + 2]};
    TriangleMesh& m = meshes[n.feature[i]];
    const auto [it, fresh] = vid.emplace(key, std::uint32_t(m.vertices.size()));
    if (fresh)
      m.vertices.push_back(from_yup(Vec3d{decoded[i * 3], decoded[i * 3 + 1], decoded[i * 3 + 2]}));
    return it->second;
  };
  for (const auto& ix : n.indices)
    for (std::size_t t = 0; t + 2 < ix.size(); t += 3) {
      if (!features.at(std::size_t(n.feature[ix[t]])).valid) continue;
      const std::array<std::uint32_t, 3> tri{vertex(ix[t]), vertex(ix[t + 1]), vertex(ix[t + 2])};
      meshes[n.feature[ix[t]]].triangles.push_back(tri);
    }
  for (const auto& [f, m] : meshes)
    if (!opt.snapped_is_valid(m)) return false;
  return true;
}

/// The node as stored, and which of its features keep float positions.
/// Without `opt.snapped_is_valid`: the features whose distinct corners
/// int16 would merge (unquantizable) stay float. With it, a valid feature
/// that int16 could damage -- two distinct corners within 2 int16 steps per
/// axis, or a triangle less than 4 steps high -- is checked as int16 stores
/// it (corners welded) and, when that is not a valid solid, snapped: its
/// int16 corners within r steps per axis (transitively; r = 1, 2) welded
/// into the smallest, collapsed triangles and pairs of opposite triangles
/// (zero-volume fins) dropped; the first r the check accepts is stored
/// (each vertex at its welded int16 position), else the feature stays
/// float. Invalid features: as without the check.
GlbBuilder::Impl::Node GlbBuilder::Impl::snapped(const Node& in) const {
  Node n = in;
  n.float_features.clear();
  if (!(opt.quantize || opt.compression == Compression::meshopt)) return n;
  const std::set<float> bad = detail::unquantizable(in);
  if (!opt.snapped_is_valid) {
    n.float_features = bad;
    return n;
  }
  const double e = quant_extent(n);
  const double step = e / 32767;
  using Key = std::array<std::int16_t, 3>;
  auto key_of = [&](const Vec3d& rel) {
    const Vec3d y = to_yup(rel);
    return Key{quant(y[0], e), quant(y[1], e), quant(y[2], e)};
  };
  auto at = [&](const Key& k) {
    return from_yup(
        Vec3d{double(k[0]) / 32767.0 * e, double(k[1]) / 32767.0 * e, double(k[2]) / 32767.0 * e});
  };
  // each feature's vertices and triangles (class, first index)
  std::map<float, std::vector<std::uint32_t>> vertices_of;
  for (std::uint32_t i = 0; i < n.rel.size(); ++i) vertices_of[n.feature[i]].push_back(i);
  std::map<float, std::vector<std::pair<int, std::size_t>>> triangles_of;
  for (int c = 0; c < kClasses; ++c)
    for (std::size_t t = 0; t + 2 < n.indices[size_t(c)].size(); t += 3)
      triangles_of[n.feature[n.indices[size_t(c)][t]]].emplace_back(c, t);
  std::array<std::vector<char>, kClasses> drop;  // per class, per triangle
  for (int c = 0; c < kClasses; ++c) drop[size_t(c)].assign(n.indices[size_t(c)].size() / 3, 0);
  for (const auto& [f, vs] : vertices_of) {
    if (!features.at(std::size_t(f)).valid) {
      if (bad.count(f)) n.float_features.insert(f);
      continue;
    }
    const auto& tris = triangles_of[f];
    // the feature's corners as int16 cells; pairs of cells within 2 steps
    std::vector<Key> cells;
    std::map<Key, std::uint32_t> cell_id;
    std::unordered_map<std::uint32_t, std::uint32_t> cell_of;  // node vertex -> cell
    for (const std::uint32_t v : vs) {
      const auto [it, fresh] = cell_id.emplace(key_of(n.rel[v]), std::uint32_t(cells.size()));
      if (fresh) cells.push_back(it->first);
      cell_of[v] = it->second;
    }
    std::vector<std::array<std::int64_t, 3>> cell_points;
    for (const Key& k : cells) cell_points.push_back({k[0], k[1], k[2]});
    // a validator merges corners within its snap tolerance: that many steps too
    const std::uint32_t reach =
        std::max<std::uint32_t>(2, std::uint32_t(std::ceil(opt.snap_tolerance_m * 1.1 / step)));
    const std::vector<NearPair> near = near_pairs(cell_points, reach);
    std::vector<std::uint32_t> rank(cells.size());  // a cluster welds into its smallest cell
    std::uint32_t next_rank = 0;
    for (const auto& [key, id] : cell_id) rank[id] = next_rank++;
    bool damageable = bad.count(f) || !near.empty();
    for (std::size_t k = 0; !damageable && k < tris.size(); ++k) {
      const auto& ix = n.indices[size_t(tris[k].first)];
      const Vec3d& p = n.rel[ix[tris[k].second]];
      const Vec3d& q = n.rel[ix[tris[k].second + 1]];
      const Vec3d& r = n.rel[ix[tris[k].second + 2]];
      const Vec3d u{q[0] - p[0], q[1] - p[1], q[2] - p[2]},
          w{r[0] - p[0], r[1] - p[1], r[2] - p[2]}, x{r[0] - q[0], r[1] - q[1], r[2] - q[2]};
      const Vec3d cr{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                     u[0] * w[1] - u[1] * w[0]};
      const double area2 = std::sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
      const double longest = std::sqrt(std::max({u[0] * u[0] + u[1] * u[1] + u[2] * u[2],
                                                 w[0] * w[0] + w[1] * w[1] + w[2] * w[2],
                                                 x[0] * x[0] + x[1] * x[1] + x[2] * x[2]}));
      damageable = area2 < 4 * step * longest;  // smallest height < 4 steps
    }
    if (!damageable) continue;  // int16 as it is
    bool stored_int16 = false;
    std::vector<std::uint32_t> radii{0u, 1u, 2u};
    if (reach > 2) radii.push_back(reach);
    for (const std::uint32_t r : radii) {
      if (r > 0 && std::none_of(near.begin(), near.end(), [&](const NearPair& p) {
            return p.d <= r && (p.d == r || r == reach);
          }))
        continue;  // nothing new to weld
      // cells within r steps per axis, transitively -> the smallest cell
      const std::vector<std::uint32_t> root = weld(near, r, rank);
      // the model as stored: welded vertices (cells in first-use order)
      TriangleMesh m;
      std::vector<std::uint32_t> vid(cells.size(), ~0u);
      auto vertex = [&](std::uint32_t node_vertex) {
        const std::uint32_t cell = root[cell_of.at(node_vertex)];
        if (vid[cell] == ~0u) {
          vid[cell] = std::uint32_t(m.vertices.size());
          m.vertices.push_back(at(cells[cell]));
        }
        return vid[cell];
      };
      std::vector<std::array<std::uint32_t, 3>> welded;
      for (const auto& [c, t] : tris) {
        const auto& ix = n.indices[size_t(c)];
        welded.push_back({vertex(ix[t]), vertex(ix[t + 1]), vertex(ix[t + 2])});
      }
      std::vector<std::size_t> from;
      TriangleMesh kept;
      kept.vertices = m.vertices;
      kept.triangles = drop_collapsed_and_fins(welded, from);
      std::vector<char> stays(tris.size(), 0);
      for (const std::size_t k : from) stays[k] = 1;
      if (!opt.snapped_is_valid(kept)) continue;
      stored_int16 = true;
      if (r == 0 && !bad.count(f)) break;  // int16 as it is
      for (const std::uint32_t v : vs) n.rel[v] = at(cells[root[cell_of.at(v)]]);
      for (std::size_t k = 0; k < tris.size(); ++k)
        if (!stays[k]) drop[size_t(tris[k].first)][tris[k].second / 3] = 1;
      break;
    }
    if (!stored_int16) n.float_features.insert(f);
  }
  for (int c = 0; c < kClasses; ++c) {
    auto& ix = n.indices[size_t(c)];
    std::vector<std::uint32_t> out;
    out.reserve(ix.size());
    for (std::size_t t = 0; t + 2 < ix.size(); t += 3)
      if (!drop[size_t(c)][t / 3])
        out.insert(out.end(), ix.begin() + long(t), ix.begin() + long(t) + 3);
    ix = std::move(out);
  }
  return n;
}

const std::vector<GlbBuilder::Impl::Node>& GlbBuilder::Impl::stored_nodes() const {
  if (!stored) {
    stored = std::make_unique<std::vector<Node>>();
    for (const auto& node : nodes) stored->push_back(snapped(node));
  }
  return *stored;
}

BBox3 GlbBuilder::stored_bounds() const {
  BBox3 b;
  const Vec3d& o = impl_->origin;
  const std::vector<Impl::Node>& nodes = impl_->stored_nodes();
  for (std::size_t ni = 0; ni < nodes.size(); ++ni) {
    const Impl::Node& node = nodes[ni];
    const double e = quant_extent(node);
    const bool q = impl_->quantized(node);
    // meshopt: the features int16 would damage stay float (see glb())
    const std::set<float> bad = !q && impl_->opt.compression == Compression::meshopt
                                    ? node.float_features
                                    : std::set<float>{};
    // meshopt: the float part through the EXPONENTIAL filter (see glb())
    std::vector<float> dec;
    std::map<std::array<float, 4>, Vec3d> as_stored;  // (feature, float y-up) -> decoded
    if (!q && impl_->opt.compression == Compression::meshopt) {
      std::set<float> all(node.feature.begin(), node.feature.end());
      // (the filter is per vertex: the codec order does not change the result)
      const Impl::Node fpart =
          bad.empty() || bad.size() == all.size() ? node : detail::part(node, bad, true);
      std::vector<std::int32_t> enc;
      const int bits = impl_->float_bits(ni, fpart, e);
      if (bits > 0) exp_encode(fpart, bits, enc, dec);
      if (bits > 0)
        for (std::size_t i = 0; i < fpart.rel.size(); ++i) {
          const Vec3d y = to_yup(fpart.rel[i]);
          as_stored[{fpart.feature[i], float(y[0]), float(y[1]), float(y[2])}] =
              Vec3d{dec[i * 3], dec[i * 3 + 1], dec[i * 3 + 2]};
        }
    }
    for (std::size_t i = 0; i < node.rel.size(); ++i) {
      const Vec3d y = to_yup(node.rel[i]);
      const bool qi = q || (!bad.empty() && !bad.count(node.feature[i]));
      if (!qi && !as_stored.empty()) {
        const Vec3d& s = as_stored.at({node.feature[i], float(y[0]), float(y[1]), float(y[2])});
        const Vec3d z = from_yup(s);
        b.add(Vec3d{o[0] + z[0], o[1] + z[1], o[2] + z[2]});
        continue;
      }
      Vec3d s;
      for (int k = 0; k < 3; ++k)
        s[size_t(k)] =
            qi ? double(quant(y[size_t(k)], e)) / 32767.0 * e : double(float(y[size_t(k)]));
      const Vec3d z = from_yup(s);
      b.add(Vec3d{o[0] + z[0], o[1] + z[1], o[2] + z[2]});
    }
  }
  return b;
}

}  // namespace citylod::io
