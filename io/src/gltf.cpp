// glb writer: flat-shaded per-feature meshes, three materials, EXT_mesh_features
// and EXT_structural_metadata, optional KHR_mesh_quantization. tinygltf (the
// Debian library) builds and serializes the glTF; its header stays here.
#include "citylod/io/gltf.hpp"

#include "citylod/io/weld.hpp"

#include <meshoptimizer.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "citylod/io/error.hpp"

namespace citylod::io {

namespace {

constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr const char* kWhere = "glb";

/// z-up (ENU) -> glTF y-up: (x, y, z) -> (x, z, -y). A rotation: windings keep.
inline Vec3d to_yup(const Vec3d& p) {
  return {p[0], p[2], -p[1]};
}
inline Vec3d from_yup(const Vec3d& p) {
  return {p[0], -p[2], p[1]};
}

/// Primitive classes: the three surface classes with their fixed material,
/// then the same three coloured (COLOR_0, white "*_rgb" material).
constexpr int kClasses = 6;
using Indices = std::array<std::vector<std::uint32_t>, kClasses>;

/// A mesh split into flat-shaded vertices (one per source vertex, face
/// normal and colour) and one index list per primitive class.
struct FlatMesh {
  std::vector<Vec3d> positions;
  std::vector<Vec3f> normals;
  std::vector<Rgba8> colours;  ///< one per vertex (a = 0: none)
  Indices indices;
  std::size_t triangles = 0;
};

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

FlatMesh flat_shade(const TriangleMesh& mesh, const std::vector<Rgba8>& colours = {}) {
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

/// An 8-bit sRGB value as an 8-bit linear one (glTF's vertex colours are linear).
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

std::size_t vertex_bytes(bool quantize) {
  return quantize ? 8 + 8 + 4 : 12 + 12 + 4;
}

struct Material {
  const char* name;
  double r, g, b, roughness;
};
// Linear-space base colours: light plaster walls, terracotta roofs, grey base.
constexpr Material kMaterials[3] = {{"wall", 0.80, 0.76, 0.68, 0.9},
                                    {"roof", 0.45, 0.13, 0.08, 0.8},
                                    {"base", 0.25, 0.25, 0.25, 1.0}};

using Value = tinygltf::Value;
Value str(const std::string& s) {
  return Value(s);
}
Value obj(Value::Object o) {
  return Value(std::move(o));
}

/// Appends bufferViews to buffer 0, every one 8-byte aligned (required for
/// property table columns, harmless for the rest).
struct BinWriter {
  tinygltf::Model& model;
  std::vector<unsigned char>& data;

  int view(const void* p, std::size_t n, int target, int stride = 0) {
    while (data.size() % 8) data.push_back(0);
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = data.size();
    bv.byteLength = n;
    bv.byteStride = size_t(stride);
    bv.target = target;
    const auto* b = static_cast<const unsigned char*>(p);
    data.insert(data.end(), b, b + n);
    model.bufferViews.push_back(bv);
    return int(model.bufferViews.size() - 1);
  }
  /// EXT_meshopt_compression: the view's data encoded (the view points at the
  /// encoded bytes until glb() rewrites it onto the fallback buffer).
  struct Meshopt {
    int view;
    std::size_t raw_length, stride, count;
    const char* mode;    // "ATTRIBUTES" | "TRIANGLES"
    const char* filter;  // "NONE" | "OCTAHEDRAL"
  };
  std::vector<Meshopt>* meshopt = nullptr;  // set: compress vertex/index views

  /// Vertex attribute data, `count` elements of `stride` bytes; `plain_stride`:
  /// the bufferView's byteStride without compression (0 = none).
  int attributes(const void* p, std::size_t count, std::size_t stride, const char* filter,
                 int plain_stride) {
    if (!meshopt) return view(p, count * stride, kArrayBuffer, plain_stride);
    std::vector<unsigned char> enc(meshopt_encodeVertexBufferBound(count, stride));
    enc.resize(meshopt_encodeVertexBuffer(enc.data(), enc.size(), p, count, stride));
    if (enc.empty()) throw IoError(kWhere, "meshopt vertex encoding failed");
    const int v = view(enc.data(), enc.size(), kArrayBuffer, int(stride));
    meshopt->push_back({v, count * stride, stride, count, "ATTRIBUTES", filter});
    return v;
  }
  int triangles(const std::vector<std::uint32_t>& ix, std::size_t vertices, bool u16) {
    const std::size_t size = u16 ? 2 : 4;
    if (!meshopt) {
      if (u16) {
        std::vector<std::uint16_t> s(ix.begin(), ix.end());
        return view(s.data(), s.size() * 2, kElementArrayBuffer);
      }
      return view(ix.data(), ix.size() * 4, kElementArrayBuffer);
    }
    std::vector<unsigned char> enc(meshopt_encodeIndexBufferBound(ix.size(), vertices));
    enc.resize(meshopt_encodeIndexBuffer(enc.data(), enc.size(), ix.data(), ix.size()));
    if (enc.empty()) throw IoError(kWhere, "meshopt index encoding failed");
    const int v = view(enc.data(), enc.size(), kElementArrayBuffer);
    meshopt->push_back({v, ix.size() * size, size, ix.size(), "TRIANGLES", "NONE"});
    return v;
  }
  int accessor(int view, int component, int type, std::size_t count, bool normalized = false,
               std::vector<double> min = {}, std::vector<double> max = {}) {
    tinygltf::Accessor a;
    a.bufferView = view;
    a.byteOffset = 0;
    a.componentType = component;
    a.type = type;
    a.count = count;
    a.normalized = normalized;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    model.accessors.push_back(a);
    return int(model.accessors.size() - 1);
  }
};

std::uint32_t le32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
void put32(std::string& b, std::uint32_t v) {
  char c[4];
  std::memcpy(c, &v, 4);
  b.append(c, 4);
}

/// The glb tinygltf wrote, finished: the EXT_structural_metadata schema put in
/// (`schema`, or `schemaUri` when `schema_uri` is set) and every encoded
/// bufferView moved onto a fallback buffer (no data) and described by its
/// EXT_meshopt_compression object pointing at the encoded bytes in the BIN chunk.
std::string finish_glb(const std::string& glb, const std::vector<BinWriter::Meshopt>& views,
                       const nlohmann::json& schema, const std::string& schema_uri) {
  const std::uint32_t json_len = le32(glb, 12);
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(glb.substr(20, json_len));
  const std::size_t bin_at = 20 + json_len;
  const std::uint32_t bin_len = le32(glb, bin_at);
  {
    auto& meta = j["extensions"]["EXT_structural_metadata"];
    nlohmann::ordered_json m;
    if (schema_uri.empty())
      m["schema"] = nlohmann::ordered_json::parse(schema.dump());
    else
      m["schemaUri"] = schema_uri;
    for (auto& [k, v] : meta.items()) m[k] = v;
    meta = std::move(m);
  }
  // "mode" 4 (TRIANGLES) is the default: not written
  if (j.contains("meshes"))
    for (auto& mesh : j["meshes"])
      for (auto& prim : mesh["primitives"])
        if (prim.value("mode", 4) == 4) prim.erase("mode");
  std::size_t fallback = 0;
  for (const auto& m : views) {
    auto& bv = j["bufferViews"][size_t(m.view)];
    nlohmann::ordered_json ext{{"buffer", 0},
                               {"byteOffset", bv.value("byteOffset", 0)},
                               {"byteLength", bv["byteLength"]},
                               {"byteStride", m.stride},
                               {"mode", m.mode},
                               {"count", m.count}};
    if (std::string(m.filter) != "NONE") ext["filter"] = m.filter;
    while (fallback % 8) ++fallback;
    bv["buffer"] = 1;
    bv["byteOffset"] = fallback;
    bv["byteLength"] = m.raw_length;
    if (std::string(m.mode) == "ATTRIBUTES")
      bv["byteStride"] = m.stride;
    else
      bv.erase("byteStride");
    if (ext["byteOffset"] == 0) ext.erase("byteOffset");  // the default
    if (fallback == 0) bv.erase("byteOffset");
    bv["extensions"]["EXT_meshopt_compression"] = ext;
    fallback += m.raw_length;
  }
  if (!views.empty()) {
    j["buffers"] = nlohmann::ordered_json::array(
        {{{"byteLength", bin_len}},
         {{"byteLength", fallback},
          {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}});
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
      std::vector<std::string> e = j.value(key, std::vector<std::string>{});
      e.push_back("EXT_meshopt_compression");
      std::sort(e.begin(), e.end());
      j[key] = e;
    }
  }
  std::string js = j.dump();
  while (js.size() % 4) js.push_back(' ');
  std::string out;
  out.reserve(28 + js.size() + bin_len);
  out.append("glTF", 4);
  put32(out, 2);
  put32(out, std::uint32_t(12 + 8 + js.size() + 8 + bin_len));
  put32(out, std::uint32_t(js.size()));
  out.append("JSON", 4);
  out += js;
  put32(out, bin_len);
  out.append("BIN\0", 4);
  out.append(glb, bin_at + 8, bin_len);
  return out;
}

/// A STRING attribute's text: strings as they are, other JSON values as JSON
/// text, a missing one (nullptr) as the noData string NUL (see schema_json).
std::string attribute_text(const nlohmann::json* v) {
  return !v ? std::string(1, '\0') : v->is_string() ? v->get<std::string>() : v->dump();
}

/// The EXT_structural_metadata schema: class "building" (our properties and the
/// source attributes) and enum LodKind. Keys sorted (nlohmann::json).
nlohmann::json schema_json(const std::vector<GlbAttribute>& attributes) {
  using J = nlohmann::json;
  auto prop = [](const char* type, const char* component, const char* description) {
    J o{{"type", type}, {"description", description}};
    if (component) o["componentType"] = component;
    return o;
  };
  J props{
      {"building_id", prop("STRING", nullptr, "building (chunk) id of the work directory")},
      {"lod_kind",
       {{"type", "ENUM"},
        {"enumType", "LodKind"},
        {"description", "anchor or interpolation model of the LOD-Tree, or the fallback outline"}}},
      {"level", prop("SCALAR", "INT32", "LOD-Tree level set of the model")},
      {"step", prop("SCALAR", "INT32", "traversal step that produced the model")},
      {"model_index", prop("SCALAR", "INT32", "index in the building's kept models, 0 = coarsest")},
      {"model_count", prop("SCALAR", "INT32", "number of kept models of the building")},
      {"height", prop("SCALAR", "FLOAT32", "vertical extent of the model, metres")},
      {"footprint_area",
       prop("SCALAR", "FLOAT32", "footprint area of the building, square metres")},
      {"geometric_error", prop("SCALAR", "FLOAT32", "distance to the finest model, metres")},
      {"rmse",
       {{"type", "SCALAR"},
        {"componentType", "FLOAT32"},
        {"noData", -1.0},
        {"description",
         "RMSE of the building's input points to the model, metres (-1: not measured)"}}},
      {"valid", prop("BOOLEAN", nullptr,
                     "the model is a valid solid: closed, oriented, no pinched vertex, one outer "
                     "shell, no self-intersection")},
  };
  J values = J::array({{{"name", "anchor"}, {"value", 0}},
                       {{"name", "interpolation"}, {"value", 1}},
                       {{"name", "fallback"}, {"value", 2}}});
  J enums{{"LodKind", {{"valueType", "UINT8"}, {"values", values}}}};
  for (const GlbAttribute& a : attributes) {
    J def{{"name", a.name}, {"description", "footprint attribute"}};
    switch (a.type) {
      case GlbAttribute::Type::int64:
        def["type"] = "SCALAR";
        def["componentType"] = "INT64";
        break;
      case GlbAttribute::Type::float64:
        def["type"] = "SCALAR";
        def["componentType"] = "FLOAT64";
        if (a.no_data) def["noData"] = std::numeric_limits<double>::lowest();
        break;
      case GlbAttribute::Type::boolean:
        def["type"] = "BOOLEAN";
        break;
      case GlbAttribute::Type::string:
        if (!a.enum_values.empty()) {
          def["type"] = "ENUM";
          def["enumType"] = a.property;
          J vs = J::array();
          for (std::size_t i = 0; i < a.enum_values.size(); ++i)
            vs.push_back({{"name", a.enum_values[i]}, {"value", i}});
          enums[a.property] = {{"valueType", "UINT8"}, {"values", vs}};
          if (a.no_data) def["noData"] = std::string(1, '\0');
          break;
        }
        def["type"] = "STRING";
        // A missing value is the one-character string NUL, never a source value
        // (GDAL strings are C strings); "" would leave a column of missing
        // values without characters, which a bufferView cannot hold.
        if (a.no_data) def["noData"] = std::string(1, '\0');
        break;
    }
    props[a.property] = std::move(def);
  }
  return {{"id", "citylod"},
          {"classes", {{"building", {{"name", "Building LOD model"}, {"properties", props}}}}},
          {"enums", enums}};
}

}  // namespace

const char* to_string(LodKind k) {
  switch (k) {
    case LodKind::anchor:
      return "anchor";
    case LodKind::interpolation:
      return "interpolation";
    case LodKind::fallback:
      return "fallback";
  }
  return "?";
}

std::vector<GlbAttribute> glb_attribute_schema(const std::vector<const nlohmann::json*>& objects) {
  struct Seen {
    std::size_t null = 0, boolean = 0, integer = 0, real = 0, other = 0;
    bool big = false;  // an integer beyond 2^53 (not exact as a double)
  };
  std::map<std::string, Seen> seen;
  for (const nlohmann::json* o : objects)
    if (o && o->is_object())
      for (const auto& [k, v] : o->items()) seen[k];
  for (auto& [name, s] : seen)
    for (const nlohmann::json* o : objects) {
      const nlohmann::json* v = nullptr;
      if (o && o->is_object()) {
        const auto it = o->find(name);
        if (it != o->end()) v = &*it;
      }
      if (!v || v->is_null())
        ++s.null;
      else if (v->is_boolean())
        ++s.boolean;
      else if (v->is_number_integer()) {
        ++s.integer;
        const std::int64_t lim = std::int64_t(1) << 53;
        if (v->is_number_unsigned())
          s.big = s.big || v->get<std::uint64_t>() > std::uint64_t(lim);
        else
          s.big = s.big || v->get<std::int64_t>() > lim || v->get<std::int64_t>() < -lim;
      } else if (v->is_number())
        ++s.real;
      else
        ++s.other;
    }
  std::vector<GlbAttribute> out;
  std::set<std::string> ids;
  for (const auto& [name, s] : seen) {
    GlbAttribute a;
    a.name = name;
    const std::size_t numbers = s.integer + s.real;
    if (s.other == 0 && s.boolean == 0 && numbers > 0) {
      if (s.real == 0 && s.null == 0)
        a.type = GlbAttribute::Type::int64;
      else
        a.type = s.big ? GlbAttribute::Type::string : GlbAttribute::Type::float64;
    } else if (s.other == 0 && numbers == 0 && s.boolean > 0 && s.null == 0) {
      a.type = GlbAttribute::Type::boolean;
    }
    a.no_data = s.null > 0;
    if (a.type == GlbAttribute::Type::string) {
      std::set<std::string> distinct;  // a missing value: the noData string NUL
      for (const nlohmann::json* o : objects) {
        const nlohmann::json* v = nullptr;
        if (o && o->is_object()) {
          const auto it = o->find(name);
          if (it != o->end() && !it->is_null()) v = &*it;
        }
        distinct.insert(attribute_text(v));
        if (distinct.size() > 255) break;
      }
      if (distinct.size() <= 255 &&
          (distinct.size() == 1 || distinct.size() * 4 <= objects.size() * 3))
        a.enum_values.assign(distinct.begin(), distinct.end());
    }
    std::string id = "fp_";
    for (char c : name) id += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
    std::string unique = id;
    for (int k = 2; !ids.insert(unique).second; ++k) unique = id + "_" + std::to_string(k);
    a.property = unique;
    out.push_back(std::move(a));
  }
  return out;
}

std::string glb_schema(const GlbOptions& options) {
  return schema_json(options.attributes).dump();
}

const char* to_string(Compression c) {
  return c == Compression::meshopt ? "meshopt" : "none";
}

Compression compression_from_string(const std::string& s) {
  if (s == "none") return Compression::none;
  if (s == "meshopt") return Compression::meshopt;
  throw std::invalid_argument("compression must be none or meshopt, got '" + s + "'");
}

SurfaceClass classify_normal(const Vec3d& n) {
  if (n[2] >= 0.34) return SurfaceClass::roof;  // slope below ~70 degrees
  if (n[2] <= -0.34) return SurfaceClass::base;
  return SurfaceClass::wall;
}

GlbMeshSize glb_mesh_size(const TriangleMesh& mesh, bool quantize) {
  const FlatMesh f = flat_shade(mesh);
  GlbMeshSize s;
  s.vertices = f.positions.size();
  s.triangles = f.triangles;
  // Indices counted as 4 bytes (uint16 when a node stays below 65536 vertices).
  s.bytes = s.vertices * vertex_bytes(quantize) + s.triangles * 12;
  s.float_bytes = s.vertices * vertex_bytes(false) + s.triangles * 12;
  return s;
}

// ------------------------------------------------------------------ builder
struct GlbBuilder::Impl {
  struct Node {
    std::string name;
    std::vector<Vec3d> rel;  // z-up, relative to origin
    std::vector<Vec3f> normals;
    std::vector<float> feature;
    std::vector<Rgba8> colours;  // one per vertex (a = 0: none)
    Indices indices;
    /// features stored with float positions (set by Impl::snapped)
    std::set<float> float_features;
    bool coloured() const {
      for (int c = 3; c < kClasses; ++c)
        if (!indices[size_t(c)].empty()) return true;
      return false;
    }
  };
  Vec3d origin;
  GlbOptions opt;
  std::vector<Node> nodes;
  std::vector<GlbFeature> features;
  std::size_t triangles = 0;

