// glb reader (see glb_reader.hpp): container checks, tinygltf parse, then
// every accessor read with explicit bounds checks.
#include "citylod/io/glb_reader.hpp"

#include <meshoptimizer.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "citylod/io/error.hpp"
#include "citylod/io/file_check.hpp"

namespace citylod::io {

namespace {

using Mat4 = std::array<double, 16>;
constexpr Mat4 kIdentity{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

std::uint32_t u32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;  // glb is little-endian, as is every platform we build on
}

/// Checks the glb container (header and chunk table) before tinygltf sees it.
void check_container(const std::string& b, const std::string& name) {
  if (b.size() < 20)
    throw IoError(name,
                  "not a glb (" + std::to_string(b.size()) + " bytes, too short for a header)");
  if (std::memcmp(b.data(), "glTF", 4) != 0) throw IoError(name, "not a glb (no 'glTF' magic)");
  if (u32(b, 4) != 2)
    throw IoError(name, "glb version " + std::to_string(u32(b, 4)) + " (only 2 is supported)");
  const std::uint32_t total = u32(b, 8);
  if (total != b.size())
    throw IoError(name, "glb header says " + std::to_string(total) + " bytes, the file has " +
                            std::to_string(b.size()) + " (truncated or corrupt)");
  std::size_t at = 12;
  int chunk = 0;
  while (at < b.size()) {
    if (at + 8 > b.size())
      throw IoError(name, "glb chunk " + std::to_string(chunk) + " header is truncated");
    const std::uint32_t len = u32(b, at), type = u32(b, at + 4);
    if (std::uint64_t(at) + 8 + len > b.size())
      throw IoError(name, "glb chunk " + std::to_string(chunk) + " (" + std::to_string(len) +
                              " bytes) runs past the end of the file");
    if (chunk == 0 && type != 0x4E4F534Au) throw IoError(name, "first glb chunk is not JSON");
    at += 8 + std::size_t(len);
    ++chunk;
  }
  if (chunk == 0) throw IoError(name, "glb has no JSON chunk");
}

int component_size(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    case TINYGLTF_COMPONENT_TYPE_DOUBLE:
      return 8;
    default:
      return 0;
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

/// One component at `p`, as double; normalized integers mapped to [-1, 1] / [0, 1].
double component(const unsigned char* p, int ct, bool normalized) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      std::int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(double(v) / 127.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? double(*p) / 255.0 : double(*p);
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(double(v) / 32767.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? double(v) / 65535.0 : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_INT: {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p, 4);
      return double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
    default:
      return 0;
  }
}

class Reader {
 public:
  Reader(const tinygltf::Model& m, std::string name, std::size_t file_size)
      : m_(m), name_(std::move(name)), file_size_(file_size) {}

  /// Bytes of a bufferView, bounds-checked.
  std::pair<const unsigned char*, std::size_t> view(int index, const std::string& what) const {
    if (index < 0 || std::size_t(index) >= m_.bufferViews.size())
      throw IoError(name_, what + ": bufferView " + std::to_string(index) + " does not exist");
    const tinygltf::BufferView& v = m_.bufferViews[std::size_t(index)];
    if (v.buffer < 0 || std::size_t(v.buffer) >= m_.buffers.size())
      throw IoError(name_, what + ": buffer " + std::to_string(v.buffer) + " does not exist");
    const auto& data = m_.buffers[std::size_t(v.buffer)].data;
    if (std::uint64_t(v.byteOffset) + v.byteLength > data.size())
      throw IoError(name_,
                    what + ": bufferView " + std::to_string(index) + " lies outside its buffer");
    return {data.data() + v.byteOffset, v.byteLength};
  }

  /// Accessor values, `comps` per element (must match the accessor's type).
  std::vector<double> accessor(int index, int comps, const std::string& what) const {
    if (index < 0 || std::size_t(index) >= m_.accessors.size())
      throw IoError(name_, what + ": accessor " + std::to_string(index) + " does not exist");
    const tinygltf::Accessor& a = m_.accessors[std::size_t(index)];
    const int cs = component_size(a.componentType), nc = type_components(a.type);
    if (cs == 0 || nc == 0)
      throw IoError(name_, what + ": accessor " + std::to_string(index) + " has an invalid type");
    if (nc != comps)
      throw IoError(name_, what + ": accessor " + std::to_string(index) + " has " +
                               std::to_string(nc) + " components, expected " +
                               std::to_string(comps));
    if (a.sparse.isSparse) throw IoError(name_, what + ": sparse accessors are not supported");
    // Declared sizes are checked against the real bytes before anything is allocated.
    if (a.bufferView < 0 || a.count == 0) {  // no bufferView: zeros (glTF 2.0)
      if (a.count > file_size_)
        throw IoError(name_, what + ": accessor " + std::to_string(index) + " declares " +
                                 std::to_string(a.count) + " elements without data");
      return std::vector<double>(a.count * std::size_t(nc), 0.0);
    }
    const auto [base, len] = view(a.bufferView, what);
    const std::size_t elem = std::size_t(cs) * std::size_t(nc);
    const std::size_t stride = m_.bufferViews[std::size_t(a.bufferView)].byteStride
                                   ? m_.bufferViews[std::size_t(a.bufferView)].byteStride
                                   : elem;
    if (stride < elem ||
        std::uint64_t(a.byteOffset) + std::uint64_t(stride) * (a.count - 1) + elem > len)
      throw IoError(name_,
                    what + ": accessor " + std::to_string(index) + " reads past its bufferView");
    std::vector<double> out(a.count * std::size_t(nc), 0.0);
    for (std::size_t i = 0; i < a.count; ++i) {
      const unsigned char* p = base + a.byteOffset + i * stride;
      for (int k = 0; k < nc; ++k)
        out[i * std::size_t(nc) + std::size_t(k)] =
            component(p + std::size_t(k) * std::size_t(cs), a.componentType, a.normalized);
    }
    return out;
  }

  const tinygltf::Model& m_;
  std::string name_;
  std::size_t file_size_;
};

Mat4 node_matrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    Mat4 m;
    for (int i = 0; i < 16; ++i) m[std::size_t(i)] = n.matrix[std::size_t(i)];
    return m;
  }
  Mat4 t = kIdentity, r = kIdentity, s = kIdentity;
  if (n.translation.size() == 3)
    for (int k = 0; k < 3; ++k) t[12 + std::size_t(k)] = n.translation[std::size_t(k)];
  if (n.rotation.size() == 4) {
    const double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
    r = {1 - 2 * (y * y + z * z),
         2 * (x * y + z * w),
         2 * (x * z - y * w),
         0,
         2 * (x * y - z * w),
         1 - 2 * (x * x + z * z),
         2 * (y * z + x * w),
         0,
         2 * (x * z + y * w),
         2 * (y * z - x * w),
         1 - 2 * (x * x + y * y),
         0,
         0,
         0,
         0,
         1};
  }
  if (n.scale.size() == 3)
    for (int k = 0; k < 3; ++k) s[std::size_t(k) * 5] = n.scale[std::size_t(k)];
  return multiply(t, multiply(r, s));
}

const tinygltf::Value& member(const tinygltf::Value& v, const char* key) {
  static const tinygltf::Value null_value;
  return v.IsObject() && v.Has(key) ? v.Get(key) : null_value;
}

int int_member(const tinygltf::Value& v, const char* key, int def) {
  const tinygltf::Value& x = member(v, key);
  return x.IsNumber() ? x.GetNumberAsInt() : def;
}

std::string string_member(const tinygltf::Value& v, const char* key, const std::string& def = "") {
  const tinygltf::Value& x = member(v, key);
  return x.IsString() ? x.Get<std::string>() : def;
}

/// Reads one property table of EXT_structural_metadata.
GlbPropertyTable read_table(const Reader& rd, const tinygltf::Value& schema,
                            const tinygltf::Value& table, int index) {
  const std::string where = "property table " + std::to_string(index);
  GlbPropertyTable t;
  t.name = string_member(table, "name");
  t.class_name = string_member(table, "class");
  const int count = int_member(table, "count", -1);
  if (count < 0) throw IoError(rd.name_, where + " has no valid count");
  t.count = std::size_t(count);
  const tinygltf::Value& cls =
      member(member(member(schema, "classes"), t.class_name.c_str()), "properties");
  const tinygltf::Value& props = member(table, "properties");
  for (const std::string& name : props.Keys()) {
    const tinygltf::Value& p = props.Get(name);
    const tinygltf::Value& def = member(cls, name.c_str());
    const std::string type = string_member(def, "type");
    if (member(def, "array").IsBool() && member(def, "array").Get<bool>())
      continue;  // arrays: not read
    const std::string what = where + " property '" + name + "'";
    const int values = int_member(p, "values", -1);
    if (type == "STRING") {
      const auto [data, len] = rd.view(values, what);
      const auto [offs, olen] = rd.view(int_member(p, "stringOffsets", -1), what);
      const std::string ot = string_member(p, "stringOffsetType", "UINT32");
      const std::size_t os = ot == "UINT8"    ? 1
                             : ot == "UINT16" ? 2
                             : ot == "UINT32" ? 4
                             : ot == "UINT64" ? 8
                                              : 0;
      if (os == 0) throw IoError(rd.name_, what + ": unknown stringOffsetType " + ot);
      if (olen < (t.count + 1) * os)
        throw IoError(rd.name_, what + ": string offsets are truncated");
      const unsigned char* const offsets = offs;  // (a lambda cannot capture a binding in C++17)
      auto off = [&](std::size_t i) {
        std::uint64_t v = 0;
        std::memcpy(&v, offsets + i * os, os);
        return v;
      };
      auto& col = t.strings[name];
      for (std::size_t i = 0; i < t.count; ++i) {
        const std::uint64_t a = off(i), b = off(i + 1);
        if (a > b || b > len)
          throw IoError(rd.name_, what + ": string offsets lie outside the values");
        col.emplace_back(reinterpret_cast<const char*>(data) + a, std::size_t(b - a));
      }
    } else if (type == "BOOLEAN") {
      const auto [data, len] = rd.view(values, what);
      if (len < (t.count + 7) / 8) throw IoError(rd.name_, what + ": values are truncated");
      for (std::size_t i = 0; i < t.count; ++i)
        t.numbers[name].push_back((data[i / 8] >> (i % 8)) & 1u ? 1.0 : 0.0);
    } else if (type == "SCALAR" || type == "ENUM") {
      std::string ct = string_member(def, "componentType");
      std::map<long long, std::string> names;
      if (type == "ENUM") {
        const tinygltf::Value& e =
            member(member(schema, "enums"), string_member(def, "enumType").c_str());
        ct = string_member(e, "valueType", "UINT16");
        const tinygltf::Value& vs = member(e, "values");
        for (std::size_t i = 0; i < vs.ArrayLen(); ++i)
          names[int_member(vs.Get(int(i)), "value", 0)] = string_member(vs.Get(int(i)), "name");
      }
      static const std::map<std::string, int> kTypes{
          {"INT8", TINYGLTF_COMPONENT_TYPE_BYTE},
          {"UINT8", TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE},
          {"INT16", TINYGLTF_COMPONENT_TYPE_SHORT},
          {"UINT16", TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
          {"INT32", TINYGLTF_COMPONENT_TYPE_INT},
          {"UINT32", TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
          {"FLOAT32", TINYGLTF_COMPONENT_TYPE_FLOAT},
          {"FLOAT64", TINYGLTF_COMPONENT_TYPE_DOUBLE}};
      const auto it = kTypes.find(ct);
      if (it == kTypes.end()) continue;  // INT64/UINT64 and unknown: not read
      const auto [data, len] = rd.view(values, what);
      const std::size_t cs = std::size_t(component_size(it->second));
      if (len < t.count * cs) throw IoError(rd.name_, what + ": values are truncated");
      for (std::size_t i = 0; i < t.count; ++i) {
        const double v = component(data + i * cs, it->second, false);
        if (type == "ENUM") {
          const auto n = names.find((long long)v);
          t.strings[name].push_back(n != names.end() ? n->second : std::to_string((long long)v));
        } else {
          t.numbers[name].push_back(v);
        }
      }
    }
  }
  return t;
}

}  // namespace

Vec3d transform_point(const std::array<double, 16>& m, const Vec3d& p) {
  return {m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
          m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
          m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14]};
}

std::array<double, 16> multiply(const std::array<double, 16>& a, const std::array<double, 16>& b) {
  std::array<double, 16> c{};
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[std::size_t(k * 4 + row)] * b[std::size_t(col * 4 + k)];
      c[std::size_t(col * 4 + row)] = s;
    }
  return c;
}

