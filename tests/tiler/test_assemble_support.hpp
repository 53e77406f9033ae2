// Test support for `citylod assemble`: synthetic work directories (manifest +
// per-building report.json + LOD model PLYs), an independent glb reader and a
// tileset.json checker. Used by tests/tiler/test_assemble*.cpp and
// tests/cli/test_assemble*.cpp.
#pragma once

#include <meshoptimizer.h>
#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/types.hpp"
#include "citylod/io/writers.hpp"

namespace citylod::test {

namespace fs = std::filesystem;
using io::TriangleMesh;
using io::Vec3d;

// ------------------------------------------------------------ meshes

/// Closed convex solid from its vertices and faces (any winding): faces are fan
/// triangulated and oriented outward (away from the vertex centroid).
inline void add_convex(TriangleMesh& m, const std::vector<Vec3d>& v,
                       const std::vector<std::vector<int>>& faces) {
  const std::uint32_t base = std::uint32_t(m.vertices.size());
  Vec3d c{0, 0, 0};
  for (const auto& p : v)
    for (int k = 0; k < 3; ++k) c[size_t(k)] += p[size_t(k)] / double(v.size());
  m.vertices.insert(m.vertices.end(), v.begin(), v.end());
  for (const auto& f : faces)
    for (std::size_t i = 1; i + 1 < f.size(); ++i) {
      std::array<int, 3> t{f[0], f[i], f[i + 1]};
      const Vec3d &a = v[size_t(t[0])], &b = v[size_t(t[1])], &d = v[size_t(t[2])];
      const Vec3d u{b[0] - a[0], b[1] - a[1], b[2] - a[2]},
          w{d[0] - a[0], d[1] - a[1], d[2] - a[2]};
      const Vec3d n{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                    u[0] * w[1] - u[1] * w[0]};
      const Vec3d g{(a[0] + b[0] + d[0]) / 3 - c[0], (a[1] + b[1] + d[1]) / 3 - c[1],
                    (a[2] + b[2] + d[2]) / 3 - c[2]};
      if (n[0] * g[0] + n[1] * g[1] + n[2] * g[2] < 0) std::swap(t[1], t[2]);
      m.triangles.push_back(
          {base + std::uint32_t(t[0]), base + std::uint32_t(t[1]), base + std::uint32_t(t[2])});
    }
}

/// Axis-aligned box [x0,x1]x[y0,y1]x[z0,z1].
inline void add_box(TriangleMesh& m, double x0, double y0, double z0, double x1, double y1,
                    double z1) {
  std::vector<Vec3d> v;
  for (int i = 0; i < 8; ++i)
    v.push_back({(i & 1) ? x1 : x0, (i & 2) ? y1 : y0, (i & 4) ? z1 : z0});
  add_convex(m, v,
             {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}});
}

/// House with walls of height h and a gable roof of rise r (ridge along x).
inline void add_house(TriangleMesh& m, double w, double d, double h, double r) {
  std::vector<Vec3d> v{{0, 0, 0}, {w, 0, 0}, {w, d, 0}, {0, d, 0},         {0, 0, h},
                       {w, 0, h}, {w, d, h}, {0, d, h}, {0, d / 2, h + r}, {w, d / 2, h + r}};
  add_convex(m, v,
             {{0, 1, 2, 3},
              {0, 1, 5, 4},
              {3, 2, 6, 7},
              {0, 3, 7, 8, 4},
              {1, 2, 6, 9, 5},
              {4, 5, 9, 8},
              {7, 6, 9, 8}});
}

// ------------------------------------------------------------ work directories

struct SynthModel {
  std::string kind;  // "anchor" | "interpolation"
  int level = 0, step = 0;
  TriangleMesh mesh;  // relative to the chunk origin
};

struct SynthBuilding {
  std::string id;
  Vec3d origin{0, 0, 0};  // chunk origin, scene ENU
  std::vector<SynthModel> models;
  bool write_report = true;
};

