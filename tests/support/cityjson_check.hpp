// Checks of CityJSON 2.0 text sequences written by citylod, independent of
// citylod's own code: the structure rules of the specification (required
// members, integer vertices, index ranges, Solid depth, semantics aligned
// with the boundaries, feature ids) and a solid check of each Solid on its
// polygons (closed, consistently oriented with a positive volume = outward,
// edge-manifold, no pinched vertex), by exact incidence on vertex indices.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace citylod::test {

struct CjSeq {
  nlohmann::json header;
  std::vector<nlohmann::json> features;
};

inline CjSeq read_cjseq(const std::string& path) {
  CjSeq s;
  std::ifstream f(path);
  std::string line;
  bool first = true;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    if (first)
      s.header = nlohmann::json::parse(line);
    else
      s.features.push_back(nlohmann::json::parse(line));
    first = false;
  }
  return s;
}

/// Solid validity on the polygons of one shell set (vertex indices).
struct SolidCheck {
  bool closed_oriented = false;  ///< every directed edge once, its reverse once
  int pinched = 0;               ///< vertices whose faces form several fans
  double volume = 0;             ///< signed (outward shells: > 0)
  bool valid() const { return closed_oriented && pinched == 0 && volume > 0; }
};

inline SolidCheck check_solid(const nlohmann::json& boundaries,
                              const std::vector<std::array<double, 3>>& v) {
  SolidCheck c;
  std::map<std::pair<long, long>, int> directed;
  std::vector<std::vector<long>> rings;
  for (const auto& shell : boundaries)
    for (const auto& surface : shell)
      for (std::size_t r = 0; r < surface.size(); ++r) {
        std::vector<long> ring;
        for (const auto& i : surface[r]) ring.push_back(i.get<long>());
        rings.push_back(ring);
      }
  for (const auto& ring : rings)
    for (std::size_t i = 0; i < ring.size(); ++i)
      ++directed[{ring[i], ring[(i + 1) % ring.size()]}];
  c.closed_oriented = true;
  for (const auto& [e, n] : directed) {
    const auto r = directed.find({e.second, e.first});
    if (n != 1 || r == directed.end() || r->second != 1) c.closed_oriented = false;
  }
  // pinched: faces around a vertex connected through edges at that vertex
  std::map<long, std::vector<std::size_t>> faces_of;
  for (std::size_t f = 0; f < rings.size(); ++f)
    for (long i : std::set<long>(rings[f].begin(), rings[f].end())) faces_of[i].push_back(f);
  for (const auto& [vtx, fs] : faces_of) {
    std::map<long, std::vector<std::size_t>> by_neighbour;  // other end of an edge at vtx
    for (std::size_t f : fs) {
      const auto& r = rings[f];
      for (std::size_t i = 0; i < r.size(); ++i) {
        if (r[i] != vtx) continue;
        by_neighbour[r[(i + 1) % r.size()]].push_back(f);
        by_neighbour[r[(i + r.size() - 1) % r.size()]].push_back(f);
      }
    }
    std::map<std::size_t, std::size_t> parent;
    for (std::size_t f : fs) parent[f] = f;
    std::function<std::size_t(std::size_t)> find = [&](std::size_t x) {
      return parent[x] == x ? x : parent[x] = find(parent[x]);
    };
    for (const auto& [n, list] : by_neighbour)
      for (std::size_t k = 1; k < list.size(); ++k) parent[find(list[k])] = find(list[0]);
    std::set<std::size_t> roots;
    for (std::size_t f : fs) roots.insert(find(f));
    if (roots.size() > 1) ++c.pinched;
  }
  // volume: fan triangles of each ring around its first vertex (planar rings)
  for (const auto& ring : rings)
    for (std::size_t i = 1; i + 1 < ring.size(); ++i) {
      const auto &a = v[size_t(ring[0])], &b = v[size_t(ring[i])], &d = v[size_t(ring[i + 1])];
      c.volume += (a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) +
                   a[2] * (b[0] * d[1] - b[1] * d[0])) /
                  6;
    }
  return c;
}

/// The vertices of a feature with the header's transform applied.
inline std::vector<std::array<double, 3>> feature_vertices(const nlohmann::json& header,
                                                           const nlohmann::json& feature,
                                                           bool relative = false) {
  std::vector<std::array<double, 3>> out;
  const auto& s = header["transform"]["scale"];
  const auto& t = header["transform"]["translate"];
  for (const auto& p : feature["vertices"]) {
    std::array<double, 3> x;
    for (int k = 0; k < 3; ++k)
      x[size_t(k)] = p[size_t(k)].get<long long>() * s[size_t(k)].get<double>() +
                     (relative ? 0.0 : t[size_t(k)].get<double>());
    out.push_back(x);
  }
  return out;
}