namespace {

std::uint32_t glb_u32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
void glb_put32(std::string& b, std::uint32_t v) {
  char c[4];
  std::memcpy(c, &v, 4);
  b.append(c, 4);
}

/// A glb whose bufferViews use EXT_meshopt_compression, decoded into a plain
/// glb (the decoded views appended to the BIN chunk); other glbs unchanged.
/// `used`: whether the extension was there.
std::string decode_meshopt(const std::string& bytes, const std::string& name, bool& used) {
  used = false;
  if (bytes.size() < 28 || bytes.find("EXT_meshopt_compression") == std::string::npos) return bytes;
  const std::uint32_t json_len = glb_u32(bytes, 12);
  if (20 + std::size_t(json_len) > bytes.size()) return bytes;  // tinygltf reports it
  nlohmann::ordered_json j =
      nlohmann::ordered_json::parse(bytes.substr(20, json_len), nullptr, false);
  if (j.is_discarded() || !j.contains("bufferViews")) return bytes;
  const std::size_t bin_at = 20 + json_len;
  std::string bin;
  if (bin_at + 8 <= bytes.size()) {
    const std::uint32_t bin_len = glb_u32(bytes, bin_at);
    if (bin_at + 8 + std::size_t(bin_len) > bytes.size())
      throw IoError(name, "BIN chunk is truncated");
    bin = bytes.substr(bin_at + 8, bin_len);
  }
  for (auto& bv : j["bufferViews"]) {
    if (!bv.contains("extensions") || !bv["extensions"].contains("EXT_meshopt_compression"))
      continue;
    used = true;
    const auto& e = bv["extensions"]["EXT_meshopt_compression"];
    const std::size_t off = e.value("byteOffset", std::size_t(0)),
                      len = e.value("byteLength", std::size_t(0)),
                      stride = e.value("byteStride", std::size_t(0)),
                      count = e.value("count", std::size_t(0));
    const std::string mode = e.value("mode", ""), filter = e.value("filter", "NONE");
    if (e.value("buffer", -1) != 0 || off > bin.size() || len > bin.size() - off || stride == 0)
      throw IoError(name,
                    "EXT_meshopt_compression: a bufferView's data lies outside the BIN chunk");
    // The codecs' own preconditions (meshoptimizer asserts them: an abort, not
    // an error), and a decoded size the encoded bytes can hold: the vertex
    // codec packs at most 64:1, the index codecs less.
    const bool index_stride = stride == 2 || stride == 4;
    const bool ok_params =
        mode == "ATTRIBUTES"
            ? stride % 4 == 0 && stride <= 256 &&
                  (filter == "NONE" || (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) ||
                   (filter == "QUATERNION" && stride == 8) || filter == "EXPONENTIAL")
        : mode == "TRIANGLES" ? index_stride && count % 3 == 0
                              : mode == "INDICES" && index_stride;
    if (!ok_params)
      throw IoError(name, "EXT_meshopt_compression: invalid mode, filter, byteStride or count");
    if (count > (64 * len + 4096) / stride)
      throw IoError(name, "EXT_meshopt_compression: a bufferView declares more data (" +
                              std::to_string(count) + " x " + std::to_string(stride) +
                              " bytes) than its " + std::to_string(len) + " bytes can hold");
    std::vector<unsigned char> out(count * stride);
    const auto* src = reinterpret_cast<const unsigned char*>(bin.data() + off);
    int rc = -1;
    if (mode == "ATTRIBUTES") {
      rc = meshopt_decodeVertexBuffer(out.data(), count, stride, src, len);
      if (rc == 0 && filter == "OCTAHEDRAL") meshopt_decodeFilterOct(out.data(), count, stride);
      if (rc == 0 && filter == "QUATERNION") meshopt_decodeFilterQuat(out.data(), count, stride);
      if (rc == 0 && filter == "EXPONENTIAL") meshopt_decodeFilterExp(out.data(), count, stride);
    } else if (mode == "TRIANGLES") {
      rc = meshopt_decodeIndexBuffer(out.data(), count, stride, src, len);
    } else if (mode == "INDICES") {
      rc = meshopt_decodeIndexSequence(out.data(), count, stride, src, len);
    }
    if (rc != 0)
      throw IoError(name,
                    "EXT_meshopt_compression: cannot decode a bufferView (mode " + mode + ")");
    while (bin.size() % 8) bin.push_back('\0');
    bv["buffer"] = 0;
    bv["byteOffset"] = bin.size();
    bv["byteLength"] = out.size();
    bv["extensions"].erase("EXT_meshopt_compression");
    if (bv["extensions"].empty()) bv.erase("extensions");
    bin.append(reinterpret_cast<const char*>(out.data()), out.size());
  }
  if (!used) return bytes;
  while (bin.size() % 4) bin.push_back('\0');
  j["buffers"] = nlohmann::ordered_json::array({{{"byteLength", bin.size()}}});
  for (const char* key : {"extensionsUsed", "extensionsRequired"})
    if (j.contains(key)) {
      auto& a = j[key];
      for (auto it = a.begin(); it != a.end();)
        it = *it == "EXT_meshopt_compression" ? a.erase(it) : it + 1;
      if (a.empty()) j.erase(key);
    }
  std::string js = j.dump();
  while (js.size() % 4) js.push_back(' ');
  std::string out("glTF", 4);
  glb_put32(out, 2);
  glb_put32(out, std::uint32_t(28 + js.size() + bin.size()));
  glb_put32(out, std::uint32_t(js.size()));
  out.append("JSON", 4);
  out += js;
  glb_put32(out, std::uint32_t(bin.size()));
  out.append("BIN\0", 4);
  out += bin;
  return out;
}

/// JSON -> tinygltf::Value (for a schema read from its own file).
tinygltf::Value to_value(const nlohmann::json& j) {
  if (j.is_object()) {
    tinygltf::Value::Object o;
    for (const auto& [k, v] : j.items()) o[k] = to_value(v);
    return tinygltf::Value(std::move(o));
  }
  if (j.is_array()) {
    tinygltf::Value::Array a;
    for (const auto& v : j) a.push_back(to_value(v));
    return tinygltf::Value(std::move(a));
  }
  if (j.is_string()) return tinygltf::Value(j.get<std::string>());
  if (j.is_boolean()) return tinygltf::Value(j.get<bool>());
  if (j.is_number_integer() && j.get<double>() >= std::numeric_limits<int>::min() &&
      j.get<double>() <= std::numeric_limits<int>::max())
    return tinygltf::Value(j.get<int>());
  if (j.is_number()) return tinygltf::Value(j.get<double>());
  return tinygltf::Value();
}

/// The schema an EXT_structural_metadata object refers to by `schemaUri`: a
/// relative path resolved against `dir` (the glb's directory). Null when
/// there is no directory (bytes in memory) or the URI is absolute / has a scheme.
tinygltf::Value external_schema(const std::string& uri, const std::string& dir,
                                const std::string& name) {
  if (dir.empty() || uri.empty() || uri[0] == '/' || uri.find(':') != std::string::npos)
    return tinygltf::Value();
  const std::string path = (std::filesystem::path(dir) / uri).string();
  const std::uint64_t size = regular_file_size(path);
  if (size > (std::uint64_t(64) << 20))
    throw IoError(name, "schema " + uri + " larger than 64 MiB");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw IoError(name, "cannot open its schema " + uri);
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    throw IoError(name, "schema " + uri + " is not a JSON object");
  return to_value(j);
}

GlbDocument parse_glb_in(const std::string& bytes, const std::string& name, const std::string& dir);

}  // namespace