/// LOD chain of a building (w x d footprint, h walls), every model closed and
/// outward oriented, each one closer (Hausdorff) to the finest than the last:
///   n <= 3: box (anchor L0) -> box + annex (interpolation) -> gable house + annex (anchor L1)
///   n >= 4: box (anchor L0) -> gable house (interpolation) -> house + annex (anchor L1)
///           -> + chimney on the ridge (anchor L2)
inline std::vector<SynthModel> lod_chain(double w, double d, double h, int n) {
  auto annex = [&](TriangleMesh& m) { add_box(m, w, 0, 0, w + 4, d / 2, h * 0.5); };
  std::vector<SynthModel> out;
  SynthModel m0{"anchor", 0, 0, {}};
  add_box(m0.mesh, 0, 0, 0, w, d, h);
  out.push_back(m0);
  if (n <= 1) return out;
  if (n <= 3) {
    SynthModel m1{"interpolation", 1, 1, {}};
    add_box(m1.mesh, 0, 0, 0, w, d, h);
    annex(m1.mesh);
    out.push_back(m1);
    if (n == 3) {
      SynthModel m2{"anchor", 1, 2, {}};
      add_house(m2.mesh, w, d, h, 3.0);
      annex(m2.mesh);
      out.push_back(m2);
    }
    return out;
  }
  SynthModel m1{"interpolation", 1, 1, {}};
  add_house(m1.mesh, w, d, h, 3.0);
  out.push_back(m1);
  SynthModel m2{"anchor", 1, 2, {}};
  add_house(m2.mesh, w, d, h, 3.0);
  annex(m2.mesh);
  out.push_back(m2);
  SynthModel m3{"anchor", 2, 3, {}};
  m3.mesh = m2.mesh;
  add_box(m3.mesh, w * 0.3, d / 2 - 0.5, h + 2, w * 0.3 + 1, d / 2 + 0.5,
          h + 4.5);  // 1.5 m above the ridge
  out.push_back(m3);
  return out;
}

/// `n` buildings on a jittered grid (pitch 30 m), each with `models` LOD models.
inline std::vector<SynthBuilding> synthetic_city(int n, int models, double pitch = 30.0) {
  std::vector<SynthBuilding> out;
  const int cols = int(std::ceil(std::sqrt(double(n))));
  for (int i = 0; i < n; ++i) {
    SynthBuilding b;
    char id[32];
    std::snprintf(id, sizeof id, "b-%04d", i);
    b.id = id;
    const double jx = double((i * 7919) % 11) - 5.0, jy = double((i * 104729) % 9) - 4.0;
    b.origin = {(i % cols) * pitch + jx - 200.0, (i / cols) * pitch + jy - 150.0, 0.5 * (i % 3)};
    const double w = 10 + (i % 5) * 2.0, d = 8 + (i % 4) * 1.5, h = 6 + (i % 7);
    b.models = lod_chain(w, d, h, models);
    out.push_back(std::move(b));
  }
  return out;
}

struct GlbFile {
  nlohmann::json json;
  std::string bin;
};

inline std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

inline std::uint32_t u32(const std::string& s, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, s.data() + at, 4);
  return v;
}

/// Parses a glb; throws std::runtime_error when the container is malformed.
inline GlbFile read_glb(const std::string& path) {
  const std::string b = read_bytes(path);
  if (b.size() < 20 || b.compare(0, 4, "glTF") != 0 || u32(b, 4) != 2 || u32(b, 8) != b.size())
    throw std::runtime_error(path + ": not a glb v2");
  const std::uint32_t jlen = u32(b, 12);
  if (u32(b, 16) != 0x4E4F534A) throw std::runtime_error(path + ": first chunk is not JSON");
  GlbFile g;
  g.json = nlohmann::json::parse(b.substr(20, jlen));
  const std::size_t at = 20 + jlen;
  if (at + 8 <= b.size()) {
    if (u32(b, at + 4) != 0x004E4942) throw std::runtime_error(path + ": second chunk is not BIN");
    g.bin = b.substr(at + 8, u32(b, at));
  }
  // EXT_meshopt_compression: decode each compressed view (meshoptimizer's
  // decoders, as a client does) and point the view at the decoded bytes.
  for (auto& bv : g.json["bufferViews"]) {
    if (!bv.contains("extensions") || !bv["extensions"].contains("EXT_meshopt_compression"))
      continue;
    const auto e = bv["extensions"]["EXT_meshopt_compression"];
    const std::size_t count = e["count"], stride = e["byteStride"], len = e["byteLength"];
    const std::size_t off = e.value("byteOffset", std::size_t(0));
    if (e["buffer"] != 0 || off + len > g.bin.size())
      throw std::runtime_error(path + ": meshopt view outside the BIN chunk");
    std::string out(count * stride, '\0');
    const auto* src = reinterpret_cast<const unsigned char*>(g.bin.data() + off);
    int rc = -1;
    if (e["mode"] == "ATTRIBUTES") {
      rc = meshopt_decodeVertexBuffer(out.data(), count, stride, src, len);
      if (rc == 0 && e.value("filter", "NONE") == "OCTAHEDRAL")
        meshopt_decodeFilterOct(out.data(), count, stride);
    } else if (e["mode"] == "TRIANGLES") {
      rc = meshopt_decodeIndexBuffer(out.data(), count, stride, src, len);
    }
    if (rc != 0) throw std::runtime_error(path + ": a meshopt view does not decode");
    while (g.bin.size() % 8) g.bin.push_back('\0');
    bv["byteOffset"] = g.bin.size();
    bv["byteLength"] = out.size();
    bv["buffer"] = 0;
    g.bin += out;
  }
  return g;
}