/// The whole LOD chain of one citylod feature, coarse to fine: the Building's
/// geometries and those of its "+LodTreeModel" objects (docs/cityjson.md), by
/// step, each as (geometry, its citylod model entry).
inline std::vector<std::pair<nlohmann::json, nlohmann::json>> feature_chain(
    const nlohmann::json& f) {
  std::map<int, std::pair<nlohmann::json, nlohmann::json>> by_step;
  const auto& b = f["CityObjects"][f["id"].get<std::string>()];
  for (std::size_t g = 0; g < b["geometry"].size(); ++g) {
    const auto& m = b["attributes"]["citylod_models"][g];
    by_step[m["step"].get<int>()] = {b["geometry"][g], m};
  }
  for (const auto& [id, o] : f["CityObjects"].items())
    if (o["type"] == "+LodTreeModel" && !o["geometry"].empty()) {
      const auto& m = o["attributes"]["citylod_model"];
      by_step[m["step"].get<int>()] = {o["geometry"][0], m};
    }
  std::vector<std::pair<nlohmann::json, nlohmann::json>> out;
  for (auto& [step, gm] : by_step) out.push_back(gm);
  return out;
}

/// Problems of a feature's chain objects: each "+LodTreeModel" names its
/// Building, has one geometry and the id "<building>-lodtree-<step>".
inline std::vector<std::string> chain_problems(const nlohmann::json& f) {
  std::vector<std::string> p;
  const std::string fid = f["id"].get<std::string>();
  for (const auto& [id, o] : f["CityObjects"].items()) {
    if (o["type"] != "+LodTreeModel") continue;
    if (o["attributes"]["citylod_building"] != fid) p.push_back(id + ": not of building " + fid);
    if (o["geometry"].size() != 1u) p.push_back(id + ": not one geometry");
    const auto& m = o["attributes"]["citylod_model"];
    if (!m.contains("step") || id != fid + "-lodtree-" + std::to_string(m["step"].get<int>()))
      p.push_back(id + ": id is not <building>-lodtree-<step>");
  }
  return p;
}

/// check_solid of a Solid geometry, or of each Solid of a MultiSolid (valid
/// when every one is: volume their sum, or the smallest when one is not positive).
inline SolidCheck check_geometry(const nlohmann::json& g,
                                 const std::vector<std::array<double, 3>>& v) {
  if (g.value("type", "") != "MultiSolid") return check_solid(g["boundaries"], v);
  SolidCheck all;
  all.closed_oriented = true;
  double least = std::numeric_limits<double>::infinity();
  for (const auto& solid : g["boundaries"]) {
    const SolidCheck c = check_solid(solid, v);
    all.closed_oriented = all.closed_oriented && c.closed_oriented;
    all.pinched += c.pinched;
    all.volume += c.volume;
    least = std::min(least, c.volume);
  }
  if (!(least > 0)) all.volume = least;
  return all;
}

/// Structure problems of one Solid's boundaries (shells/surfaces/rings over
/// `nv` vertices) and semantic values (`vals`, may be null) into `p`.
inline void solid_problems(const nlohmann::json& b, const nlohmann::json* vals,
                           const nlohmann::json& surfaces, long nv, const std::string& where,
                           std::vector<std::string>& p) {
  bool depth_ok = b.is_array() && !b.empty();
  for (const auto& shell : b)
    for (const auto& surf : shell) {
      depth_ok = depth_ok && surf.is_array() && !surf.empty();
      for (const auto& ring : surf) {
        depth_ok = depth_ok && ring.is_array() && ring.size() >= 3;
        for (const auto& i : ring)
          if (!i.is_number_integer() || i.get<long>() < 0 || i.get<long>() >= nv) {
            p.push_back(where + ": index out of range or not an integer");
            depth_ok = false;
            break;
          }
      }
    }
  if (!depth_ok) p.push_back(where + ": Solid boundaries are not shells/surfaces/rings");
  if (!vals) return;
  bool aligned = vals->is_array() && vals->size() == b.size();
  for (std::size_t k = 0; aligned && k < b.size(); ++k) {
    const nlohmann::json& sv = (*vals)[k];
    aligned = sv.is_array() && sv.size() == b[k].size();
    for (std::size_t j = 0; aligned && j < sv.size(); ++j)
      aligned = sv[j].is_null() || (sv[j].is_number_integer() && sv[j].get<long>() >= 0 &&
                                    sv[j].get<long>() < long(surfaces.size()));
  }
  if (!aligned) p.push_back(where + ": semantics.values not aligned with boundaries");
}