GlbDocument parse_glb(const std::string& bytes, const std::string& name) {
  return parse_glb_in(bytes, name, "");
}

namespace {

/// The (plain) glb as a tinygltf model. Images are accepted as they are, never decoded;
/// only what the glb holds is read: no external buffers or images (any file of the
/// machine).
void load_model(const std::string& plain, const std::string& name, tinygltf::Model& model) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int,
                           const unsigned char*, int, void*) { return true; },
                        nullptr);
  tinygltf::FsCallbacks fs_cb{};
  fs_cb.FileExists = [](const std::string&, void*) { return false; };
  fs_cb.ExpandFilePath = [](const std::string& p, void*) { return p; };
  fs_cb.ReadWholeFile = [](std::vector<unsigned char>*, std::string* err, const std::string& p,
                           void*) {
    if (err) *err += "external file '" + p + "' not read (a glb must hold its buffers)\n";
    return false;
  };
  fs_cb.WriteWholeFile = [](std::string*, const std::string&, const std::vector<unsigned char>&,
                            void*) { return false; };
  fs_cb.user_data = nullptr;
  loader.SetFsCallbacks(fs_cb);
  std::string err, warn;
  const std::string base = std::filesystem::path(name).parent_path().string();
  if (!loader.LoadBinaryFromMemory(&model, &err, &warn,
                                   reinterpret_cast<const unsigned char*>(plain.data()),
                                   static_cast<unsigned int>(plain.size()), base)) {
    std::string e = err.empty() ? "tinygltf could not parse it" : err;
    for (auto& c : e)
      if (c == '\n' || c == '\r') c = ' ';
    while (!e.empty() && e.back() == ' ') e.pop_back();
    throw IoError(name, "not a valid glb: " + e);
  }
}