/// Component i of element e of an accessor, as the client sees it (normalized
/// integers divided, no node transform).
inline double accessor_value(const GlbFile& g, int acc, std::size_t e, int i) {
  const auto& a = g.json["accessors"][size_t(acc)];
  const auto& bv = g.json["bufferViews"][a["bufferView"].get<size_t>()];
  const int ct = a["componentType"];
  const std::size_t csize = (ct == 5126 || ct == 5125) ? 4 : (ct == 5122 || ct == 5123) ? 2 : 1;
  const std::string type = a["type"];
  const std::size_t ncomp = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : 4;
  const std::size_t stride = bv.value("byteStride", ncomp * csize);
  const std::size_t off = bv.value("byteOffset", std::size_t(0)) +
                          a.value("byteOffset", std::size_t(0)) + e * stride + size_t(i) * csize;
  const bool norm = a.value("normalized", false);
  switch (ct) {
    case 5126: {
      float f;
      std::memcpy(&f, g.bin.data() + off, 4);
      return f;
    }
    case 5122: {
      std::int16_t v;
      std::memcpy(&v, g.bin.data() + off, 2);
      return norm ? std::max(double(v) / 32767.0, -1.0) : double(v);
    }
    case 5123: {
      std::uint16_t v;
      std::memcpy(&v, g.bin.data() + off, 2);
      return norm ? double(v) / 65535.0 : double(v);
    }
    case 5125: {
      std::uint32_t v;
      std::memcpy(&v, g.bin.data() + off, 4);
      return double(v);
    }
    case 5121:
      return norm ? double(std::uint8_t(g.bin[off])) / 255.0 : double(std::uint8_t(g.bin[off]));
    case 5120:
      return norm ? std::max(double(std::int8_t(g.bin[off])) / 127.0, -1.0)
                  : double(std::int8_t(g.bin[off]));
  }
  throw std::runtime_error("unsupported componentType");
}

/// Every vertex of every node, in the tile frame (z-up: node TRS applied, then
/// glTF y-up -> z-up), with its feature id.
struct GlbVertex {
  Eigen::Vector3d p;
  int feature;
  std::string node;
};
inline std::vector<GlbVertex> glb_vertices(const GlbFile& g) {
  std::vector<GlbVertex> out;
  for (const auto& node : g.json["nodes"]) {
    if (!node.contains("mesh")) continue;
    Eigen::Vector3d t(0, 0, 0), s(1, 1, 1);
    if (node.contains("translation"))
      t = Eigen::Vector3d(node["translation"][0].get<double>(),
                          node["translation"][1].get<double>(),
                          node["translation"][2].get<double>());
    if (node.contains("scale"))
      s = Eigen::Vector3d(node["scale"][0].get<double>(), node["scale"][1].get<double>(),
                          node["scale"][2].get<double>());
    std::set<int> done;
    for (const auto& prim : g.json["meshes"][node["mesh"].get<size_t>()]["primitives"]) {
      const int pa = prim["attributes"]["POSITION"], fa = prim["attributes"]["_FEATURE_ID_0"];
      if (!done.insert(pa).second) continue;
      const std::size_t n = g.json["accessors"][size_t(pa)]["count"];
      for (std::size_t e = 0; e < n; ++e) {
        Eigen::Vector3d y(accessor_value(g, pa, e, 0), accessor_value(g, pa, e, 1),
                          accessor_value(g, pa, e, 2));
        y = y.cwiseProduct(s) + t;
        out.push_back({Eigen::Vector3d(y.x(), -y.z(), y.y()), int(accessor_value(g, fa, e, 0)),
                       node.value("name", std::string())});
      }
    }
  }
  return out;
}

