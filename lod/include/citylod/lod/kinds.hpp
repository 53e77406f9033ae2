// The words the LOD engine, the work directory, the tileset and the CityJSON
// share: the kind of a LOD model and the outcome of a building. One enum each,
// one spelling each (to_string / *_from_string). The engine defines them; the
// work-directory records (tiler/workdir.hpp) and the glb writer and reader
// (io/gltf.hpp, which may include this one header of lod) use these types, not
// copies of them. Standard library only.
#pragma once

#include <cstdint>
#include <string>

namespace citylod::lod {

/// Kind of a LOD model: an anchor (a finished level set), an interpolation
/// (a level in progress), or the fallback (the extruded outline written when
/// a building's reconstruction fails; it counts as an anchor). The values are
/// the glb property table's enum ModelKind.
enum class ModelKind : std::uint8_t { anchor = 0, interpolation = 1, fallback = 2 };
const char* to_string(ModelKind k);  ///< "anchor" | "interpolation" | "fallback"
/// Throws std::invalid_argument for an unknown spelling.
ModelKind model_kind_from_string(const std::string& s);
inline bool is_anchor(ModelKind k) {
  return k != ModelKind::interpolation;
}

/// The outcome of one building. The LOD engine returns ok or fallback; the LOD
/// stage records failed when the engine threw; the manifest starts at pending,
/// and split marks a building it could not cut skipped.
/// Spelling: "pending" | "ok" | "fallback" | "failed" | "skipped".
enum class Status { pending, ok, fallback, failed, skipped };
const char* to_string(Status s);
/// Throws std::invalid_argument for an unknown spelling.
Status status_from_string(const std::string& s);

}  // namespace citylod::lod
