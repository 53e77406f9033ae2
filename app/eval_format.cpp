// The text and JSON forms of `citylod eval` (eval_format.hpp).
#include "eval_format.hpp"

#include <algorithm>

namespace citylod::app {

nlohmann::ordered_json to_json(const std::vector<ModelFileEval>& models) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const auto& m : models) {
    nlohmann::ordered_json j{{"model", m.model}, {"reference", m.reference}};
    j.update(model_json(m.e));
    out.push_back(j);
  }
  return out;
}

std::string to_text(const std::vector<ModelFileEval>& models) {
  std::string text;
  for (const auto& m : models) {
    const lod::ModelEvaluation& e = m.e;
    text += strf(
        "%s: %zu triangles, %s, %s, %s, volume %.3f m3, e1 %.3f %%, e2 %.3f %%, Hausdorff %.3f m\n",
        m.model.c_str(), e.triangles, e.check.closed ? "closed" : "open",
        e.check.edge_manifold ? "edge-manifold" : "non-manifold",
        e.check.self_intersecting ? "self-intersecting" : "no self-intersections", e.volume, e.e1,
        e.e2, e.hausdorff);
    text += strf("  %d pinched vertices, %d shells, %d cavities: %s\n", e.check.pinched_vertices,
                 e.check.shells, e.check.cavities,
                 e.check.valid() ? "a valid solid" : "NOT a valid solid");
  }
  return text;
}

nlohmann::ordered_json to_json(const WorkEval& w) {
  using J = nlohmann::ordered_json;
  const WorkSummary s = summarize(w);
  J out;
  out["mode"] = "work";
  out["work"] = w.work;
  out["samples"] = w.samples;
  J bs = J::array();
  for (const auto& b : w.buildings) {
    J jb;
    jb["id"] = b.id;
    jb["status"] = to_string(b.status);
    if (!b.reason.empty()) jb["reason"] = b.reason;
    jb["has_lod"] = b.has_lod;
    if (b.has_lod) {
      jb["reference"] = {{"file", b.chunk},
                         {"points", b.reference_points},
                         {"triangles", b.reference_triangles},
                         {"diagonal_m", b.diagonal}};
      jb["finest_step"] = b.finest >= 0 ? J(b.models[size_t(b.finest)].step) : J(nullptr);
      J ms = J::array();
      for (const auto& m : b.models) {
        J jm = model_json(m.e, m.empty);
        J head{{"file", m.file},
               {"kind", lod::to_string(m.kind)},
               {"level", m.level},
               {"step", m.step}};
        head.update(jm);
        ms.push_back(head);
      }
      jb["models"] = ms;
    }
    bs.push_back(jb);
  }
  out["buildings"] = bs;
  J sum;
  sum["manifest_buildings"] = w.manifest_buildings;
  sum["buildings"] = s.buildings;
  sum["models"] = s.models;
  sum["closed"] = s.closed;
  sum["edge_manifold"] = s.edge_manifold;
  sum["oriented"] = s.oriented;
  sum["self_intersecting"] = s.self_intersecting;
  sum["pinched"] = s.pinched;
  sum["not_one_shell"] = s.not_one_shell;
  sum["valid"] = s.valid;
  sum["empty"] = s.empty;
  auto stat_json = [](const Stat& st) {
    return J{
        {"mean", st.mean}, {"median", st.median}, {"max", st.max}, {"max_building", st.argmax}};
  };
  sum["finest_e1_percent"] = stat_json(s.finest_e1);
  sum["finest_e2_percent"] = stat_json(s.finest_e2);
  J fb = J::array();
  for (const auto& [id, why] : s.fallbacks) fb.push_back({{"id", id}, {"reason", why}});
  sum["fallbacks"] = fb;
  J nl = J::array();
  for (const auto& [id, why] : s.without_lod) nl.push_back({{"id", id}, {"reason", why}});
  sum["without_lod"] = nl;
  out["summary"] = sum;
  return out;
}