/// The root nodes: the default scene's (else the first scene's); without scenes, the
/// nodes no node has as a child.
std::vector<int> scene_roots(const tinygltf::Model& model, const std::string& name) {
  std::vector<int> roots;
  const int scene = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
  if (scene >= 0) {
    if (std::size_t(scene) >= model.scenes.size())
      throw IoError(name, "default scene does not exist");
    roots = model.scenes[std::size_t(scene)].nodes;
  } else {
    std::set<int> children;
    for (const auto& n : model.nodes) children.insert(n.children.begin(), n.children.end());
    for (int i = 0; i < int(model.nodes.size()); ++i)
      if (!children.count(i)) roots.push_back(i);
  }
  return roots;
}

/// A primitive's triangles: its indices (or 0..nv-1), a multiple of 3, each in range.
void read_triangles(const Reader& rd, const tinygltf::Primitive& prim, std::size_t nv,
                    const std::string& what, const std::string& name, GlbPrimitive& out) {
  std::vector<double> idx;
  if (prim.indices >= 0) {
    idx = rd.accessor(prim.indices, 1, what + " indices");
  } else {
    idx.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) idx[i] = double(i);
  }
  if (idx.size() % 3)
    throw IoError(name, what + ": " + std::to_string(idx.size()) + " indices, not a multiple of 3");
  for (std::size_t i = 0; i + 2 < idx.size(); i += 3) {
    std::array<std::uint32_t, 3> t;
    for (int k = 0; k < 3; ++k) {
      const double v = idx[i + std::size_t(k)];
      if (!(v >= 0) || v >= double(nv))
        throw IoError(name, what + ": index " + std::to_string((long long)v) +
                                " is out of range (" + std::to_string(nv) + " vertices)");
      t[std::size_t(k)] = std::uint32_t(v);
    }
    out.triangles.push_back(t);
  }
}

