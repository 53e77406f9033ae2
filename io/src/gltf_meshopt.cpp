// glb writer, EXT_meshopt_compression: vertex and index data through
// meshoptimizer's codecs (int8 octahedral normals, the orders whose encoded
// bytes are fewest), then every encoded bufferView moved onto a fallback
// buffer as the extension describes it.
#include <algorithm>
#include <map>
#include <mutex>

#include <meshoptimizer.h>

#include "citylod/io/error.hpp"
#include "gltf_internal.hpp"

namespace citylod::io::detail {

int BinWriter::attributes(const void* p, std::size_t count, std::size_t stride, const char* filter,
                          int plain_stride) {
  if (!meshopt) return view(p, count * stride, kArrayBuffer, plain_stride);
  std::vector<unsigned char> enc(meshopt_encodeVertexBufferBound(count, stride));
  enc.resize(meshopt_encodeVertexBuffer(enc.data(), enc.size(), p, count, stride));
  if (enc.empty()) throw IoError(kWhere, "meshopt vertex encoding failed");
  const int v = view(enc.data(), enc.size(), kArrayBuffer, int(stride));
  meshopt->push_back({v, count * stride, stride, count, "ATTRIBUTES", filter});
  return v;
}

int BinWriter::triangles(const std::vector<std::uint32_t>& ix, std::size_t vertices, bool u16) {
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

void use_meshopt_versions() {
  static std::once_flag versions;  // the formats EXT_meshopt_compression defines
  std::call_once(versions, [] {
    meshopt_encodeVertexVersion(0);
    meshopt_encodeIndexVersion(1);
  });
}

std::vector<std::int8_t> octahedral_normals(const GlbNode& node) {
  const std::size_t nv = node.rel.size();
  std::vector<float> n4(nv * 4, 0.0f);
  for (std::size_t i = 0; i < nv; ++i) {
    const Vec3f& n = node.normals[i];
    n4[i * 4 + 0] = n[0];
    n4[i * 4 + 1] = n[2];
    n4[i * 4 + 2] = -n[1];
  }
  std::vector<std::int8_t> oct(nv * 4, 0);
  meshopt_encodeFilterOct(oct.data(), nv, 4, 8, n4.data());
  return oct;
}

GlbNode codec_order(const GlbNode& in, bool corners_together, bool strip) {
  GlbNode out = in;
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
  // the vertices of one corner (feature and position) side by side, in first-use order
  const auto key = [&](unsigned int v) {
    return std::array<double, 4>{double(in.feature[v]), in.rel[v][0], in.rel[v][1], in.rel[v][2]};
  };
  std::vector<unsigned int> by_corner(use_order);
  if (corners_together)
    std::stable_sort(by_corner.begin(), by_corner.end(),
                     [&](unsigned int a, unsigned int b) { return key(a) < key(b); });
  std::vector<unsigned int> at(nv);  // v's place in by_corner
  for (std::size_t i = 0; i < nv; ++i) at[by_corner[i]] = static_cast<unsigned int>(i);
  std::vector<unsigned int> remap(nv, ~0u);
  unsigned int next = 0;
  for (unsigned int v : use_order) {
    if (remap[v] != ~0u) continue;
    if (!corners_together) {
      remap[v] = next++;
      continue;
    }
    // v is the first-used vertex of its corner (a corner's vertices are numbered
    // together), so the first of them in by_corner (the sort is stable)
    for (std::size_t i = at[v]; i < nv && !(key(v) < key(by_corner[i])); ++i)
      remap[by_corner[i]] = next++;
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

void move_to_fallback_buffer(nlohmann::ordered_json& j,
                             const std::vector<BinWriter::Meshopt>& views,
                             std::uint32_t bin_length) {
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
        {{{"byteLength", bin_length}},
         {{"byteLength", fallback},
          {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}});
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
      std::vector<std::string> e = j.value(key, std::vector<std::string>{});
      e.push_back("EXT_meshopt_compression");
      std::sort(e.begin(), e.end());
      j[key] = e;
    }
  }
}

}  // namespace citylod::io::detail