std::string to_text(const WorkEval& w) {
  const WorkSummary s = summarize(w);
  std::string out = strf(
      "work directory %s: %zu buildings in the manifest, %zu with LOD output, %zu models "
      "(e1/e2 with %d samples per surface, %% of the reference's bbox diagonal)\n\n",
      w.work.c_str(), w.manifest_buildings, s.buildings, s.models, w.samples);
  std::size_t idw = 8;
  for (const auto& b : w.buildings)
    if (b.has_lod) idw = std::max(idw, b.id.size());
  out += strf("%-*s %4s %-13s %3s %9s %-6s %-8s %-8s %7s %6s %12s %8s %8s %11s\n", int(idw),
              "building", "step", "kind", "L", "triangles", "closed", "manifold", "self-int",
              "pinched", "shells", "volume m3", "e1 %", "e2 %", "Hausdorff m");
  for (const auto& b : w.buildings) {
    if (!b.has_lod) continue;
    for (std::size_t i = 0; i < b.models.size(); ++i) {
      const WorkModelEval& m = b.models[i];
      const std::string kind =
          std::string(lod::to_string(m.kind)) + (int(i) == b.finest ? "*" : "");
      if (m.empty) {
        out += strf("%-*s %4d %-13s %3d %9d %-6s %-8s %-8s %7s %6s %12s %8s %8s %11s\n", int(idw),
                    b.id.c_str(), m.step, kind.c_str(), m.level, 0, "-", "-", "-", "-", "-", "-",
                    "-", "-", "-");
        continue;
      }
      out += strf("%-*s %4d %-13s %3d %9zu %-6s %-8s %-8s %7d %6d %12.3f %8.3f %8.3f %11.3f\n",
                  int(idw), b.id.c_str(), m.step, kind.c_str(), m.level, m.e.triangles,
                  yes_no(m.e.check.closed), yes_no(m.e.check.edge_manifold),
                  yes_no(m.e.check.self_intersecting), m.e.check.pinched_vertices, m.e.check.shells,
                  m.e.volume, m.e.e1, m.e.e2, m.e.hausdorff);
    }
  }
  out += "(* = finest model of the building: its last anchor)\n\n";
  out += strf(
      "summary: %zu buildings, %zu models: %zu closed, %zu edge-manifold, %zu self-intersecting",
      s.buildings, s.models, s.closed, s.edge_manifold, s.self_intersecting);
  out += strf("; %zu valid solids (%zu with pinched vertices, %zu not one solid)", s.valid,
              s.pinched, s.not_one_shell);
  if (s.empty) out += strf(", %zu empty", s.empty);
  out += "\n";
  out += strf(
      "finest model per building: e2 mean %.3f %%, median %.3f %%, max %.3f %% (%s); "
      "e1 mean %.3f %%, median %.3f %%, max %.3f %% (%s)\n",
      s.finest_e2.mean, s.finest_e2.median, s.finest_e2.max, s.finest_e2.argmax.c_str(),
      s.finest_e1.mean, s.finest_e1.median, s.finest_e1.max, s.finest_e1.argmax.c_str());
  out += strf("fallbacks: %zu\n", s.fallbacks.size());
  for (const auto& [id, why] : s.fallbacks) out += "  " + id + ": " + why + "\n";
  if (!s.without_lod.empty()) {
    out += strf("without LOD output: %zu\n", s.without_lod.size());
    for (const auto& [id, why] : s.without_lod) out += "  " + id + ": " + why + "\n";
  }
  return out;
}

nlohmann::ordered_json to_json(const TilesetEval& t) {
  using J = nlohmann::ordered_json;
  J out;
  out["mode"] = "tileset";
  out["tileset"] = t.tileset;
  out["work"] = t.work.empty() ? J(nullptr) : J(t.work);
  out["samples"] = t.samples;
  out["tiles"] = t.tiles;
  out["content_tiles"] = t.contents.size();
  out["depth"] = t.depth;
  J levels = J::array();
  for (const auto& l : t.levels) {
    J j{{"level", l.level},
        {"tiles", l.tiles},
        {"meshes", l.meshes},
        {"buildings", l.buildings},
        {"triangles", l.triangles},
        {"closed", l.closed},
        {"edge_manifold", l.edge_manifold},
        {"self_intersecting", l.self_intersecting},
        {"pinched", l.pinched},
        {"not_one_shell", l.not_one_shell},
        {"valid", l.valid},
        {"valid_val3dity", l.valid_tolerant}};
    if (l.evaluated) {
      j["mean_e1_percent"] = l.mean_e1;
      j["mean_e2_percent"] = l.mean_e2;
      j["max_e2_percent"] = l.max_e2;
      j["max_e2_building"] = l.max_e2_building;
    }
    levels.push_back(j);
  }
  out["levels"] = levels;
  J tiles = J::array();
  for (const auto& c : t.contents)
    tiles.push_back({{"uri", c.uri},
                     {"level", c.level},
                     {"geometric_error", c.geometric_error},
                     {"triangles", c.triangles},
                     {"buildings", c.buildings}});
  out["contents"] = tiles;
  J meshes = J::array();
  for (const auto& m : t.meshes) {
    J j{{"building", m.building}, {"level", m.level}, {"tile", m.tile}};
    j["model_index"] = m.model_index >= 0 ? J(m.model_index) : J(nullptr);
    j["step"] = m.step >= 0 ? J(m.step) : J(nullptr);
    j["kind"] = m.kind ? J(lod::to_string(*m.kind)) : J(nullptr);
    j["triangles"] = m.triangles;
    j["vertices"] = m.vertices;
    put_check(j, m.check);
    j["val3dity_error"] = m.val3dity_error;  // 0: valid at val3dity's tolerances
    j["volume"] = m.volume;
    if (m.evaluated) {
      j["e1_percent"] = m.e1;
      j["e2_percent"] = m.e2;
      j["hausdorff_m"] = m.hausdorff;
    }
    meshes.push_back(j);
  }
  out["buildings"] = meshes;
  return out;
}