/// Structure problems of a CityJSONSeq by the CityJSON 2.0 rules that apply to
/// citylod's output (empty = none).
inline std::vector<std::string> cjseq_problems(const CjSeq& s) {
  std::vector<std::string> p;
  const auto& h = s.header;
  if (h.value("type", "") != "CityJSON") p.push_back("header: type is not CityJSON");
  if (h.value("version", "") != "2.0") p.push_back("header: version is not \"2.0\"");
  if (!h.contains("CityObjects") || !h["CityObjects"].is_object() || !h["CityObjects"].empty())
    p.push_back("header: CityObjects must be an empty object in a CityJSONSeq");
  if (!h.contains("vertices") || !h["vertices"].is_array() || !h["vertices"].empty())
    p.push_back("header: vertices must be an empty array in a CityJSONSeq");
  if (!h.contains("transform") || h["transform"]["scale"].size() != 3 ||
      h["transform"]["translate"].size() != 3)
    p.push_back("header: transform needs scale[3] and translate[3]");
  if (h.contains("metadata") && h["metadata"].contains("referenceSystem") &&
      !std::regex_search(h["metadata"]["referenceSystem"].get<std::string>(),
                         std::regex("^https?://www\\.opengis\\.net/def/crs/")))
    p.push_back("header: referenceSystem is not an OGC CRS URL");
  static const std::set<std::string> kSurfaces = {
      "RoofSurface",       "WallSurface",         "GroundSurface", "ClosureSurface",
      "OuterFloorSurface", "OuterCeilingSurface", "Window",        "Door"};
  const std::regex lod_re("^\\d(\\.\\d)?$");
  std::set<std::string> ids;
  for (std::size_t n = 0; n < s.features.size(); ++n) {
    const auto& f = s.features[n];
    const std::string where = "feature " + std::to_string(n + 1);
    if (f.value("type", "") != "CityJSONFeature") p.push_back(where + ": type");
    const std::string id = f.value("id", "");
    if (id.empty() || !f["CityObjects"].contains(id))
      p.push_back(where + ": id is not one of its CityObjects");
    if (!ids.insert(id).second) p.push_back(where + ": id repeats: " + id);
    const long nv = long(f["vertices"].size());
    for (const auto& v : f["vertices"])
      if (!v.is_array() || v.size() != 3 || !v[0].is_number_integer() ||
          !v[1].is_number_integer() || !v[2].is_number_integer()) {
        p.push_back(where + ": a vertex is not 3 integers");
        break;
      }
    for (const auto& [oid, o] : f["CityObjects"].items()) {
      if (!o.contains("type")) p.push_back(where + ": CityObject " + oid + " without type");
      if (!o.contains("geometry")) continue;
      const std::string type = o.value("type", "");
      if (!type.empty() && type[0] == '+' && !h.contains("extensions"))
        p.push_back(where + ": Extension type " + type + " without header extensions");
      std::set<std::string> lods;  // validators read two of one lod as overlapping parts
      for (const auto& g : o["geometry"])
        if (g.contains("lod") && g["lod"].is_string() &&
            !lods.insert(g["lod"].get<std::string>()).second)
          p.push_back(where + ": CityObject " + oid + " has two geometries of lod " +
                      g["lod"].get<std::string>());
      for (const auto& g : o["geometry"]) {
        const std::string gtype = g.value("type", "");
        if (gtype != "Solid" && gtype != "MultiSolid") {
          p.push_back(where + ": geometry is neither a Solid nor a MultiSolid");
          continue;
        }
        if (!g.contains("lod") || !g["lod"].is_string() ||
            !std::regex_match(g["lod"].get<std::string>(), lod_re))
          p.push_back(where + ": lod missing or not \"d\" / \"d.d\"");
        const auto& b = g["boundaries"];
        const nlohmann::json* vals = g.contains("semantics") ? &g["semantics"]["values"] : nullptr;
        const nlohmann::json no_surfaces = nlohmann::json::array();
        const nlohmann::json& surfaces = vals ? g["semantics"]["surfaces"] : no_surfaces;
        if (gtype == "Solid") {
          solid_problems(b, vals, surfaces, nv, where, p);
        } else if (!b.is_array() || b.size() < 2 || (vals && vals->size() != b.size())) {
          p.push_back(where + ": MultiSolid boundaries are not solids (two or more)");
        } else {
          for (std::size_t k = 0; k < b.size(); ++k)
            solid_problems(b[k], vals ? &(*vals)[k] : nullptr, surfaces, nv, where, p);
        }
        if (g.contains("semantics")) {
          const auto& sem = g["semantics"];
          for (const auto& su : sem["surfaces"])
            if (!kSurfaces.count(su.value("type", "")))
              p.push_back(where + ": semantic surface type " + su.value("type", ""));
        }
      }
    }
  }
  return p;
}

}  // namespace citylod::test
