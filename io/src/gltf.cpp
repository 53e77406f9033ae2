// glb writer, assembly: GlbBuilder collects each node's flat-shaded features;
// glb() writes them as glTF in steps -- materials, a mesh per node (two when
// some of its features keep float positions), each mesh's vertex streams and
// primitives, the views meshopt shares between meshes, the property table --
// and finishes what tinygltf serialized (schema, EXT_meshopt_compression).
// Shading, quantization, meshopt and metadata: gltf_internal.hpp.
#include "citylod/io/gltf.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include "citylod/io/error.hpp"
#include "gltf_internal.hpp"

namespace citylod::io {

using detail::BinWriter;
using detail::GlbNode;
using detail::kClasses;
using detail::kWhere;
using detail::obj;
using detail::str;
using detail::to_yup;
using detail::Value;

namespace detail {

int BinWriter::view(const void* p, std::size_t n, int target, int stride) {
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

int BinWriter::accessor(int view, int component, int type, std::size_t count, bool normalized,
                        std::vector<double> min, std::vector<double> max) {
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

}  // namespace detail

namespace {

struct Material {
  const char* name;
  double r, g, b, roughness;
};
// Linear-space base colours: light plaster walls, terracotta roofs, grey base.
constexpr Material kMaterials[3] = {{"wall", 0.80, 0.76, 0.68, 0.9},
                                    {"roof", 0.45, 0.13, 0.08, 0.8},
                                    {"base", 0.25, 0.25, 0.25, 1.0}};

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
  detail::put_schema(j, schema, schema_uri);
  // "mode" 4 (TRIANGLES) is the default: not written
  if (j.contains("meshes"))
    for (auto& mesh : j["meshes"])
      for (auto& prim : mesh["primitives"])
        if (prim.value("mode", 4) == 4) prim.erase("mode");
  detail::move_to_fallback_buffer(j, views, bin_len);
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

/// The accessors of a mesh's vertex attributes (-1: none yet).
struct Attributes {
  int position = -1, normal = -1, feature = -1, colour = -1;
};

/// One glb being written: the tinygltf model, its BIN data and, for meshopt,
/// the encoded views. Each step of the writer is a function (gltfpack's
/// write.cpp): add_mesh_node() per glTF node, finish() once.
class Assembly {
 public:
  /// The asset, extensions and materials of `nodes`; `quantized`: some node
  /// has int16 positions.
  Assembly(const GlbOptions& opt, const std::vector<GlbNode>& nodes, bool quantized);
  Assembly(const Assembly&) = delete;
  Assembly& operator=(const Assembly&) = delete;

  /// Adds a glTF node to the model and its scene; returns its index.
  int add_node(const tinygltf::Node& gn) {
    model_.nodes.push_back(gn);
    return int(model_.nodes.size() - 1);
  }
  void add_to_scene(int node) { scene_.nodes.push_back(node); }
  /// One glTF node with one mesh: `part`'s vertices quantized (node scale =
  /// `extent`) or float (meshopt: through the EXPONENTIAL filter with
  /// `float_bits` > 0). meshopt: in the order whose encoded bytes are fewer,
  /// first-use or corners together (positions against normals and triangles),
  /// its normals and triangles in the views the meshes share.
  int add_mesh_node(const GlbNode& part, bool quantized, double extent, int float_bits,
                    const tinygltf::Node& gn);
  /// The shared views, the scene, the property table of `features`: the glb.
  std::string finish(const std::vector<GlbFeature>& features);

 private:
  int emit(const GlbNode& node, bool quantized, double extent, tinygltf::Node gn);
  Attributes quantized_attributes(const GlbNode& node, double extent, tinygltf::Node& gn);
  Attributes float_attributes(const GlbNode& node);
  int octahedral_normals(const GlbNode& node);
  int colours(const GlbNode& node);
  tinygltf::Mesh mesh(const GlbNode& node, const Attributes& a);
  void write_shared_views();

  const GlbOptions& opt_;
  const bool mo_;  // meshopt
  tinygltf::Model model_;
  std::vector<unsigned char> bin_;
  BinWriter w_{model_, bin_};
  std::vector<BinWriter::Meshopt> compressed_;
  tinygltf::Scene scene_;
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
  } shared_;
  int part_bits_ = 0;  // meshopt, float part being written: its EXPONENTIAL bits
};

Assembly::Assembly(const GlbOptions& opt, const std::vector<GlbNode>& nodes, bool quantized)
    : opt_(opt), mo_(opt.compression == Compression::meshopt) {
  model_.asset.version = "2.0";
  model_.asset.generator = opt.generator;
  model_.extensionsUsed = {"EXT_mesh_features", "EXT_structural_metadata"};
  if (quantized || mo_) {  // meshopt: int8 normals
    model_.extensionsUsed.push_back("KHR_mesh_quantization");
    model_.extensionsRequired.push_back("KHR_mesh_quantization");
  }
  std::sort(model_.extensionsUsed.begin(), model_.extensionsUsed.end());

  for (const auto& m : kMaterials) {
    tinygltf::Material mat;
    mat.name = m.name;
    mat.pbrMetallicRoughness.baseColorFactor = {m.r, m.g, m.b, 1.0};
    mat.pbrMetallicRoughness.metallicFactor = 0.0;
    mat.pbrMetallicRoughness.roughnessFactor = m.roughness;
    model_.materials.push_back(mat);
  }
  // Coloured triangles: white materials (COLOR_0 carries the colour), only
  // when some triangle is coloured (the glb of an input without colours is
  // unchanged).
  if (std::any_of(nodes.begin(), nodes.end(), [](const GlbNode& n) { return n.coloured(); }))
    for (const auto& m : kMaterials) {
      tinygltf::Material mat;
      mat.name = std::string(m.name) + "_rgb";
      mat.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
      mat.pbrMetallicRoughness.metallicFactor = 0.0;
      mat.pbrMetallicRoughness.roughnessFactor = m.roughness;
      model_.materials.push_back(mat);
    }

  model_.buffers.emplace_back();
  if (mo_) {
    detail::use_meshopt_versions();
    w_.meshopt = &compressed_;
  }
  scene_.name = "citylod";
}

/// meshopt: int8 octahedral normals (meshopt's OCTAHEDRAL filter), 4 bytes each
int Assembly::octahedral_normals(const GlbNode& node) {
  const std::size_t nv = node.rel.size();
  const std::vector<std::int8_t> oct = detail::octahedral_normals(node);
  if (shared_.on) {
    const int a = w_.accessor(-1, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3, nv, true);
    shared_.normal_accessors.emplace_back(a, shared_.normals.size() / 4);
    shared_.normals.insert(shared_.normals.end(), oct.begin(), oct.end());
    return a;
  }
  const int nvw = w_.attributes(oct.data(), nv, 4, "OCTAHEDRAL", 4);
  return w_.accessor(nvw, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3, nv, true);
}

/// int16 positions (KHR_mesh_quantization; the node's scale restores them),
/// int16 normals (meshopt: octahedral int8) and, for meshopt, the feature id
/// in the positions' view.
Attributes Assembly::quantized_attributes(const GlbNode& node, double extent, tinygltf::Node& gn) {
  const std::size_t nv = node.rel.size();
  Attributes a;
  const double e = extent;
  gn.scale = {e, e, e};
  std::vector<std::int16_t> pos(nv * 4, 0), nrm(nv * 4, 0);
  std::vector<double> mn(3, 32767), mx(3, -32767);
  for (std::size_t i = 0; i < nv; ++i) {
    const Vec3d y = to_yup(node.rel[i]);
    const Vec3d n = to_yup(Vec3d{node.normals[i][0], node.normals[i][1], node.normals[i][2]});
    for (int k = 0; k < 3; ++k) {
      const std::int16_t v = detail::quant(y[size_t(k)], e);
      pos[i * 4 + size_t(k)] = v;
      mn[size_t(k)] = std::min(mn[size_t(k)], double(v));
      mx[size_t(k)] = std::max(mx[size_t(k)], double(v));
      nrm[i * 4 + size_t(k)] =
          std::int16_t(std::lround(std::clamp(n[size_t(k)], -1.0, 1.0) * 32767.0));
    }
  }
  int pv;
  if (mo_) {  // one view: int16 position (and its padding), float feature id
    std::vector<unsigned char> v(nv * 12);
    for (std::size_t i = 0; i < nv; ++i) {
      std::memcpy(&v[i * 12], &pos[i * 4], 8);
      std::memcpy(&v[i * 12 + 8], &node.feature[i], 4);
    }
    pv = w_.attributes(v.data(), nv, 12, "NONE", 12);
    a.feature = w_.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
    model_.accessors[size_t(a.feature)].byteOffset = 8;
  } else {
    pv = w_.attributes(pos.data(), nv, 8, "NONE", 8);
  }
  a.position = w_.accessor(pv, TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_TYPE_VEC3, nv, true, mn, mx);
  if (mo_) {
    a.normal = octahedral_normals(node);
  } else {
    const int nvw = w_.attributes(nrm.data(), nv, 8, "NONE", 8);
    a.normal = w_.accessor(nvw, TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_TYPE_VEC3, nv, true);
  }
  return a;
}

/// float positions (meshopt: through the EXPONENTIAL filter at part_bits_
/// when > 0, the feature id in their view), float normals (meshopt:
/// octahedral int8).
Attributes Assembly::float_attributes(const GlbNode& node) {
  const std::size_t nv = node.rel.size();
  Attributes a;
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
  const int bits = mo_ ? part_bits_ : 0;
  if (bits > 0) detail::exp_encode(node, bits, exp, dec);
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
  const bool fid_in_view = mo_ && std::all_of(node.feature.begin(), node.feature.end(),
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
    pv = w_.attributes(v.data(), nv, 16, bits > 0 ? "EXPONENTIAL" : "NONE", 16);
    a.feature = w_.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
    model_.accessors[size_t(a.feature)].byteOffset = 12;
  } else if (bits > 0) {
    pv = w_.attributes(exp.data(), nv, 12, "EXPONENTIAL", 0);
  } else {
    pv = w_.attributes(pos.data(), nv, 12, "NONE", 0);
  }
  a.position =
      w_.accessor(pv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv, false, mn, mx);
  if (mo_) {
    a.normal = octahedral_normals(node);
  } else {
    const int nvw = w_.attributes(nrm.data(), nv, 12, "NONE", 0);
    a.normal = w_.accessor(nvw, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
  }
  return a;
}

/// COLOR_0: normalized u8 RGBA in linear space (glTF), from the sRGB input
int Assembly::colours(const GlbNode& node) {
  const std::size_t nv = node.rel.size();
  std::vector<std::uint8_t> rgba(nv * 4, 0);
  for (std::size_t i = 0; i < nv; ++i) {
    for (int k = 0; k < 3; ++k)
      rgba[i * 4 + size_t(k)] = detail::srgb_to_linear_u8(node.colours[i][size_t(k)]);
    rgba[i * 4 + 3] = 255;
  }
  const int cv = w_.attributes(rgba.data(), nv, 4, "NONE", 4);
  return w_.accessor(cv, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, nv, true);
}

/// The mesh of `node`: one primitive per class with triangles, its features
/// (EXT_mesh_features) over the attributes `a`.
tinygltf::Mesh Assembly::mesh(const GlbNode& node, const Attributes& a) {
  const std::size_t nv = node.rel.size();
  tinygltf::Mesh mesh;  // unnamed: its node carries the name
  // One index bufferView per mesh (meshopt: per glb, see Shared): each
  // primitive's accessor is a slice.
  const bool u16 = nv <= 65535;
  const int ct =
      u16 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  std::vector<std::uint32_t> all_ix;
  for (const auto& ix : node.indices) all_ix.insert(all_ix.end(), ix.begin(), ix.end());
  const std::size_t base = shared_.indices.size();
  int iv = -1;
  if (shared_.on) {
    shared_.indices.insert(shared_.indices.end(), all_ix.begin(), all_ix.end());
    shared_.vertices = std::max(shared_.vertices, nv);
  } else {
    iv = w_.triangles(all_ix, nv, u16);
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
    prim.indices = w_.accessor(iv, ct, TINYGLTF_TYPE_SCALAR, ix.size());
    if (shared_.on)
      shared_.index_accessors.emplace_back(prim.indices, base + first);
    else
      model_.accessors[size_t(prim.indices)].byteOffset = first * (u16 ? 2 : 4);
    first += ix.size();
    prim.attributes["POSITION"] = a.position;
    prim.attributes["NORMAL"] = a.normal;
    prim.attributes["_FEATURE_ID_0"] = a.feature;
    if (c >= 3) prim.attributes["COLOR_0"] = a.colour;
    Value::Object fid{{"featureCount", Value(int(distinct.size()))},
                      {"attribute", Value(0)},
                      {"propertyTable", Value(0)}};
    prim.extensions["EXT_mesh_features"] =
        obj({{"featureIds", Value(Value::Array{obj(std::move(fid))})}});
    mesh.primitives.push_back(prim);
  }
  return mesh;
}

/// One glTF node with one mesh (see add_mesh_node), in the order given.
int Assembly::emit(const GlbNode& node, bool quantized, double extent, tinygltf::Node gn) {
  const std::size_t nv = node.rel.size();
  Attributes a = quantized ? quantized_attributes(node, extent, gn) : float_attributes(node);
  if (a.feature < 0) {
    const int fv = w_.attributes(node.feature.data(), nv, 4, "NONE", 0);
    a.feature = w_.accessor(fv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, nv);
  }
  if (node.coloured()) a.colour = colours(node);
  model_.meshes.push_back(mesh(node, a));
  gn.mesh = int(model_.meshes.size() - 1);
  return add_node(gn);
}

int Assembly::add_mesh_node(const GlbNode& part, bool quantized, double extent, int float_bits,
                            const tinygltf::Node& gn) {
  part_bits_ = float_bits;
  if (!mo_) return emit(part, quantized, extent, gn);
  const std::size_t accessors = model_.accessors.size(), views = model_.bufferViews.size(),
                    meshes = model_.meshes.size(), nodes = model_.nodes.size(), bytes = bin_.size(),
                    encoded = compressed_.size();
  auto rollback = [&] {
    model_.accessors.resize(accessors);
    model_.bufferViews.resize(views);
    model_.meshes.resize(meshes);
    model_.nodes.resize(nodes);
    bin_.resize(bytes);
    compressed_.resize(encoded);
  };
  int chosen = 0;  // bit 0: corners together, bit 1: strip order
  std::size_t fewest = 0;
  for (int order = 0; order < 4; ++order) {
    emit(detail::codec_order(part, (order & 1) != 0, (order & 2) != 0), quantized, extent, gn);
    if (order == 0 || bin_.size() - bytes < fewest) {
      fewest = bin_.size() - bytes;
      chosen = order;
    }
    rollback();
  }
  shared_.on = true;  // the chosen order, normals and triangles into the shared views
  const int best =
      emit(detail::codec_order(part, (chosen & 1) != 0, (chosen & 2) != 0), quantized, extent, gn);
  shared_.on = false;
  return best;
}

void Assembly::write_shared_views() {
  if (!shared_.normal_accessors.empty()) {
    const int nvw =
        w_.attributes(shared_.normals.data(), shared_.normals.size() / 4, 4, "OCTAHEDRAL", 4);
    for (const auto& [a, v] : shared_.normal_accessors) {
      model_.accessors[size_t(a)].bufferView = nvw;
      model_.accessors[size_t(a)].byteOffset = v * 4;
    }
  }
  if (!shared_.index_accessors.empty()) {
    const bool u16 = shared_.vertices <= 65535;
    const int iv = w_.triangles(shared_.indices, shared_.vertices, u16);
    for (const auto& [a, i] : shared_.index_accessors) {
      model_.accessors[size_t(a)].bufferView = iv;
      model_.accessors[size_t(a)].byteOffset = i * (u16 ? 2 : 4);
      model_.accessors[size_t(a)].componentType =
          u16 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    }
  }
}

std::string Assembly::finish(const std::vector<GlbFeature>& features) {
  write_shared_views();
  model_.scenes.push_back(scene_);
  model_.defaultScene = 0;

  // EXT_structural_metadata: one property table (+ schema: finish_glb)
  const Value::Object table = detail::property_table(w_, features, opt_.attributes);
  model_.extensions["EXT_structural_metadata"] =
      obj({{"propertyTables", Value(Value::Array{obj(table)})}});

  while (bin_.size() % 4) bin_.push_back(0);
  model_.buffers[0].data = std::move(bin_);

  tinygltf::TinyGLTF writer;
  std::ostringstream os;
  if (!writer.WriteGltfSceneToStream(&model_, os, false, true))
    throw IoError(kWhere, "tinygltf could not serialize");
  // the schema itself only when no schemaUri points at it
  return finish_glb(
      os.str(), compressed_,
      opt_.schema_uri.empty() ? detail::schema_json(opt_.attributes) : nlohmann::json(),
      opt_.schema_uri);
}

}  // namespace

const char* to_string(Compression c) {
  return c == Compression::meshopt ? "meshopt" : "none";
}

Compression compression_from_string(const std::string& s) {
  if (s == "none") return Compression::none;
  if (s == "meshopt") return Compression::meshopt;
  throw std::invalid_argument("compression must be none or meshopt, got '" + s + "'");
}

// ------------------------------------------------------------------ builder
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
  const detail::FlatMesh f = detail::flat_shade(mesh, colours);
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

std::string GlbBuilder::glb() const {
  const Impl& im = *impl_;
  if (im.features.empty()) throw IoError(kWhere, "no features to write");
  std::vector<char> node_q;  // per node: int16 positions (see Impl::quantized)
  const std::vector<GlbNode>& nodes = im.stored_nodes();
  for (const auto& node : nodes) node_q.push_back(im.quantized(node) ? 1 : 0);
  const bool q = std::find(node_q.begin(), node_q.end(), 1) != node_q.end();
  const bool mo = im.opt.compression == Compression::meshopt;
  Assembly a(im.opt, nodes, q);

  const Vec3d oy = to_yup(im.origin);
  for (std::size_t ni = 0; ni < nodes.size(); ++ni) {
    const auto& node = nodes[ni];
    tinygltf::Node gn;
    gn.name = node.name;
    gn.translation = {oy[0], oy[1], oy[2]};
    bool any = false;
    for (const auto& ix : node.indices) any = any || !ix.empty();
    if (node.rel.empty() || !any) {
      a.add_to_scene(a.add_node(gn));
      continue;
    }
    const double extent = detail::quant_extent(node);
    const std::set<float> bad = mo && !node_q[ni] ? node.float_features : std::set<float>{};
    std::set<float> all(node.feature.begin(), node.feature.end());
    if (bad.empty() || bad.size() == all.size()) {
      const int bits = mo && !node_q[ni] ? im.float_bits(ni, node, extent) : 0;
      a.add_to_scene(a.add_mesh_node(node, node_q[ni] != 0, extent, bits, gn));
      continue;
    }
    // meshopt: the features int16 would damage stay float in a second mesh;
    // the named node holds both (hiding it hides the model).
    tinygltf::Node parent;
    parent.name = node.name;
    tinygltf::Node qn = gn, fn = gn;
    qn.name = node.name + ":int16";
    fn.name = node.name + ":float";
    parent.children.push_back(a.add_mesh_node(detail::part(node, bad, false), true, extent, 0, qn));
    const GlbNode fpart = detail::part(node, bad, true);
    const int bits = im.float_bits(ni, fpart, extent);
    parent.children.push_back(a.add_mesh_node(fpart, false, extent, bits, fn));
    a.add_to_scene(a.add_node(parent));
  }
  return a.finish(im.features);
}

}  // namespace citylod::io