std::string to_text(const TilesetEval& t) {
  std::string out = strf("tileset %s: %zu tiles, %zu with glb content, depth %d", t.tileset.c_str(),
                         t.tiles, t.contents.size(), t.depth);
  if (!t.work.empty())
    out += strf(
        "; e1/e2 against the chunks of %s (%d samples per surface, %% of the chunk's bbox "
        "diagonal)",
        t.work.c_str(), t.samples);
  out += "\n\n";
  const bool ev = !t.work.empty();
  out += strf("%5s %6s %9s %10s %7s %8s %8s %7s %9s %6s %9s", "level", "tiles", "buildings",
              "triangles", "closed", "manifold", "self-int", "pinched", "not-1-shl", "valid",
              "val3dity");
  if (ev) out += strf(" %9s %9s %9s  %s", "mean e1 %", "mean e2 %", "max e2 %", "(building)");
  out += "\n";
  for (const auto& l : t.levels) {
    out += strf("%5d %6zu %9zu %10zu %7zu %8zu %8zu %7zu %9zu %6zu %9zu", l.level, l.tiles,
                l.buildings, l.triangles, l.closed, l.edge_manifold, l.self_intersecting, l.pinched,
                l.not_one_shell, l.valid, l.valid_tolerant);
    if (ev)
      out +=
          strf(" %9.3f %9.3f %9.3f  %s", l.mean_e1, l.mean_e2, l.max_e2, l.max_e2_building.c_str());
    out += "\n";
  }
  out +=
      "(closed / manifold / self-int / pinched: building meshes with a pinched vertex / not-1-shl: "
      "not one solid / valid: valid solids / val3dity: valid at val3dity's tolerances, snap 1 mm, "
      "planarity 1 cm / 20 degrees; a level is a tile depth, root = 0)\n\n";
  std::size_t idw = 8, tw = 4;
  for (const auto& m : t.meshes) {
    idw = std::max(idw, m.building.size());
    tw = std::max(tw, m.tile.size());
  }
  out += strf("%-*s %5s %-*s %5s %-13s %9s %-6s %-8s %-8s %8s %12s", int(idw), "building", "level",
              int(tw), "tile", "model", "kind", "triangles", "closed", "manifold", "self-int",
              "val3dity", "volume m3");
  if (ev) out += strf(" %8s %8s %11s", "e1 %", "e2 %", "Hausdorff m");
  out += "\n";
  for (const auto& m : t.meshes) {
    const std::string model = m.model_index >= 0 ? std::to_string(m.model_index) : "-";
    out +=
        strf("%-*s %5d %-*s %5s %-13s %9zu %-6s %-8s %-8s %8s %12.3f", int(idw), m.building.c_str(),
             m.level, int(tw), m.tile.c_str(), model.c_str(),
             m.kind ? lod::to_string(*m.kind) : "-", m.triangles, yes_no(m.check.closed),
             yes_no(m.check.edge_manifold), yes_no(m.check.self_intersecting),
             m.val3dity_error == 0 ? "valid" : std::to_string(m.val3dity_error).c_str(), m.volume);
    if (ev) out += strf(" %8.3f %8.3f %11.3f", m.e1, m.e2, m.hausdorff);
    out += "\n";
  }
  return out;
}

}  // namespace citylod::app
