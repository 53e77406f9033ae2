// Binary glTF (glb) output for 3D Tiles content: per-building triangle meshes
// with flat normals, roof / wall / base materials (+ white "*_rgb" ones for
// triangles coloured from the input, COLOR_0), EXT_mesh_features feature
// ids and an EXT_structural_metadata property table (one row per feature).
//
//   io::GlbBuilder b(tile_centre_enu);            // node translation
//   b.add_feature(meta, mesh_in_scene_enu);       // one building (model) each
//   io::atomic_write_file(path, b.glb());
//
// Coordinates: meshes come in a z-up ENU frame (metres, double). The glb stores
// float32 positions relative to `origin` (so they stay small), rotated to glTF's
// y-up axes as (x, z, -y); the node translation puts them back at `origin`, and
// a 3D Tiles client's y-up -> z-up rotation restores the ENU axes. tinygltf is
// private to io/src. Output is deterministic: same calls -> same bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "citylod/lod/kinds.hpp"

#include "citylod/io/types.hpp"

namespace citylod::io {

/// One row of the glb's property table (class "building" of schema "citylod").
/// A feature is one LOD model of one building.
struct GlbFeature {
  std::string building_id;
  lod::ModelKind kind = lod::ModelKind::anchor;
  int level = 0;        ///< LOD-Tree level set of the model
  int step = 0;         ///< traversal step that produced it (report.json)
  int model_index = 0;  ///< position in the building's kept chain, 0 = coarsest
  int model_count = 1;  ///< models kept for the building
  double height_m = 0;  ///< vertical extent of the model
  double footprint_area_m2 = 0;
  double error_m = 0;  ///< geometric error: distance to the building's finest model
  /// RMSE of the building's input points to the model, metres (report.json
  /// e2); < 0 = not measured (stored as the property's noData, -1).
  double rmse_m = -1;
  bool valid = true;  ///< the model is a valid solid (closed, oriented, one shell, ...)
  /// Values of the GlbOptions::attributes by name (a JSON object; a missing key or
  /// null is "no data"), e.g. the building's footprint attributes.
  nlohmann::json attributes = nlohmann::json::object();
};

/// A source attribute written as a property of the "building" class (typed, the
/// same for every glb of a tileset: glb_attribute_schema() over all buildings).
struct GlbAttribute {
  enum class Type : std::uint8_t { int64, float64, boolean, string };
  std::string name;      ///< key in GlbFeature::attributes; the property's "name"
  std::string property;  ///< property id: "fp_" + name made [A-Za-z0-9_], unique
  Type type = Type::string;
  /// Some value is missing/null: FLOAT64 declares noData = lowest double, STRING
  /// the one-character string NUL ("\u0000").
  bool no_data = false;
  /// A STRING attribute with at most 255 distinct values (a missing one counts
  /// as the noData value NUL) and at most 3 per 4 objects (e.g. a constant
  /// source or status field): written as an ENUM (UINT8, enum id = `property`)
  /// of these values, sorted; a client reads back the same strings, one byte
  /// per feature.
  std::vector<std::string> enum_values;
};

/// The attributes of many features as typed properties, sorted by name: all
/// integers -> INT64 (FLOAT64 when some are missing and |v| <= 2^53, else
/// STRING); numbers -> FLOAT64; all booleans, none missing -> BOOLEAN; anything
/// else (strings, mixed types, booleans with gaps, all null) -> STRING (numbers and
/// booleans as JSON text; few distinct strings: `enum_values`). Deterministic
/// for the same set of objects.
std::vector<GlbAttribute> glb_attribute_schema(const std::vector<const nlohmann::json*>& objects);

/// Geometry compression of the glb.
///   none:    plain accessors (float32, or int16 with `quantize`).
///   meshopt: EXT_meshopt_compression (required extension): quantized
///            positions (int16, KHR_mesh_quantization) and normals (int8,
///            OCTAHEDRAL filter), feature ids and indices through
///            meshoptimizer's vertex / index codecs. Property tables stay plain.
enum class Compression : std::uint8_t { none = 0, meshopt = 1 };
const char* to_string(Compression c);  ///< "none" | "meshopt"
/// Throws std::invalid_argument naming the accepted values.
Compression compression_from_string(const std::string& s);

struct GlbOptions {
  /// KHR_mesh_quantization: positions as normalized int16 (node scale restores
  /// metres; step = node extent / 32767), normals as normalized int16. A node
  /// where int16 would merge two distinct corners of one model keeps float
  /// positions (the model stays closed and edge-manifold as stored).
  bool quantize = false;
  /// meshopt implies quantized positions (with the same float fallback).
  Compression compression = Compression::none;
  /// Quantized output: says whether a model, as int16 would store it, is a
  /// valid solid (vertices relative to the glb's origin, corners welded).
  /// Set, a valid model int16 could damage (corners within 2 steps, or a
  /// triangle under 4 steps high) is checked as stored, snapped when needed
  /// (its corners within 1-2 steps welded, collapsed triangles and
  /// zero-volume fins dropped) and kept float only when no snapped version
  /// passes; its float positions go through the EXPONENTIAL filter at the
  /// int16 step when they pass too (docs/3dtiles.md). Empty: a model whose
  /// distinct corners int16 would merge keeps float positions.
  std::function<bool(const TriangleMesh&)> snapped_is_valid;
  /// With snapped_is_valid: the distance (m) under which a validator reads two
  /// corners as one (val3dity's snap tolerance): a model with two distinct
  /// int16 corners within it is damageable too, and it is also snapped at the
  /// radius of that many steps. 0: only the 1-2 steps above.
  double snap_tolerance_m = 0;
  std::string generator = "citylod";
  /// Extra properties of the "building" class, from GlbFeature::attributes.
  std::vector<GlbAttribute> attributes;
  /// Non-empty: EXT_structural_metadata refers to the schema by this URI
  /// (relative to the glb; write glb_schema() there) instead of embedding it,
  /// so the tiles of a tileset share one copy.
  std::string schema_uri;
};

/// The EXT_structural_metadata schema (JSON text) of glbs written with `options`.
std::string glb_schema(const GlbOptions& options);

/// Surface class of a triangle, from its outward normal: roof (facing up, slope
/// below ~70 degrees), base (facing down), wall (everything else).
enum class SurfaceClass : std::uint8_t { wall = 0, roof = 1, base = 2 };
SurfaceClass classify_normal(const Vec3d& unit_normal);

/// Size of a mesh once flat-shaded the way GlbBuilder stores it.
struct GlbMeshSize {
  std::size_t vertices = 0;     ///< after splitting vertices per face normal
  std::size_t triangles = 0;    ///< non-degenerate triangles
  std::size_t bytes = 0;        ///< vertex + index data in the BIN chunk (estimate, +-4 B)
  std::size_t float_bytes = 0;  ///< the same stored as float32 (whatever `quantize` says)
};
GlbMeshSize glb_mesh_size(const TriangleMesh& mesh, bool quantize = false);

class GlbBuilder {
 public:
  /// `origin`: point of the input frame (z-up metres) that becomes the node
  /// translation; stored positions are relative to it.
  explicit GlbBuilder(const Vec3d& origin, GlbOptions options = {});
  ~GlbBuilder();
  GlbBuilder(GlbBuilder&&) noexcept;
  GlbBuilder& operator=(GlbBuilder&&) noexcept;

  /// Starts a new glTF node (with its own mesh); features added afterwards go
  /// into it. Without a call, everything goes into one node named "content".
  void begin_node(const std::string& name);

  /// Adds one feature (a building's model) to the current node: triangles are
  /// flat-shaded (vertices split per face normal), degenerate ones dropped.
  /// `colours` (empty, or one per triangle): a coloured triangle (a = 255)
  /// gets its colour as COLOR_0 (linear, from the sRGB input) and a white
  /// material of its surface class ("roof_rgb", ...); the others keep the
  /// fixed material. Returns its feature id (row in the property table).
  std::uint32_t add_feature(const GlbFeature& meta, const TriangleMesh& mesh,
                            const std::vector<Rgba8>& colours = {});

  std::size_t feature_count() const;
  std::size_t triangle_count() const;
  std::size_t vertex_count() const;

  /// The bounds of the positions as stored (after float32 rounding or
  /// quantization), back in the input frame: what a client will draw.
  BBox3 stored_bounds() const;

  /// Serializes to glb bytes. Throws IoError("<glb>: ...") when there is
  /// nothing to write or tinygltf fails.
  std::string glb() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::io
