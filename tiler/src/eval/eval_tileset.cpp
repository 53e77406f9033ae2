// `citylod eval TILESET [--work WORK]`: what a tileset holds, per tile depth and
// per building mesh (see citylod/tiler/eval.hpp).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <tuple>

#include <nlohmann/json.hpp>

#include "citylod/geo/local_frame.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/glb_reader.hpp"
#include "citylod/io/json_file.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/lod/validity.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/eval.hpp"
#include "citylod/tiler/scene_georef.hpp"
#include "citylod/tiler/threads.hpp"
#include "citylod/tiler/workdir.hpp"
#include "eval/tileset_walk.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using Mat4 = TilesetWalk::Mat4;
using io::Vec3d;

namespace {

/// One building's triangles in one glb.
struct Group {
  std::string building;
  int model_index = -1, step = -1;
  std::optional<ModelKind> kind;
  io::TriangleMesh
      mesh;  // content frame, z-up (node transforms and the y-up -> z-up rotation applied)
};

/// glTF y-up -> 3D Tiles z-up: (x, y, z) -> (x, -z, y).
Vec3d to_zup(const Vec3d& p) {
  return {p[0], -p[2], p[1]};
}

/// Splits a glb's triangles by building; vertices with the same stored
/// position in the same node are welded (the writer splits them per face normal).
std::vector<Group> read_groups(const TilesetWalk::Content& c) {
  const io::GlbDocument d = io::read_glb(c.file);
  struct Building {
    Group g;
    std::map<std::tuple<int, double, double, double>, std::uint32_t>
        weld;  // node, stored position -> vertex
  };
  std::map<std::string, Building> groups;
  for (const auto& p : d.primitives) {
    const io::GlbPropertyTable* table =
        p.property_table >= 0 ? &d.property_tables[std::size_t(p.property_table)] : nullptr;
    std::map<std::int64_t, Building*> by_feature;  // of this primitive
    for (const auto& t : p.triangles) {
      const std::int64_t f = p.feature_ids.empty() ? -1 : p.feature_ids[t[0]];
      auto found = by_feature.find(f);
      if (found == by_feature.end()) {
        std::string id = f >= 0 ? "feature-" + std::to_string(f) : "(no feature id)";
        int model_index = -1, step = -1;
        std::optional<ModelKind> kind;
        if (table && f >= 0 && std::size_t(f) < table->count) {
          const auto s = table->strings.find("building_id");
          if (s != table->strings.end()) id = s->second[std::size_t(f)];
          const auto mi = table->numbers.find("model_index");
          if (mi != table->numbers.end()) model_index = int(mi->second[std::size_t(f)]);
          const auto st = table->numbers.find("step");
          if (st != table->numbers.end()) step = int(st->second[std::size_t(f)]);
          const auto k = table->strings.find("lod_kind");
          if (k != table->strings.end()) try {
              kind = model_kind_from_string(k->second[std::size_t(f)]);
            } catch (const std::invalid_argument&) {  // not one of ours: no kind
            }
        }
        auto [it, fresh] = groups.try_emplace(id);
        if (fresh) {
          it->second.g.building = id;
          it->second.g.model_index = model_index;
          it->second.g.step = step;
          it->second.g.kind = kind;
        }
        found = by_feature.emplace(f, &it->second).first;
      }
      Building& b = *found->second;
      std::array<std::uint32_t, 3> tri;
      for (int k = 0; k < 3; ++k) {
        const Vec3d& v = p.positions[t[std::size_t(k)]];
        const auto [w, added] =
            b.weld.try_emplace({p.node, v[0], v[1], v[2]}, std::uint32_t(b.g.mesh.vertices.size()));
        if (added) b.g.mesh.vertices.push_back(to_zup(io::transform_point(p.matrix, v)));
        tri[std::size_t(k)] = w->second;
      }
      b.g.mesh.triangles.push_back(tri);
    }
  }
  std::vector<Group> out;
  for (auto& [id, b] : groups) out.push_back(std::move(b.g));
  return out;
}

/// What the meshes are compared with: the work directory's manifest (scene frame, chunk
/// origins); empty without a work directory.
struct References {
  Manifest man;
  std::map<std::string, const ChunkRecord*> chunks;  ///< into man.chunks
  std::unique_ptr<geo::LocalFrame> frame;
  std::unique_ptr<SceneGeoref> georef;  ///< ENU -> scene frame
};

void read_references(const std::string& work_dir, References& ref) {
  if (work_dir.empty()) return;
  if (!fs::is_directory(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  ref.man = read_manifest(work_dir);
  for (const auto& c : ref.man.chunks) ref.chunks[c.id] = &c;
  require_valid_origin(ref.man, work_dir);
  const auto& sc = ref.man.scene;
  ref.frame =
      std::make_unique<geo::LocalFrame>(geo::LonLatH(sc.origin_lon, sc.origin_lat, sc.origin_h));
  ref.georef = std::make_unique<SceneGeoref>(ref.man, work_dir);
}

/// Every glb's groups (parallel over contents); the first error in tree order is thrown.
std::vector<std::vector<Group>> read_all_groups(const TilesetWalk& w, int threads,
                                                const ProgressFn& progress) {
  std::vector<std::vector<Group>> groups(w.contents.size());
  std::vector<std::string> errors(w.contents.size());
  {
    std::mutex mutex;
    std::size_t done = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (long i = 0; i < long(w.contents.size()); ++i) {
      try {
        groups[size_t(i)] = read_groups(w.contents[size_t(i)]);
      } catch (const std::exception& e) {
        errors[size_t(i)] = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      notify_count(progress, "reading tiles", ++done, w.contents.size(), "tiles");
    }
    notify_finished(progress, "reading tiles");
  }
  for (const auto& e : errors)
    if (!e.empty()) throw std::runtime_error(e);  // the first in tree order
  return groups;
}

/// A group of a content.
struct Row {
  std::size_t content, group;
};

/// r.contents, and r.meshes: one row per group, sorted by level, building, tile order.
/// Returns the rows (r.meshes' order) and fills `by_building` (row indices).
std::vector<Row> tabulate(const TilesetWalk& w, const std::vector<std::vector<Group>>& groups,
                          const References& ref, const std::string& work_dir, TilesetEval& r,
                          std::map<std::string, std::vector<std::size_t>>& by_building) {
  std::vector<Row> rows;
  for (std::size_t c = 0; c < groups.size(); ++c) {
    TileInfo ti;
    ti.uri = w.contents[c].rel;
    ti.level = w.contents[c].level;
    ti.geometric_error = w.contents[c].error;
    ti.buildings = groups[c].size();
    for (std::size_t g = 0; g < groups[c].size(); ++g) {
      ti.triangles += groups[c][g].mesh.triangles.size();
      rows.push_back({c, g});
    }
    r.contents.push_back(ti);
  }
  std::stable_sort(rows.begin(), rows.end(), [&](const Row& a, const Row& b) {
    const int la = w.contents[a.content].level, lb = w.contents[b.content].level;
    if (la != lb) return la < lb;
    return groups[a.content][a.group].building < groups[b.content][b.group].building;
  });
  r.meshes.resize(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Group& g = groups[rows[i].content][rows[i].group];
    TileMeshEval& m = r.meshes[i];
    m.building = g.building;
    m.level = w.contents[rows[i].content].level;
    m.tile = w.contents[rows[i].content].rel;
    m.model_index = g.model_index;
    m.step = g.step;
    m.kind = g.kind;
    m.triangles = g.mesh.triangles.size();
    m.vertices = g.mesh.vertices.size();
    by_building[g.building].push_back(i);
    if (ref.frame && !ref.chunks.count(g.building))
      throw io::IoError(
          manifest_path(work_dir),
          "building '" + g.building + "' of " + m.tile +
              " is not in the manifest (was the tileset assembled from this work directory?)");
  }
  return rows;
}

/// One mesh against its building's chunk `ref` (loaded from `rec`), or, without a work
/// directory (`ref` null), its checks alone. Validity as val3dity would judge it at its
/// tolerances (content frame: metres).
void evaluate_mesh(const Group& g, const Mat4& t, const References& refs, const ChunkRecord* rec,
                   const LoadedBuilding* ref, const EvalOptions& o, TileMeshEval& m) {
  {
    const lod::TriangleMesh lm = to_lod_mesh(g.mesh, [](const Vec3d& v) { return v; });
    std::vector<std::vector<int>> faces;
    for (const auto& tr : lm.triangles) faces.push_back({tr[0], tr[1], tr[2]});
    m.val3dity_error = lod::check_solid(lod::make_solid(lm.vertices, faces)).error;
  }
  if (!ref) {
    const lod::TriangleMesh lm = to_lod_mesh(g.mesh, [](const Vec3d& v) { return v; });
    m.check = lod::check_mesh(lm);
    m.volume = lod::mesh_volume(lm);
    return;
  }
  // content frame -> tileset world (ECEF) -> scene ENU -> chunk frame -> reference's local
  // frame
  const Vec3d& co = rec->origin;
  const Vec3d& ro = ref->origin;
  io::TriangleMesh scene = g.mesh;
  for (auto& v : scene.vertices) {
    const Vec3d world = io::transform_point(t, v);
    const Eigen::Vector3d enu =
        refs.frame->ecef_to_enu(Eigen::Vector3d(world[0], world[1], world[2]));
    v = {enu.x(), enu.y(), enu.z()};
  }
  if (!scene.vertices.empty())
    refs.georef->from_enu(Eigen::Map<Eigen::Matrix3Xd>(scene.vertices[0].data(), 3,
                                                       Eigen::Index(scene.vertices.size())));
  const lod::TriangleMesh lm = to_lod_mesh(scene, [&](const Vec3d& v) {
    return Vec3d{v[0] - co[0] - ro[0], v[1] - co[1] - ro[1], v[2] - co[2] - ro[2]};
  });
  const lod::ModelEvaluation e = lod::evaluate_model(lm, ref->input, o.samples);
  m.check = e.check;
  m.volume = e.volume;
  m.evaluated = true;
  m.e1 = e.e1;
  m.e2 = e.e2;
  m.hausdorff = e.hausdorff;
}

/// Per building (parallel): validity, and e1/e2 against its chunk; the first error in
/// id order is thrown.
void evaluate_buildings(const TilesetWalk& w, const std::vector<std::vector<Group>>& groups,
                        const std::vector<Row>& rows,
                        const std::map<std::string, std::vector<std::size_t>>& by_building,
                        const References& refs, const std::string& work_dir, const EvalOptions& o,
                        int threads, const ProgressFn& progress, TilesetEval& r) {
  std::vector<std::string> ids;
  for (const auto& [id, v] : by_building) ids.push_back(id);
  std::vector<std::string> berrors(ids.size());
  {
    std::mutex mutex;
    std::size_t done = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (long k = 0; k < long(ids.size()); ++k) {
      const std::string& id = ids[size_t(k)];
      try {
        std::unique_ptr<LoadedBuilding> ref;
        const ChunkRecord* rec = nullptr;
        if (refs.frame) {
          rec = refs.chunks.at(id);
          const std::string chunk = chunk_path(work_dir, id);
          if (!fs::exists(chunk))
            throw io::IoError(chunk, "chunk of building '" + id + "' is missing");
          ref = std::make_unique<LoadedBuilding>(load_building(chunk));
          if (ref->input.points.empty())
            throw io::IoError(chunk, "chunk of building '" + id + "' is empty");
        }
        for (std::size_t i : by_building.at(id))
          evaluate_mesh(groups[rows[i].content][rows[i].group],
                        w.contents[rows[i].content].transform, refs, rec, ref.get(), o,
                        r.meshes[i]);
      } catch (const std::exception& e) {
        berrors[size_t(k)] = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      notify_count(progress, "eval", ++done, ids.size(), "buildings");
    }
    notify_finished(progress, "eval");
  }
  for (const auto& e : berrors)
    if (!e.empty()) throw std::runtime_error(e);  // the first in id order
}

/// r.levels: per level, its tiles, meshes, buildings, checks and mean / max errors.
void summarise_levels(TilesetEval& r) {
  std::map<int, LevelSummary> levels;
  std::map<int, std::set<std::string>> level_buildings;
  for (const auto& c : r.contents) {
    LevelSummary& l = levels[c.level];
    l.level = c.level;
    ++l.tiles;
  }
  for (const auto& m : r.meshes) {
    LevelSummary& l = levels[m.level];
    ++l.meshes;
    level_buildings[m.level].insert(m.building);
    l.triangles += m.triangles;
    l.closed += m.check.closed;
    l.edge_manifold += m.check.edge_manifold;
    l.self_intersecting += m.check.self_intersecting;
    l.pinched += m.check.pinched_vertices > 0;
    l.not_one_shell += m.check.shells != 1;
    l.valid += m.check.valid();
    l.valid_tolerant += m.val3dity_error == 0;
    if (m.evaluated) {
      ++l.evaluated;
      l.mean_e1 += m.e1;
      l.mean_e2 += m.e2;
      if (l.max_e2_building.empty() || m.e2 > l.max_e2) {
        l.max_e2 = m.e2;
        l.max_e2_building = m.building;
      }
    }
  }
  for (auto& [level, l] : levels) {
    l.buildings = level_buildings[level].size();
    if (l.evaluated) {
      l.mean_e1 /= double(l.evaluated);
      l.mean_e2 /= double(l.evaluated);
    }
    r.levels.push_back(l);
  }
}

}  // namespace

TilesetEval evaluate_tileset(const std::string& path, const std::string& work_dir,
                             const EvalOptions& o, const ProgressFn& progress) {
  TilesetEval r;
  r.samples = o.samples;
  r.work = work_dir;
  fs::path ts = path;
  if (fs::is_directory(ts)) ts = tileset_json_path(ts.string());
  r.tileset = ts.string();
  const TilesetWalk w = walk_tileset(ts.string());
  r.tiles = w.tiles;
  r.depth = w.depth;
  if (w.contents.empty()) throw io::IoError(r.tileset, "the tileset has no glb content");

  References refs;  // the manifest (scene frame, chunk origins)
  read_references(work_dir, refs);
  const int threads = resolve_threads(o.threads);
  // ---- 1. read every glb (parallel over contents)
  const std::vector<std::vector<Group>> groups = read_all_groups(w, threads, progress);
  // ---- 2. rows, sorted by level, building, tile order
  std::map<std::string, std::vector<std::size_t>> by_building;  // row indices
  const std::vector<Row> rows = tabulate(w, groups, refs, work_dir, r, by_building);
  // ---- 3. per building (parallel): validity, and e1/e2 against its chunk
  evaluate_buildings(w, groups, rows, by_building, refs, work_dir, o, threads, progress, r);
  // ---- 4. per level
  summarise_levels(r);
  return r;
}

}  // namespace citylod::tiler