  /// Uniform dequantization scale of a node (KHR_mesh_quantization).
  static double quant_extent(const Node& n) {
    double e = 0;
    for (const auto& p : n.rel)
      for (double x : p) e = std::max(e, std::fabs(x));
    return e > 1e-3 ? e : 1e-3;
  }
  static std::int16_t quant(double x, double extent) {
    const double q = std::round(x / extent * 32767.0);
    return std::int16_t(std::clamp(q, -32767.0, 32767.0));
  }
  /// Whether int16 positions keep every feature's distinct vertices distinct:
  /// two corners closer than a quantization step would merge and make a
  /// closed model non-manifold. Such a node is written with float positions.
  /// The features of a node whose distinct corners int16 would merge.
  static std::set<float> unquantizable(const Node& n) {
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
  /// The vertices and triangles of the features in `features` (in_set) or of
  /// the others, renumbered.
  static Node part(const Node& n, const std::set<float>& features, bool in_set) {
    Node out;
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
  /// meshopt, float positions (y-up, relative): meshoptimizer's EXPONENTIAL
  /// filter with the fewest mantissa bits (of 16, 18, ..., 24) that keep every
  /// coordinate within the tolerance and each feature's distinct corners
  /// distinct. With `opt.snapped_is_valid` the tolerance is the node's int16
  /// step and every valid feature must be a valid solid as decoded at those
  /// bits; otherwise (or failing that) the tolerance is 1/256 of the step
  /// (about float32 precision: up to the int16 step, unchecked, turned a
  /// sub-step sliver of a Delft model self-intersecting). Returns the bits
  /// (0: none qualifies, plain float).
  int exp_bits(const Node& n, double extent) const {
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
  /// The float positions of `n` (y-up) through the EXPONENTIAL filter with
  /// `bits`: the filtered words and what a client decodes.
  static void exp_encode(const Node& n, int bits, std::vector<std::int32_t>& encoded,
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
  /// exp_bits of the float part `fpart` of stored node `ni`, computed once
  /// (the filter is per vertex: the codec order does not change it).
  int float_bits(std::size_t ni, const Node& fpart, double extent) const {
    const auto it = float_bits_of.find(ni);
    if (it != float_bits_of.end()) return it->second;
    return float_bits_of[ni] = exp_bits(fpart, extent);
  }
  mutable std::map<std::size_t, int> float_bits_of;
  /// Whether every valid feature of `n` is a valid solid with the positions
  /// `decoded` (y-up, 3 floats a vertex; corners welded by position).
  bool decoded_solids_valid(const Node& n, const std::vector<float>& decoded) const {
    std::map<float, TriangleMesh> meshes;
    std::map<std::array<float, 4>, std::uint32_t> vid;
    auto vertex = [&](std::uint32_t i) {
      const std::array<float, 4> key{n.feature[i], decoded[i * 3], decoded[i * 3 + 1],
                                     decoded[i * 3 + 2]};
      TriangleMesh& m = meshes[n.feature[i]];
      const auto [it, fresh] = vid.emplace(key, std::uint32_t(m.vertices.size()));
      if (fresh)
        m.vertices.push_back(
            from_yup(Vec3d{decoded[i * 3], decoded[i * 3 + 1], decoded[i * 3 + 2]}));
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
  Node snapped(const Node& in) const {
    Node n = in;
    n.float_features.clear();
    if (!(opt.quantize || opt.compression == Compression::meshopt)) return n;
    const std::set<float> bad = unquantizable(in);
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
      return from_yup(Vec3d{double(k[0]) / 32767.0 * e, double(k[1]) / 32767.0 * e,
                            double(k[2]) / 32767.0 * e});
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
  /// The nodes as stored (see snapped), computed once.
  const std::vector<Node>& stored_nodes() const {
    if (!stored) {
      stored = std::make_unique<std::vector<Node>>();
      for (const auto& node : nodes) stored->push_back(snapped(node));
    }
    return *stored;
  }
  mutable std::unique_ptr<std::vector<Node>> stored;
  /// A node's triangles in vertex-cache order (per primitive) and its vertices
  /// in first-use order, each followed by the other vertices of its corner
  /// (same feature, same position: flat shading stores a corner once per face
  /// normal): consecutive equal positions are what meshoptimizer's vertex
  /// codec stores in the fewest bits. Same surfaces, same features.
  static Node codec_order(const Node& in, bool corners_together, bool strip) {
    Node out = in;
    const std::size_t nv = in.rel.size();
    std::vector<unsigned int> all;
    for (auto& ix : out.indices) {
      if (ix.empty()) continue;
      if (strip)
        meshopt_optimizeVertexCacheStrip(ix.data(), ix.data(), ix.size(), nv);
      else
        meshopt_optimizeVertexCache(ix.data(), ix.data(), ix.size(), nv);
      all.insert(all.end(), ix.begin(), ix.end());
    }
    // the vertices of each corner, in first-use order (unreferenced ones last)
    std::vector<unsigned int> use_order;
    use_order.reserve(nv);
    std::vector<char> seen(nv, 0);
    for (unsigned int v : all)
      if (!seen[v]) {
        seen[v] = 1;
        use_order.push_back(v);
      }
    for (std::size_t v = 0; v < nv; ++v)
      if (!seen[v]) use_order.push_back(static_cast<unsigned int>(v));
    std::map<std::array<double, 4>, std::vector<unsigned int>> corners;
    for (unsigned int v : use_order)
      corners[{double(in.feature[v]), in.rel[v][0], in.rel[v][1], in.rel[v][2]}].push_back(v);
    std::vector<unsigned int> remap(nv, ~0u);
    unsigned int next = 0;
    for (unsigned int v : use_order) {
      if (remap[v] != ~0u) continue;
      if (!corners_together) {
        remap[v] = next++;
        continue;
      }
      for (unsigned int u :
           corners.at({double(in.feature[v]), in.rel[v][0], in.rel[v][1], in.rel[v][2]}))
        remap[u] = next++;
    }
    for (std::size_t i = 0; i < nv; ++i) {
      out.rel[remap[i]] = in.rel[i];
      out.normals[remap[i]] = in.normals[i];
      out.feature[remap[i]] = in.feature[i];
      out.colours[remap[i]] = in.colours[i];
    }
    for (auto& ix : out.indices)
      for (auto& v : ix) v = remap[v];
    return out;
  }
  bool quantized(const Node& n) const {
    return (opt.quantize || opt.compression == Compression::meshopt) && n.float_features.empty();
  }
};

GlbBuilder::GlbBuilder(const Vec3d& origin, GlbOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->origin = origin;
  impl_->opt = std::move(options);
}
GlbBuilder::~GlbBuilder() = default;
GlbBuilder::GlbBuilder(GlbBuilder&&) noexcept = default;
GlbBuilder& GlbBuilder::operator=(GlbBuilder&&) noexcept = default;

void GlbBuilder::begin_node(const std::string& name) {
  impl_->nodes.emplace_back();
  impl_->nodes.back().name = name;
  impl_->stored.reset();
  impl_->float_bits_of.clear();
}

std::uint32_t GlbBuilder::add_feature(const GlbFeature& meta, const TriangleMesh& mesh,
                                      const std::vector<Rgba8>& colours) {
  if (impl_->nodes.empty()) begin_node("content");
  auto& node = impl_->nodes.back();
  impl_->stored.reset();
  impl_->float_bits_of.clear();
  const std::uint32_t fid = std::uint32_t(impl_->features.size());
  if (fid >= (1u << 24))
    throw IoError(kWhere, "more than 2^24 features in one glb (float feature ids)");
  impl_->features.push_back(meta);
  const FlatMesh f = flat_shade(mesh, colours);
  const std::uint32_t base = std::uint32_t(node.rel.size());
  const Vec3d& o = impl_->origin;
  for (std::size_t i = 0; i < f.positions.size(); ++i) {
    const Vec3d& p = f.positions[i];
    node.rel.push_back({p[0] - o[0], p[1] - o[1], p[2] - o[2]});
    node.normals.push_back(f.normals[i]);
    node.feature.push_back(float(fid));
    node.colours.push_back(f.colours[i]);
  }
  for (int c = 0; c < kClasses; ++c)
    for (std::uint32_t i : f.indices[size_t(c)]) node.indices[size_t(c)].push_back(base + i);
  impl_->triangles += f.triangles;
  return fid;
}

std::size_t GlbBuilder::feature_count() const {
  return impl_->features.size();
}
std::size_t GlbBuilder::triangle_count() const {
  return impl_->triangles;
}
std::size_t GlbBuilder::vertex_count() const {
  std::size_t n = 0;
  for (const auto& node : impl_->nodes) n += node.rel.size();
  return n;
}

BBox3 GlbBuilder::stored_bounds() const {
  BBox3 b;
  const Vec3d& o = impl_->origin;
  const std::vector<Impl::Node>& nodes = impl_->stored_nodes();
  for (std::size_t ni = 0; ni < nodes.size(); ++ni) {
    const Impl::Node& node = nodes[ni];
    const double e = Impl::quant_extent(node);
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
          bad.empty() || bad.size() == all.size() ? node : Impl::part(node, bad, true);
      std::vector<std::int32_t> enc;
      const int bits = impl_->float_bits(ni, fpart, e);
      if (bits > 0) Impl::exp_encode(fpart, bits, enc, dec);
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
            qi ? double(Impl::quant(y[size_t(k)], e)) / 32767.0 * e : double(float(y[size_t(k)]));
      const Vec3d z = from_yup(s);
      b.add(Vec3d{o[0] + z[0], o[1] + z[1], o[2] + z[2]});
    }
  }
  return b;
}

std::string GlbBuilder::glb() const {
  const Impl& im = *impl_;
  if (im.features.empty()) throw IoError(kWhere, "no features to write");
  std::vector<char> node_q;  // per node: int16 positions (see Impl::quantizable)
  const std::vector<Impl::Node>& nodes = im.stored_nodes();
  for (const auto& node : nodes) node_q.push_back(im.quantized(node) ? 1 : 0);
  const bool q = std::find(node_q.begin(), node_q.end(), 1) != node_q.end();

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = im.opt.generator;
  model.extensionsUsed = {"EXT_mesh_features", "EXT_structural_metadata"};
  if (q || im.opt.compression == Compression::meshopt) {  // meshopt: int8 normals
    model.extensionsUsed.push_back("KHR_mesh_quantization");
    model.extensionsRequired.push_back("KHR_mesh_quantization");
  }
  std::sort(model.extensionsUsed.begin(), model.extensionsUsed.end());

  for (const auto& m : kMaterials) {
    tinygltf::Material mat;
    mat.name = m.name;
    mat.pbrMetallicRoughness.baseColorFactor = {m.r, m.g, m.b, 1.0};
    mat.pbrMetallicRoughness.metallicFactor = 0.0;
    mat.pbrMetallicRoughness.roughnessFactor = m.roughness;
    model.materials.push_back(mat);
  }
  // Coloured triangles: white materials (COLOR_0 carries the colour), only
  // when some triangle is coloured (the glb of an input without colours is
  // unchanged).
  if (std::any_of(nodes.begin(), nodes.end(), [](const Impl::Node& n) { return n.coloured(); }))
    for (const auto& m : kMaterials) {
      tinygltf::Material mat;
      mat.name = std::string(m.name) + "_rgb";
      mat.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
      mat.pbrMetallicRoughness.metallicFactor = 0.0;
      mat.pbrMetallicRoughness.roughnessFactor = m.roughness;
      model.materials.push_back(mat);
    }

  model.buffers.emplace_back();
  std::vector<unsigned char> bin;
  BinWriter w{model, bin};
  const bool mo = im.opt.compression == Compression::meshopt;
  std::vector<BinWriter::Meshopt> compressed;
  if (mo) {
    static std::once_flag versions;  // the formats EXT_meshopt_compression defines
    std::call_once(versions, [] {
      meshopt_encodeVertexVersion(0);
      meshopt_encodeIndexVersion(1);
    });
    w.meshopt = &compressed;
  }
  tinygltf::Scene scene;
  scene.name = "citylod";

  const Vec3d oy = to_yup(im.origin);
  // One glTF node with one mesh: `part`'s vertices quantized (node scale =
  // `extent`) or float.
  // meshopt: the normals and the triangles of every mesh in one compressed
  // bufferView each, written after the last mesh (the accessors are slices):
  // two compressed bufferViews in all instead of two per mesh.
  struct Shared {
    bool on = false;
    std::vector<std::int8_t> normals;
    std::vector<std::pair<int, std::size_t>> normal_accessors;  // accessor, first vertex
    std::vector<std::uint32_t> indices;                         // each mesh's own vertices
    std::size_t vertices = 0;                                   // of the largest mesh
    std::vector<std::pair<int, std::size_t>> index_accessors;   // accessor, first index
  } shared;
  int part_bits = 0;  // meshopt, float part being written: its EXPONENTIAL bits
  auto emit = [&](const Impl::Node& node, bool quantized, double extent, tinygltf::Node gn) -> int {
    const std::size_t nv = node.rel.size();
    // Vertex attributes.
    int pos_acc, nrm_acc, fid_acc = -1;
    // meshopt: int8 octahedral normals (meshopt's OCTAHEDRAL filter), 4 bytes each
    auto oct_normals = [&] {
      std::vector<float> n4(nv * 4, 0.0f);
      for (std::size_t i = 0; i < nv; ++i) {
        const Vec3f& n = node.normals[i];
        n4[i * 4 + 0] = n[0];
        n4[i * 4 + 1] = n[2];
        n4[i * 4 + 2] = -n[1];
      }
      std::vector<std::int8_t> oct(nv * 4, 0);
      meshopt_encodeFilterOct(oct.data(), nv, 4, 8, n4.data());
      if (shared.on) {
        const int a = w.accessor(-1, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3, nv, true);
        shared.normal_accessors.emplace_back(a, shared.normals.size() / 4);
        shared.normals.insert(shared.normals.end(), oct.begin(), oct.end());
        return a;
      }
      const int nvw = w.attributes(oct.data(), nv, 4, "OCTAHEDRAL", 4);
      return w.accessor(nvw, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3, nv, true);
    };
    if (quantized) {
      const double e = extent;
      gn.scale = {e, e, e};
      std::vector<std::int16_t> pos(nv * 4, 0), nrm(nv * 4, 0);
      std::vector<double> mn(3, 32767), mx(3, -32767);
      for (std::size_t i = 0; i < nv; ++i) {
        const Vec3d y = to_yup(node.rel[i]);
        const Vec3d n = to_yup(Vec3d{node.normals[i][0], node.normals[i][1], node.normals[i][2]});
        for (int k = 0; k < 3; ++k) {
          const std::int16_t v = Impl::quant(y[size_t(k)], e);
          pos[i * 4 + size_t(k)] = v;
          mn[size_t(k)] = std::min(mn[size_t(k)], double(v));
          mx[size_t(k)] = std::max(mx[size_t(k)], double(v));
          nrm[i * 4 + size_t(k)] =
              std::int16_t(std::lround(std::clamp(n[size_t(k)], -1.0, 1.0) * 32767.0));
        }
      }
      int pv;
      if (mo) {  // one view: int16 position (and its padding), float feature id
        std::vector<unsigned char> v(nv * 12);
        for (std::size_t i = 0; i < nv; ++i) {
          std::memcpy(&v[i * 12], &pos[i * 4], 8);
          std::memcpy(&v[i * 12 + 8], &node.feature[i], 4);
        }
        pv = w.attributes(v.data(), nv, 12, "NONE", 12);
        fid_acc = w.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
        model.accessors[size_t(fid_acc)].byteOffset = 8;
      } else {
        pv = w.attributes(pos.data(), nv, 8, "NONE", 8);
      }
      pos_acc = w.accessor(pv, TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_TYPE_VEC3, nv, true, mn, mx);
      if (mo) {
        nrm_acc = oct_normals();
      } else {
        const int nvw = w.attributes(nrm.data(), nv, 8, "NONE", 8);
        nrm_acc = w.accessor(nvw, TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_TYPE_VEC3, nv, true);
      }
    } else {
      std::vector<float> pos(nv * 3), nrm(nv * 3);
      std::vector<double> mn(3, std::numeric_limits<double>::infinity()),
          mx(3, -std::numeric_limits<double>::infinity());
      for (std::size_t i = 0; i < nv; ++i) {
        const Vec3d y = to_yup(node.rel[i]);
        const Vec3f& n = node.normals[i];
        const float ny[3] = {n[0], n[2], -n[1]};
        for (int k = 0; k < 3; ++k) {
          const float v = float(y[size_t(k)]);
          pos[i * 3 + size_t(k)] = v;
          mn[size_t(k)] = std::min(mn[size_t(k)], double(v));
          mx[size_t(k)] = std::max(mx[size_t(k)], double(v));
          nrm[i * 3 + size_t(k)] = ny[k];
        }
      }
      std::vector<std::int32_t> exp;
      std::vector<float> dec;
      const int bits = mo ? part_bits : 0;
      if (bits > 0) Impl::exp_encode(node, bits, exp, dec);
      int pv;
      if (bits > 0) {  // the decoded positions are the stored ones
        for (int k = 0; k < 3; ++k) {
          mn[size_t(k)] = std::numeric_limits<double>::infinity();
          mx[size_t(k)] = -mn[size_t(k)];
        }
        for (std::size_t i = 0; i < nv * 3; ++i) {
          mn[i % 3] = std::min(mn[i % 3], double(dec[i]));
          mx[i % 3] = std::max(mx[i % 3], double(dec[i]));
        }
      }
      // meshopt: one view of position and feature id (the id an EXPONENTIAL
      // word with exponent 0 and the id as mantissa: decoded exactly)
      const bool fid_in_view =
          mo && std::all_of(node.feature.begin(), node.feature.end(),
                            [](float f) { return f >= 0 && f < float(1 << 23); });
      if (fid_in_view) {
        std::vector<std::uint32_t> v(nv * 4);
        for (std::size_t i = 0; i < nv; ++i) {
          if (bits > 0) {
            std::memcpy(&v[i * 4], &exp[i * 3], 12);
            v[i * 4 + 3] = std::uint32_t(node.feature[i]);
          } else {
            std::memcpy(&v[i * 4], &pos[i * 3], 12);
            std::memcpy(&v[i * 4 + 3], &node.feature[i], 4);
          }
        }
        pv = w.attributes(v.data(), nv, 16, bits > 0 ? "EXPONENTIAL" : "NONE", 16);
        fid_acc = w.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
        model.accessors[size_t(fid_acc)].byteOffset = 12;
      } else if (bits > 0) {
        pv = w.attributes(exp.data(), nv, 12, "EXPONENTIAL", 0);
      } else {
        pv = w.attributes(pos.data(), nv, 12, "NONE", 0);
      }
      pos_acc =
          w.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv, false, mn, mx);
      if (mo) {
        nrm_acc = oct_normals();
      } else {
        const int nvw = w.attributes(nrm.data(), nv, 12, "NONE", 0);
        nrm_acc = w.accessor(nvw, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
      }
    }
    if (fid_acc < 0) {
      const int fv = w.attributes(node.feature.data(), nv, 4, "NONE", 0);
      fid_acc = w.accessor(fv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
    }
    // COLOR_0: normalized u8 RGBA in linear space (glTF), from the sRGB input
    int col_acc = -1;
    if (node.coloured()) {
      std::vector<std::uint8_t> rgba(nv * 4, 0);
      for (std::size_t i = 0; i < nv; ++i) {
        for (int k = 0; k < 3; ++k)
          rgba[i * 4 + size_t(k)] = srgb_to_linear_u8(node.colours[i][size_t(k)]);
        rgba[i * 4 + 3] = 255;
      }
      const int cv = w.attributes(rgba.data(), nv, 4, "NONE", 4);
      col_acc = w.accessor(cv, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, nv, true);
    }

    tinygltf::Mesh mesh;  // unnamed: its node carries the name
    // One index bufferView per mesh (meshopt: per glb, see Shared): each
    // primitive's accessor is a slice.
    const bool u16 = nv <= 65535;
    const int ct =
        u16 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    std::vector<std::uint32_t> all_ix;
    for (const auto& ix : node.indices) all_ix.insert(all_ix.end(), ix.begin(), ix.end());
    const std::size_t base = shared.indices.size();
    int iv = -1;
    if (shared.on) {
      shared.indices.insert(shared.indices.end(), all_ix.begin(), all_ix.end());
      shared.vertices = std::max(shared.vertices, nv);
    } else {
      iv = w.triangles(all_ix, nv, u16);
    }
    // featureCount: the distinct ids of the attribute (the whole accessor,
    // which the primitives share), not only those a primitive's triangles use
    // (a building without coloured faces has none in the coloured primitive)
    const std::set<float> distinct(node.feature.begin(), node.feature.end());
    std::size_t first = 0;
    for (int c = 0; c < kClasses; ++c) {
      const auto& ix = node.indices[size_t(c)];
      if (ix.empty()) continue;
      tinygltf::Primitive prim;
      prim.mode = TINYGLTF_MODE_TRIANGLES;
      prim.material = c;
      prim.indices = w.accessor(iv, ct, TINYGLTF_TYPE_SCALAR, ix.size());
      if (shared.on)
        shared.index_accessors.emplace_back(prim.indices, base + first);
      else
        model.accessors[size_t(prim.indices)].byteOffset = first * (u16 ? 2 : 4);
      first += ix.size();
      prim.attributes["POSITION"] = pos_acc;
      prim.attributes["NORMAL"] = nrm_acc;
      prim.attributes["_FEATURE_ID_0"] = fid_acc;
      if (c >= 3) prim.attributes["COLOR_0"] = col_acc;
      Value::Object fid{{"featureCount", Value(int(distinct.size()))},
                        {"attribute", Value(0)},
                        {"propertyTable", Value(0)}};
      prim.extensions["EXT_mesh_features"] =
          obj({{"featureIds", Value(Value::Array{obj(std::move(fid))})}});
      mesh.primitives.push_back(prim);
    }
    model.meshes.push_back(mesh);
    gn.mesh = int(model.meshes.size() - 1);
    model.nodes.push_back(gn);
    return int(model.nodes.size() - 1);
  };
  // meshopt: a mesh in the order whose encoded bytes are fewer, first-use or
  // corners together (positions against normals and triangles).
  auto emit_best = [&](const Impl::Node& part, bool quantized, double extent,
                       const tinygltf::Node& gn) -> int {
    if (!mo) return emit(part, quantized, extent, gn);
    const std::size_t accessors = model.accessors.size(), views = model.bufferViews.size(),
                      meshes = model.meshes.size(), nodes = model.nodes.size(), bytes = bin.size(),
                      encoded = compressed.size();
    auto rollback = [&] {
      model.accessors.resize(accessors);
      model.bufferViews.resize(views);
      model.meshes.resize(meshes);
      model.nodes.resize(nodes);
      bin.resize(bytes);
      compressed.resize(encoded);
    };
    int chosen = 0;  // bit 0: corners together, bit 1: strip order
    std::size_t fewest = 0;
    for (int order = 0; order < 4; ++order) {
      emit(Impl::codec_order(part, (order & 1) != 0, (order & 2) != 0), quantized, extent, gn);
      if (order == 0 || bin.size() - bytes < fewest) {
        fewest = bin.size() - bytes;
        chosen = order;
      }
      rollback();
    }
    shared.on = true;  // the chosen order, normals and triangles into the shared views
    const int best =
        emit(Impl::codec_order(part, (chosen & 1) != 0, (chosen & 2) != 0), quantized, extent, gn);
    shared.on = false;
    return best;
  };
  for (std::size_t ni = 0; ni < nodes.size(); ++ni) {
    const auto& node = nodes[ni];
    tinygltf::Node gn;
    gn.name = node.name;
    gn.translation = {oy[0], oy[1], oy[2]};
    bool any = false;
    for (const auto& ix : node.indices) any = any || !ix.empty();
    if (node.rel.empty() || !any) {
      model.nodes.push_back(gn);
      scene.nodes.push_back(int(model.nodes.size() - 1));
      continue;
    }
    const double extent = Impl::quant_extent(node);
    const std::set<float> bad = mo && !node_q[ni] ? node.float_features : std::set<float>{};
    std::set<float> all(node.feature.begin(), node.feature.end());
    if (bad.empty() || bad.size() == all.size()) {
      part_bits = mo && !node_q[ni] ? im.float_bits(ni, node, extent) : 0;
      scene.nodes.push_back(emit_best(node, node_q[ni] != 0, extent, gn));
      continue;
    }
    // meshopt: the features int16 would damage stay float in a second mesh;
    // the named node holds both (hiding it hides the model).
    tinygltf::Node parent;
    parent.name = node.name;
    tinygltf::Node qn = gn, fn = gn;
    qn.name = node.name + ":int16";
    fn.name = node.name + ":float";
    part_bits = 0;
    parent.children.push_back(emit_best(Impl::part(node, bad, false), true, extent, qn));
    const Impl::Node fpart = Impl::part(node, bad, true);
    part_bits = im.float_bits(ni, fpart, extent);
    parent.children.push_back(emit_best(fpart, false, extent, fn));
    model.nodes.push_back(parent);
    scene.nodes.push_back(int(model.nodes.size() - 1));
  }
  if (!shared.normal_accessors.empty()) {
    const int nvw =
        w.attributes(shared.normals.data(), shared.normals.size() / 4, 4, "OCTAHEDRAL", 4);
    for (const auto& [a, v] : shared.normal_accessors) {
      model.accessors[size_t(a)].bufferView = nvw;
      model.accessors[size_t(a)].byteOffset = v * 4;
    }
  }
  if (!shared.index_accessors.empty()) {
    const bool u16 = shared.vertices <= 65535;
    const int iv = w.triangles(shared.indices, shared.vertices, u16);
    for (const auto& [a, i] : shared.index_accessors) {
      model.accessors[size_t(a)].bufferView = iv;
      model.accessors[size_t(a)].byteOffset = i * (u16 ? 2 : 4);
      model.accessors[size_t(a)].componentType =
          u16 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    }
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  // ---- EXT_structural_metadata: schema + one property table.
  const std::size_t n = im.features.size();
  std::string ids;
  std::vector<std::uint32_t> offsets{0};
  std::vector<std::uint8_t> kind;
  std::vector<std::int32_t> level, step, index, count;
  std::vector<float> height, area, error, rmse;
  std::vector<std::uint8_t> valid((n + 7) / 8, 0);  // BOOLEAN: a bitstream, LSB first
  for (std::size_t i = 0; i < n; ++i) {
    const GlbFeature& f = im.features[i];
    if (f.valid) valid[i / 8] |= std::uint8_t(1u << (i % 8));
    rmse.push_back(f.rmse_m >= 0 ? float(f.rmse_m) : -1.0f);
    ids += f.building_id;
    offsets.push_back(std::uint32_t(ids.size()));
    kind.push_back(std::uint8_t(f.kind));
    level.push_back(f.level);
    step.push_back(f.step);
    index.push_back(f.model_index);
    count.push_back(f.model_count);
    height.push_back(float(f.height_m));
    area.push_back(float(f.footprint_area_m2));
    error.push_back(float(f.error_m));
  }
  Value::Object props;
  auto column = [&](const char* name, const void* p, std::size_t bytes) {
    props[name] = obj({{"values", Value(w.view(p, bytes, 0))}});
  };
  // STRING: offsets as UINT16 when the characters allow it (UINT32 otherwise)
  auto string_column = [&](const char* name, std::string chars,
                           const std::vector<std::uint32_t>& offs) {
    Value::Object o;
    const bool small = offs.back() <= 0xFFFF;
    if (chars.empty()) chars.push_back('\0');  // a bufferView needs byteLength >= 1
    o["values"] = Value(w.view(chars.data(), chars.size(), 0));
    if (small) {
      const std::vector<std::uint16_t> o16(offs.begin(), offs.end());
      o["stringOffsets"] = Value(w.view(o16.data(), o16.size() * 2, 0));
      o["stringOffsetType"] = str("UINT16");
    } else {
      o["stringOffsets"] = Value(w.view(offs.data(), offs.size() * 4, 0));  // default UINT32
    }
    props[name] = obj(std::move(o));
  };
  string_column("building_id", ids, offsets);
  column("lod_kind", kind.data(), n);
  column("level", level.data(), n * 4);
  column("step", step.data(), n * 4);
  column("model_index", index.data(), n * 4);
  column("model_count", count.data(), n * 4);
  column("height", height.data(), n * 4);
  column("footprint_area", area.data(), n * 4);
  column("geometric_error", error.data(), n * 4);
  // The source attributes (GlbOptions::attributes), typed.
  for (const GlbAttribute& a : im.opt.attributes) {
    auto value_of = [&](const GlbFeature& f) -> const nlohmann::json* {
      if (!f.attributes.is_object()) return nullptr;
      const auto it = f.attributes.find(a.name);
      return it == f.attributes.end() || it->is_null() ? nullptr : &*it;
    };
    switch (a.type) {
      case GlbAttribute::Type::int64: {
        std::vector<std::int64_t> v;
        for (const auto& f : im.features) {
          const nlohmann::json* j = value_of(f);
          v.push_back(j && j->is_number_integer() ? j->get<std::int64_t>() : 0);
        }
        column(a.property.c_str(), v.data(), n * 8);
        break;
      }
      case GlbAttribute::Type::float64: {
        const double none = std::numeric_limits<double>::lowest();
        std::vector<double> v;
        for (const auto& f : im.features) {
          const nlohmann::json* j = value_of(f);
          v.push_back(j && j->is_number() ? j->get<double>() : none);
        }
        column(a.property.c_str(), v.data(), n * 8);
        break;
      }
      case GlbAttribute::Type::boolean: {
        std::vector<std::uint8_t> bits((n + 7) / 8, 0);
        for (std::size_t i = 0; i < n; ++i) {
          const nlohmann::json* j = value_of(im.features[i]);
          if (j && j->is_boolean() && j->get<bool>()) bits[i / 8] |= std::uint8_t(1u << (i % 8));
        }
        column(a.property.c_str(), bits.data(), bits.size());
        break;
      }
      case GlbAttribute::Type::string: {
        if (!a.enum_values.empty()) {  // ENUM (UINT8): the index of the value
          std::vector<std::uint8_t> v;
          for (const auto& f : im.features) {
            const std::string text = attribute_text(value_of(f));
            const auto it = std::lower_bound(a.enum_values.begin(), a.enum_values.end(), text);
            if (it == a.enum_values.end() || *it != text)
              throw IoError(kWhere, "attribute '" + a.name + "': value '" + text +
                                        "' is not one of the schema's");
            v.push_back(std::uint8_t(it - a.enum_values.begin()));
          }
          column(a.property.c_str(), v.data(), n);
          break;
        }
        std::string chars;
        std::vector<std::uint32_t> offs{0};
        for (const auto& f : im.features) {
          chars += attribute_text(value_of(f));
          offs.push_back(std::uint32_t(chars.size()));
        }
        string_column(a.property.c_str(), chars, offs);
        break;
      }
    }
  }
  column("rmse", rmse.data(), n * 4);
  if (valid.empty()) valid.push_back(0);
  column("valid", valid.data(), valid.size());

  Value::Object table{
      {"class", str("building")}, {"count", Value(int(n))}, {"properties", obj(props)}};
  model.extensions["EXT_structural_metadata"] =
      obj({{"propertyTables", Value(Value::Array{obj(table)})}});  // + schema: finish_glb

  while (bin.size() % 4) bin.push_back(0);
  model.buffers[0].data = std::move(bin);

  tinygltf::TinyGLTF writer;
  std::ostringstream os;
  if (!writer.WriteGltfSceneToStream(&model, os, false, true))
    throw IoError(kWhere, "tinygltf could not serialize");
  return finish_glb(os.str(), compressed, schema_json(im.opt.attributes), im.opt.schema_uri);
}

}  // namespace citylod::io
