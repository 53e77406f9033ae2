// The text and JSON forms of `citylod eval` (the library returns data: citylod/tiler/eval.hpp).
#pragma once

#include <cstdarg>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "citylod/lod/lod.hpp"
#include "citylod/tiler/eval.hpp"
#include "cli.hpp"

namespace citylod::app {

using namespace citylod::tiler;

inline const char* yes_no(bool b) {
  return b ? "yes" : "no";
}

inline std::string one_line_text(std::string s) {
  for (auto& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

/// The validity fields of a mesh check, in the order every eval form writes them.
inline void put_check(nlohmann::ordered_json& j, const lod::MeshCheck& c) {
  j["closed"] = c.closed;
  j["edge_manifold"] = c.edge_manifold;
  j["oriented"] = c.oriented;
  j["self_intersecting"] = c.self_intersecting;
  j["boundary_edges"] = c.boundary_edges;
  j["nonmanifold_edges"] = c.nonmanifold_edges;
  j["pinched_vertices"] = c.pinched_vertices;
  j["shells"] = c.shells;
  j["cavities"] = c.cavities;
  j["valid"] = c.valid();
}

/// The measured fields of one model (the keys of `citylod eval MODEL --json`).
/// `empty`: the model has no triangles; the distances are null.
inline nlohmann::ordered_json model_json(const lod::ModelEvaluation& e, bool empty = false) {
  using J = nlohmann::ordered_json;
  J j;
  j["triangles"] = empty ? std::size_t(0) : e.triangles;
  put_check(j, e.check);
  j["volume"] = empty ? J(nullptr) : J(e.volume);
  j["e1_percent"] = empty ? J(nullptr) : J(e.e1);
  j["e2_percent"] = empty ? J(nullptr) : J(e.e2);
  j["hausdorff_m"] = empty ? J(nullptr) : J(e.hausdorff);
  j["reference_diagonal_m"] = empty ? J(nullptr) : J(e.diagonal);
  return j;
}

nlohmann::ordered_json to_json(const std::vector<ModelFileEval>& models);
std::string to_text(const std::vector<ModelFileEval>& models);
nlohmann::ordered_json to_json(const WorkEval& w);
std::string to_text(const WorkEval& w);
nlohmann::ordered_json to_json(const TilesetEval& t);
std::string to_text(const TilesetEval& t);

}  // namespace citylod::app
