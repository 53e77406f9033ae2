// glb writer, flat shading: a mesh -> one vertex per source vertex, face
// normal and colour, triangles per primitive class (surface class, coloured
// or not); the sizes GlbBuilder will store.
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "citylod/io/error.hpp"
#include "citylod/io/gltf.hpp"
#include "gltf_internal.hpp"

namespace citylod::io {

namespace detail {

namespace {

struct VertexKey {
  std::uint32_t vertex;
  std::int32_t nx, ny, nz;
  std::uint32_t rgba;
  bool operator==(const VertexKey& o) const {
    return vertex == o.vertex && nx == o.nx && ny == o.ny && nz == o.nz && rgba == o.rgba;
  }
};
struct VertexKeyHash {
  std::size_t operator()(const VertexKey& k) const {
    std::uint64_t h = k.vertex;
    h = h * 0x9E3779B97F4A7C15ULL ^ std::uint32_t(k.nx);
    h = h * 0x9E3779B97F4A7C15ULL ^ std::uint32_t(k.ny);
    h = h * 0x9E3779B97F4A7C15ULL ^ std::uint32_t(k.nz);
    h = h * 0x9E3779B97F4A7C15ULL ^ k.rgba;
    return std::size_t(h ^ (h >> 29));
  }
};

}  // namespace

FlatMesh flat_shade(const TriangleMesh& mesh, const std::vector<Rgba8>& colours) {
  FlatMesh out;
  if (!colours.empty() && colours.size() != mesh.triangles.size())
    throw IoError(kWhere, std::to_string(colours.size()) + " triangle colours for " +
                              std::to_string(mesh.triangles.size()) + " triangles");
  std::unordered_map<VertexKey, std::uint32_t, VertexKeyHash> index;
  index.reserve(mesh.triangles.size() * 2);
  const std::size_t nv = mesh.vertices.size();
  for (std::size_t ti = 0; ti < mesh.triangles.size(); ++ti) {
    const auto& t = mesh.triangles[ti];
    const Rgba8 rgb = colours.empty() || colours[ti][3] == 0 ? Rgba8{0, 0, 0, 0} : colours[ti];
    if (t[0] >= nv || t[1] >= nv || t[2] >= nv)
      throw IoError(kWhere, "triangle refers to vertex " +
                                std::to_string(std::max({t[0], t[1], t[2]})) + " of " +
                                std::to_string(nv));
    const Vec3d& a = mesh.vertices[t[0]];
    const Vec3d& b = mesh.vertices[t[1]];
    const Vec3d& c = mesh.vertices[t[2]];
    const Vec3d u{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const Vec3d v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    Vec3d n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 1e-10)) continue;  // degenerate (or NaN)
    for (auto& x : n) x /= len;
    const int cls = int(classify_normal(n)) + (rgb[3] ? 3 : 0);
    // Triangles of one planar face share vertices: the normal key is coarse
    // enough to absorb rounding, the first triangle's normal is kept.
    const std::int32_t nx = std::int32_t(std::lround(n[0] * 4096)),
                       ny = std::int32_t(std::lround(n[1] * 4096)),
                       nz = std::int32_t(std::lround(n[2] * 4096));
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t packed = std::uint32_t(rgb[0]) | std::uint32_t(rgb[1]) << 8 |
                                   std::uint32_t(rgb[2]) << 16 | std::uint32_t(rgb[3]) << 24;
      const VertexKey key{t[size_t(k)], nx, ny, nz, packed};
      auto [it, fresh] = index.emplace(key, std::uint32_t(out.positions.size()));
      if (fresh) {
        out.positions.push_back(mesh.vertices[t[size_t(k)]]);
        out.normals.push_back({float(n[0]), float(n[1]), float(n[2])});
        out.colours.push_back(rgb);
      }
      out.indices[size_t(cls)].push_back(it->second);
    }
    ++out.triangles;
  }
  return out;
}

std::uint8_t srgb_to_linear_u8(std::uint8_t v) {
  static const std::array<std::uint8_t, 256> table = [] {
    std::array<std::uint8_t, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      const double l = c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
      t[size_t(i)] = std::uint8_t(std::lround(l * 255.0));
    }
    return t;
  }();
  return table[v];
}

}  // namespace detail

namespace {

std::size_t vertex_bytes(bool quantize) {
  return quantize ? 8 + 8 + 4 : 12 + 12 + 4;
}

}  // namespace

SurfaceClass classify_normal(const Vec3d& n) {
  if (n[2] >= 0.34) return SurfaceClass::roof;  // slope below ~70 degrees
  if (n[2] <= -0.34) return SurfaceClass::base;
  return SurfaceClass::wall;
}

GlbMeshSize glb_mesh_size(const TriangleMesh& mesh, bool quantize) {
  const detail::FlatMesh f = detail::flat_shade(mesh);
  GlbMeshSize s;
  s.vertices = f.positions.size();
  s.triangles = f.triangles;
  // Indices counted as 4 bytes (uint16 when a node stays below 65536 vertices).
  s.bytes = s.vertices * vertex_bytes(quantize) + s.triangles * 12;
  s.float_bytes = s.vertices * vertex_bytes(false) + s.triangles * 12;
  return s;
}

}  // namespace citylod::io