// ------------------------------------------------------------ tileset checks

struct Box {
  Eigen::Vector3d c;
  Eigen::Matrix3d h;  // columns: half axes
};
inline Box box_of(const nlohmann::json& bv) {
  const auto& b = bv.at("box");
  Box r;
  r.c = Eigen::Vector3d(b[0].get<double>(), b[1].get<double>(), b[2].get<double>());
  for (int a = 0; a < 3; ++a)
    for (int k = 0; k < 3; ++k) r.h(k, a) = b[size_t(3 + 3 * a + k)];
  return r;
}
inline Eigen::Matrix4d matrix_of(const nlohmann::json& t) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (!t.is_array()) return m;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m(r, c) = t[size_t(4 * c + r)];
  return m;
}
/// Is point p (global frame) inside box b given in a frame with transform T?
inline bool inside_box(const Eigen::Vector3d& p, const Box& b, const Eigen::Matrix4d& T,
                       double tol = 1e-6) {
  const Eigen::Vector4d l = T.inverse() * Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
  const Eigen::Vector3d u = b.h.inverse() * (l.head<3>() - b.c);
  return u.cwiseAbs().maxCoeff() <= 1.0 + tol;
}
inline std::vector<Eigen::Vector3d> corners(const Box& b, const Eigen::Matrix4d& T) {
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d s((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
    const Eigen::Vector3d l = b.c + b.h * s;
    out.push_back((T * Eigen::Vector4d(l.x(), l.y(), l.z(), 1.0)).head<3>());
  }
  return out;
}

struct TilesetCheck {
  std::vector<std::string> problems;
  int tiles = 0, content_tiles = 0, depth = 0, leaves = 0;
  int external_files = 0;  ///< external tilesets followed
  std::vector<std::string> uris;
  std::map<int, int> tiles_per_depth;
};

/// Checks a tileset directory: required fields, geometricError strictly
/// decreasing down the tree (0 only at leaves), content and child boxes inside
/// their tile's box (transforms composed), content files present, and, when
/// `check_content`, every glb vertex inside its content box.
inline TilesetCheck check_tileset(const std::string& dir, bool check_content = true) {
  TilesetCheck r;
  nlohmann::json ts;
  try {
    ts = nlohmann::json::parse(read_bytes((fs::path(dir) / "tileset.json").string()));
  } catch (const std::exception& e) {
    r.problems.push_back(std::string("tileset.json: ") + e.what());
    return r;
  }
  auto bad = [&](const std::string& s) { r.problems.push_back(s); };
  if (!ts.contains("asset") || ts["asset"].value("version", "") != "1.1")
    bad("asset.version is not 1.1");
  if (!ts.contains("geometricError") || !ts["geometricError"].is_number())
    bad("no top-level geometricError");
  if (!ts.contains("root")) {
    bad("no root");
    return r;
  }
  if (ts["root"].value("refine", "") != "REPLACE") bad("root.refine is not REPLACE");
  const double top_error = ts.value("geometricError", 0.0);
  // `same_tile`: the root of an external tileset, which stands for the tile that
  // references it (same error, not counted again); `base`: its file's directory.
  std::function<void(const nlohmann::json&, const std::string&, const Eigen::Matrix4d&, const Box*,
                     const Eigen::Matrix4d*, double, int, const fs::path&, bool)>
      walk = [&](const nlohmann::json& t, const std::string& path, const Eigen::Matrix4d& parentT,
                 const Box* parent_box, const Eigen::Matrix4d* parent_boxT, double parent_error,
                 int depth, const fs::path& base, bool same_tile) {
        if (!same_tile) {
          ++r.tiles;
          ++r.tiles_per_depth[depth];
          r.depth = std::max(r.depth, depth);
        }
        if (!t.contains("boundingVolume") || !t["boundingVolume"].contains("box")) {
          bad(path + ": no boundingVolume.box");
          return;
        }
        if (!t.contains("geometricError") || !t["geometricError"].is_number()) {
          bad(path + ": no geometricError");
          return;
        }
        const double ge = t["geometricError"];
        const Eigen::Matrix4d T = parentT * matrix_of(t.value("transform", nlohmann::json()));
        const Box box = box_of(t["boundingVolume"]);
        if (depth == 0 || same_tile ? ge > parent_error : ge >= parent_error)
          bad(path + ": geometricError " + std::to_string(ge) + " not below parent's " +
              std::to_string(parent_error));
        const std::string curi = t.contains("content") ? t["content"].value("uri", "") : "";
        const bool external = curi.size() > 5 && curi.substr(curi.size() - 5) == ".json";
        if (external) {  // an external tileset: its root continues this tile
          nlohmann::json ext;
          try {
            ext = nlohmann::json::parse(read_bytes((base / curi).string()));
          } catch (const std::exception& e) {
            bad(path + ": " + curi + ": " + e.what());
            return;
          }
          if (!ext.contains("asset") || ext["asset"].value("version", "") != "1.1")
            bad(curi + ": asset.version is not 1.1");
          if (!ext.contains("root") || ext["root"].value("refine", "") != "REPLACE") {
            bad(curi + ": no root with refine REPLACE");
            return;
          }
          if (t.contains("children")) bad(path + ": external tileset and children");
          ++r.external_files;
          walk(ext["root"], path + ">" + curi,
               parentT * matrix_of(t.value("transform", nlohmann::json())), parent_box, parent_boxT,
               ge, depth, (base / curi).parent_path(), true);
          return;
        }
        const bool leaf = !t.contains("children") || t["children"].empty();
        if (leaf) ++r.leaves;
        if (leaf && ge != 0) bad(path + ": leaf with geometricError " + std::to_string(ge));
        if (!leaf && ge <= 0) bad(path + ": inner tile with geometricError 0");
        if (parent_box)
          for (const auto& p : corners(box, T))
            if (!inside_box(p, *parent_box, *parent_boxT, 1e-6)) {
              bad(path + ": bounding volume leaves the parent's");
              break;
            }
        if (t.contains("content")) {
          ++r.content_tiles;
          const auto& c = t["content"];
          const std::string uri = c.value("uri", "");
          r.uris.push_back(uri);
          const std::string file = (base / uri).string();
          if (uri.empty() || !fs::exists(file)) bad(path + ": content '" + uri + "' missing");
          Box cbox = box;
          if (c.contains("boundingVolume")) {
            cbox = box_of(c["boundingVolume"]);
            for (const auto& p : corners(cbox, T))
              if (!inside_box(p, box, T, 1e-6)) {
                bad(path + ": content bounding volume leaves the tile's");
                break;
              }
          }
          if (check_content && fs::exists(file)) {
            try {
              const GlbFile g = read_glb(file);
              for (const auto& v : glb_vertices(g)) {
                const Eigen::Vector3d p =
                    (T * Eigen::Vector4d(v.p.x(), v.p.y(), v.p.z(), 1)).head<3>();
                if (!inside_box(p, cbox, T, 1e-7)) {
                  bad(path + ": a vertex of " + uri + " lies outside its content bounding volume");
                  break;
                }
              }
            } catch (const std::exception& e) {
              bad(path + ": " + e.what());
            }
          }
        }
        if (t.contains("children"))
          for (std::size_t i = 0; i < t["children"].size(); ++i)
            walk(t["children"][i], path + "/" + std::to_string(i), T, &box, &T, ge, depth + 1, base,
                 false);
      };
  walk(ts["root"], "root", Eigen::Matrix4d::Identity(), nullptr, nullptr, top_error, 0,
       fs::path(dir), false);
  return r;
}

/// All files under a directory (relative path -> bytes), for determinism checks.
inline std::map<std::string, std::string> dir_contents(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file())
      out[fs::relative(e.path(), dir).string()] = read_bytes(e.path().string());
  return out;
}

}  // namespace citylod::test