/// EXT_mesh_features: the first feature id set of a primitive (`tables`: the property
/// tables the glb has).
void read_feature_ids(const Reader& rd, const tinygltf::Primitive& prim, std::size_t nv,
                      std::size_t tables, const std::string& what, const std::string& name,
                      GlbPrimitive& out) {
  const auto fx = prim.extensions.find("EXT_mesh_features");
  if (fx == prim.extensions.end()) return;
  const tinygltf::Value& ids = member(fx->second, "featureIds");
  if (ids.ArrayLen() == 0) return;
  const tinygltf::Value& f = ids.Get(0);
  out.property_table = int_member(f, "propertyTable", -1);
  if (out.property_table >= int(tables))
    throw IoError(name, what + ": feature ids refer to property table " +
                            std::to_string(out.property_table) + " that does not exist");
  const int attr = int_member(f, "attribute", -1);
  if (attr >= 0) {
    const auto a = prim.attributes.find("_FEATURE_ID_" + std::to_string(attr));
    if (a == prim.attributes.end())
      throw IoError(name, what + ": no attribute _FEATURE_ID_" + std::to_string(attr));
    const std::vector<double> v =
        rd.accessor(a->second, 1, what + " _FEATURE_ID_" + std::to_string(attr));
    if (v.size() != nv) throw IoError(name, what + ": feature ids and positions differ in count");
    out.feature_ids.reserve(nv);
    for (double x : v)
      out.feature_ids.push_back(std::isfinite(x) ? std::int64_t(std::llround(x)) : -1);
  } else if (!member(f, "texture").IsObject()) {
    for (std::size_t i = 0; i < nv; ++i)
      out.feature_ids.push_back(std::int64_t(i));  // implicit ids
  } else {
    out.property_table = -1;  // feature ids in a texture: not read
  }
}

