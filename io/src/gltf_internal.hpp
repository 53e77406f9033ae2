// Private: what the files of the glb writer share. Each file is one seam:
//   gltf_shading.cpp   flat shading (a mesh -> vertices per face normal, classes)
//   gltf_quantize.cpp  the positions as stored (int16, snapped, EXPONENTIAL bits)
//   gltf_meshopt.cpp   EXT_meshopt_compression (codecs, codec order, fallback views)
//   gltf_metadata.cpp  EXT_structural_metadata (schema, property table)
//   gltf.cpp           the glTF assembled from them (GlbBuilder, glb())
// tinygltf stays in io/src: this header is not public.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "citylod/io/gltf.hpp"

namespace citylod::io {

namespace detail {

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

// ------------------------------------------------------------ gltf_shading.cpp
/// A mesh split into flat-shaded vertices (one per source vertex, face
/// normal and colour) and one index list per primitive class.
struct FlatMesh {
  std::vector<Vec3d> positions;
  std::vector<Vec3f> normals;
  std::vector<Rgba8> colours;  ///< one per vertex (a = 0: none)
  Indices indices;
  std::size_t triangles = 0;
};
FlatMesh flat_shade(const TriangleMesh& mesh, const std::vector<Rgba8>& colours = {});

/// An 8-bit sRGB value as an 8-bit linear one (glTF's vertex colours are linear).
std::uint8_t srgb_to_linear_u8(std::uint8_t v);

/// The features of one glTF node, flat-shaded, relative to the glb's origin.
struct GlbNode {
  std::string name;
  std::vector<Vec3d> rel;  // z-up, relative to origin
  std::vector<Vec3f> normals;
  std::vector<float> feature;
  std::vector<Rgba8> colours;  // one per vertex (a = 0: none)
  Indices indices;
  /// features stored with float positions (set by GlbBuilder::Impl::snapped)
  std::set<float> float_features;
  bool coloured() const {
    for (int c = 3; c < kClasses; ++c)
      if (!indices[size_t(c)].empty()) return true;
    return false;
  }
};

// ------------------------------------------------------------ gltf_quantize.cpp
/// Uniform dequantization scale of a node (KHR_mesh_quantization).
double quant_extent(const GlbNode& n);
inline std::int16_t quant(double x, double extent) {
  const double q = std::round(x / extent * 32767.0);
  return std::int16_t(std::clamp(q, -32767.0, 32767.0));
}
/// The features of a node whose distinct corners int16 would merge: two
/// corners closer than a quantization step would make a closed model
/// non-manifold.
std::set<float> unquantizable(const GlbNode& n);
/// The vertices and triangles of the features in `features` (in_set) or of
/// the others, renumbered.
GlbNode part(const GlbNode& n, const std::set<float>& features, bool in_set);
/// The float positions of `n` (y-up) through the EXPONENTIAL filter with
/// `bits`: the filtered words and what a client decodes.
void exp_encode(const GlbNode& n, int bits, std::vector<std::int32_t>& encoded,
                std::vector<float>& decoded);

// ------------------------------------------------------------ gltf_meshopt.cpp
/// Appends bufferViews to buffer 0, every one 8-byte aligned (required for
/// property table columns, harmless for the rest).
struct BinWriter {
  tinygltf::Model& model;
  std::vector<unsigned char>& data;

  int view(const void* p, std::size_t n, int target, int stride = 0);
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
                 int plain_stride);
  int triangles(const std::vector<std::uint32_t>& ix, std::size_t vertices, bool u16);
  int accessor(int view, int component, int type, std::size_t count, bool normalized = false,
               std::vector<double> min = {}, std::vector<double> max = {});
};
/// Selects the codec versions EXT_meshopt_compression defines (once per process).
void use_meshopt_versions();
/// A node's normals (y-up) as meshoptimizer's OCTAHEDRAL filter stores them:
/// 4 int8 a vertex.
std::vector<std::int8_t> octahedral_normals(const GlbNode& node);
/// A node's triangles in vertex-cache order (per primitive) and its vertices
/// in first-use order, each followed by the other vertices of its corner
/// (same feature, same position: flat shading stores a corner once per face
/// normal): consecutive equal positions are what meshoptimizer's vertex
/// codec stores in the fewest bits. Same surfaces, same features.
GlbNode codec_order(const GlbNode& in, bool corners_together, bool strip);
/// The glb's JSON with every encoded bufferView moved onto a fallback buffer
/// (no data) and described by its EXT_meshopt_compression object pointing at
/// the encoded bytes in the BIN chunk (`bin_length` bytes).
void move_to_fallback_buffer(nlohmann::ordered_json& j,
                             const std::vector<BinWriter::Meshopt>& views,
                             std::uint32_t bin_length);

// ------------------------------------------------------------ gltf_metadata.cpp
using Value = tinygltf::Value;
inline Value str(const std::string& s) {
  return Value(s);
}
inline Value obj(Value::Object o) {
  return Value(std::move(o));
}
/// The EXT_structural_metadata schema: class "building" (our properties and the
/// source attributes) and enum LodKind (lod::ModelKind). Keys sorted (nlohmann::json).
nlohmann::json schema_json(const std::vector<GlbAttribute>& attributes);
/// Puts the schema into the glb JSON's EXT_structural_metadata, first
/// (`schema`, or `schemaUri` when `schema_uri` is set).
void put_schema(nlohmann::ordered_json& j, const nlohmann::json& schema,
                const std::string& schema_uri);
/// The property table of the features (class "building"): one column of
/// bufferViews per property.
Value::Object property_table(BinWriter& w, const std::vector<GlbFeature>& features,
                             const std::vector<GlbAttribute>& attributes);

}  // namespace detail

// ------------------------------------------------------------ the builder's state
struct GlbBuilder::Impl {
  using Node = detail::GlbNode;
  Vec3d origin;
  GlbOptions opt;
  std::vector<Node> nodes;
  std::vector<GlbFeature> features;
  std::size_t triangles = 0;

  // gltf_quantize.cpp
  /// meshopt, float positions (y-up, relative): the EXPONENTIAL filter's
  /// fewest mantissa bits that keep the positions (0: none qualifies).
  int exp_bits(const Node& n, double extent) const;
  /// exp_bits of the float part `fpart` of stored node `ni`, computed once
  /// (the filter is per vertex: the codec order does not change it).
  int float_bits(std::size_t ni, const Node& fpart, double extent) const;
  mutable std::map<std::size_t, int> float_bits_of;
  /// Whether every valid feature of `n` is a valid solid with the positions
  /// `decoded` (y-up, 3 floats a vertex; corners welded by position).
  bool decoded_solids_valid(const Node& n, const std::vector<float>& decoded) const;
  /// The node as stored, and which of its features keep float positions.
  Node snapped(const Node& in) const;
  /// The nodes as stored (see snapped), computed once.
  const std::vector<Node>& stored_nodes() const;
  mutable std::unique_ptr<std::vector<Node>> stored;
  bool quantized(const Node& n) const {
    return (opt.quantize || opt.compression == Compression::meshopt) && n.float_features.empty();
  }
};

}  // namespace citylod::io