/// Primitive `pi` of node `ni`'s mesh (a triangle primitive) with the node's transform `m`.
GlbPrimitive read_primitive(const Reader& rd, const tinygltf::Node& node, int ni, const Mat4& m,
                            const tinygltf::Primitive& prim, std::size_t pi, std::size_t tables,
                            const std::string& name) {
  const std::string what = "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(pi);
  const auto pos = prim.attributes.find("POSITION");
  if (pos == prim.attributes.end()) throw IoError(name, what + " has no POSITION");
  GlbPrimitive out;
  out.node = ni;
  out.node_name = node.name;
  out.matrix = m;
  out.material = prim.material;
  out.position_accessor = pos->second;
  const std::vector<double> p = rd.accessor(pos->second, 3, what + " POSITION");
  out.positions.resize(p.size() / 3);
  for (std::size_t i = 0; i < out.positions.size(); ++i) {
    out.positions[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
    if (!std::isfinite(p[3 * i]) || !std::isfinite(p[3 * i + 1]) || !std::isfinite(p[3 * i + 2]))
      throw IoError(name, what + ": position " + std::to_string(i) + " is not finite");
  }
  const std::size_t nv = out.positions.size();
  read_triangles(rd, prim, nv, what, name, out);
  read_feature_ids(rd, prim, nv, tables, what, name, out);
  return out;
}

GlbDocument parse_glb_in(const std::string& bytes, const std::string& name,
                         const std::string& dir) {
  check_container(bytes, name);
  if (bytes.size() > std::numeric_limits<unsigned int>::max())
    throw IoError(name, "glb larger than 4 GiB");
  bool meshopt = false;
  const std::string plain = decode_meshopt(bytes, name, meshopt);
  tinygltf::Model model;
  load_model(plain, name, model);
  const Reader rd(model, name, bytes.size());
  GlbDocument doc;
  doc.extensions_used = model.extensionsUsed;
  if (meshopt) {
    doc.extensions_used.push_back("EXT_meshopt_compression");
    std::sort(doc.extensions_used.begin(), doc.extensions_used.end());
  }
  doc.generator = model.asset.generator;

  // ---- property tables
  const auto meta = model.extensions.find("EXT_structural_metadata");
  if (meta != model.extensions.end()) {
    tinygltf::Value schema = member(meta->second, "schema");
    if (!schema.IsObject())
      schema = external_schema(string_member(meta->second, "schemaUri"), dir, name);
    const tinygltf::Value& tables = member(meta->second, "propertyTables");
    for (std::size_t i = 0; i < tables.ArrayLen(); ++i)
      doc.property_tables.push_back(read_table(rd, schema, tables.Get(int(i)), int(i)));
  }

  // ---- nodes of the scene, depth first
  const std::vector<int> roots = scene_roots(model, name);
  std::vector<std::pair<int, Mat4>> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, kIdentity});
  std::size_t visits = 0;
  while (!stack.empty()) {
    const auto [ni, parent] = stack.back();
    stack.pop_back();
    if (ni < 0 || std::size_t(ni) >= model.nodes.size())
      throw IoError(name, "node " + std::to_string(ni) + " does not exist");
    if (++visits > model.nodes.size() * 4 + 16)
      throw IoError(name, "the node hierarchy has a cycle");
    const tinygltf::Node& node = model.nodes[std::size_t(ni)];
    const Mat4 m = multiply(parent, node_matrix(node));
    for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.push_back({*c, m});
    if (node.mesh < 0) continue;
    if (std::size_t(node.mesh) >= model.meshes.size())
      throw IoError(name, "mesh " + std::to_string(node.mesh) + " does not exist");
    const tinygltf::Mesh& mesh = model.meshes[std::size_t(node.mesh)];
    for (std::size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1)
        continue;  // points, lines, strips: no surface
      doc.primitives.push_back(
          read_primitive(rd, node, ni, m, prim, pi, doc.property_tables.size(), name));
    }
  }
  return doc;
}

}  // namespace

GlbDocument read_glb(const std::string& path) {
  // the real size first: nothing is allocated for what the file does not hold
  const std::uint64_t size = regular_file_size(path);
  if (size > std::numeric_limits<unsigned int>::max()) throw IoError(path, "glb larger than 4 GiB");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw IoError(path, "cannot open");
  std::string bytes(std::size_t(size), '\0');
  f.read(bytes.data(), std::streamsize(size));
  if (std::uint64_t(f.gcount()) != size) throw IoError(path, "read error (file changed?)");
  return parse_glb_in(bytes, path, std::filesystem::path(path).parent_path().string());
}

}  // namespace citylod::io
