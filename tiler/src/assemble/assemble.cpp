// `citylod assemble`: work directory -> hierarchical 3D Tiles 1.1 tileset.
// Reads top to bottom: load buildings, build the tile tree, write the files.
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/option_names.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include <omp.h>
#include <nlohmann/json.hpp>

#include "citylod/geo/local_frame.hpp"
#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/gltf.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/tileset.hpp"
#include "citylod/io/weld.hpp"
#include "citylod/lod/polygon2d.hpp"
#include "citylod/lod/validity.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/scene_georef.hpp"
#include "citylod/tiler/threads.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using io::BBox3;
using io::Vec3d;

namespace {

/// Bytes of welded models kept in memory from reading to writing the glbs
/// (~4.5 M triangles; the 8x8 replica of the Delft tile needs ~20 MB). Past
/// it, the writers read and weld a model again: the same bytes either way.
constexpr std::size_t kModelCacheBytes = std::size_t(128) << 20;

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// ------------------------------------------------------------ buildings
struct KeptModel {
  std::string file;                // PLY path
  std::vector<io::Rgba8> colours;  // per PLY triangle (report.json), or empty
  lod::ModelKind kind = lod::ModelKind::anchor;
  int level = 0, step = 0;
  double error_m = 0, hausdorff_m = 0, height_m = 0;
  double rmse_m = -1;  // of the input points (report.json e2), -1 = not measured
  bool valid = false;  // a valid solid as the tiles store it (welded for validators)
  BBox3 bbox;          // scene ENU
  std::size_t triangles = 0, bytes = 0;
  std::size_t plain_bytes = 0;  // float32 estimate: the same whatever the compression
  /// The model as the glbs store it (read_model's result), kept from reading
  /// while the cache's budget lasts; else the glb writers read it again.
  std::shared_ptr<const std::pair<io::TriangleMesh, std::vector<io::Rgba8>>> ready;
};

struct Building {
  std::string id;
  std::string file_stem;  // safe file name for buildings/<stem>.glb
  Vec3d origin{0, 0, 0};  // chunk origin, scene ENU
  double footprint_area_m2 = 0;
  Vec3d centre{0, 0, 0};          // of the finest model's bbox
  std::vector<KeptModel> models;  // coarse -> fine
  std::size_t models_read = 0;
  BBox3 bbox;               // all kept models
  double error_none_m = 0;  // error of showing nothing: > error of the coarsest model
  nlohmann::json attributes = nlohmann::json::object();  // its footprint's (manifest)
  ModelChoice chain;  // the kept models as indices into its report's models
};

std::string safe_stem(const std::string& id) {
  bool ok = !id.empty() && id.size() <= 100 && id[0] != '.';
  for (char c : id)
    ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                c == '-' || c == '_' || c == '.');
  return ok ? id : "id-" + io::hash_hex(id.data(), id.size());
}

/// Footprint of a closed model: projected area of its downward faces (of its
/// upward faces if it has no floor).
double projected_area(const io::TriangleMesh& m) {
  double down = 0, up = 0;
  for (const auto& t : m.triangles) {
    const Vec3d &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
    const double z = ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / 2;
    (z < 0 ? down : up) += std::fabs(z);
  }
  return down > 0 ? down : up;
}

/// A model in the scene frame: its file's coordinates + the chunk origin.
io::TriangleMesh read_scene_model(const std::string& file, const Vec3d& origin) {
  io::TriangleMesh m = read_model_file(file);
  for (auto& v : m.vertices)
    for (int k = 0; k < 3; ++k) v[size_t(k)] += origin[size_t(k)];
  return m;
}

/// A scene-frame mesh in the tiles' frame: ENU at the scene origin (the earth's
/// curvature and the geoid enter here for a projected scene frame).
io::TriangleMesh to_enu(io::TriangleMesh m, const SceneGeoref& georef) {
  if (georef.projected() && !m.vertices.empty())
    georef.to_enu(
        Eigen::Map<Eigen::Matrix3Xd>(m.vertices[0].data(), 3, Eigen::Index(m.vertices.size())));
  return m;
}

/// The triangles as lod::check_solid reads them (shells by lod::make_solid).
lod::SolidCheck check_for_validators(const io::TriangleMesh& m) {
  std::vector<lod::Vec3> v;
  v.reserve(m.vertices.size());
  for (const auto& p : m.vertices) v.emplace_back(p[0], p[1], p[2]);
  std::vector<std::vector<int>> faces;
  faces.reserve(m.triangles.size());
  for (const auto& t : m.triangles) faces.push_back({int(t[0]), int(t[1]), int(t[2])});
  return lod::check_solid(lod::make_solid(std::move(v), faces));
}

/// A model as validators read it at their tolerances (val3dity: snap 1 mm;
/// docs/3dtiles.md "Validity"): its vertices on a 0.1 mm grid, those within r
/// of each other (per axis, transitively; r = 1.1 mm, then 2.2, 4.4, 8.8) one
/// vertex (at the position of the cluster's first), collapsed triangles,
/// zero-volume fins and collinear spikes gone (io/weld.hpp); the first r that
/// lod::check_solid accepts. A model that is valid as it is, or that no r makes
/// valid, is returned unchanged. source[i] = the input triangle of output
/// triangle i; `valid`: whether the result is valid for validators.
io::TriangleMesh weld_for_validators(const io::TriangleMesh& m, std::vector<std::size_t>& source,
                                     bool& valid) {
  source.resize(m.triangles.size());
  std::iota(source.begin(), source.end(), std::size_t(0));
  constexpr double kGrid = 1e-4;  // metres
  const lod::Tolerances tol;
  valid = false;
  if (m.triangles.empty()) return m;
  if (check_for_validators(m).valid()) {
    valid = true;
    return m;
  }
  std::vector<std::array<std::int64_t, 3>> q;
  q.reserve(m.vertices.size());
  for (const auto& p : m.vertices)
    q.push_back(
        {std::llround(p[0] / kGrid), std::llround(p[1] / kGrid), std::llround(p[2] / kGrid)});
  std::vector<std::uint32_t> rank(q.size());
  std::iota(rank.begin(), rank.end(), 0u);
  for (const double factor : {1.1, 2.2, 4.4, 8.8}) {
    const auto r = std::uint32_t(std::ceil(factor * tol.snap / kGrid));
    const std::vector<std::uint32_t> root = io::weld(io::near_pairs(q, r), r, rank);
    std::vector<std::array<std::uint32_t, 3>> welded;
    for (const auto& t : m.triangles) welded.push_back({root[t[0]], root[t[1]], root[t[2]]});
    std::vector<std::size_t> from;
    std::vector<std::vector<std::uint32_t>> faces;
    for (const auto& t : io::drop_collapsed_and_fins(welded, from))
      faces.push_back({t[0], t[1], t[2]});
    const std::vector<std::size_t> kept_faces = io::remove_collinear_spikes(faces, q);
    io::TriangleMesh out;
    out.vertices = m.vertices;
    std::vector<std::size_t> out_source;
    bool ok = true;
    for (std::size_t fi = 0; fi < faces.size(); ++fi) {
      const auto& f = faces[fi];
      // a face that took a vertex on an edge: a fan from an apex that gives no
      // triangle on a line
      bool fanned = false;
      for (std::size_t a = 0; a < f.size() && !fanned; ++a) {
        std::vector<std::array<std::uint32_t, 3>> fan;
        bool flat = false;
        for (std::size_t k = 1; k + 1 < f.size() && !flat; ++k) {
          const std::array<std::uint32_t, 3> t{f[a], f[(a + k) % f.size()],
                                               f[(a + k + 1) % f.size()]};
          const auto &p0 = q[t[0]], &p1 = q[t[1]], &p2 = q[t[2]];
          const __int128 u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
          const __int128 w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
          flat = u[1] * w[2] == u[2] * w[1] && u[2] * w[0] == u[0] * w[2] &&
                 u[0] * w[1] == u[1] * w[0];
          fan.push_back(t);
        }
        if (flat) continue;
        out.triangles.insert(out.triangles.end(), fan.begin(), fan.end());
        out_source.insert(out_source.end(), fan.size(), from[kept_faces[fi]]);
        fanned = true;
      }
      ok = ok && fanned;
    }
    if (!ok || !check_for_validators(out).valid()) continue;
    // only the vertices the triangles use
    std::vector<std::uint32_t> remap(out.vertices.size(), ~0u);
    io::TriangleMesh compact;
    for (auto& t : out.triangles)
      for (auto& v : t) {
        if (remap[v] == ~0u) {
          remap[v] = std::uint32_t(compact.vertices.size());
          compact.vertices.push_back(out.vertices[v]);
        }
        v = remap[v];
      }
    compact.triangles = std::move(out.triangles);
    source = std::move(out_source);
    valid = true;
    return compact;
  }
  return m;
}

/// A model in the tiles' frame, welded for validators, with its triangles'
/// colours (`colours`: per input triangle, or empty) following it; `valid` (if
/// not null): whether validators read it as a valid solid.
std::pair<io::TriangleMesh, std::vector<io::Rgba8>> welded_model(
    const io::TriangleMesh& enu, const std::vector<io::Rgba8>& colours, bool* valid = nullptr) {
  std::vector<std::size_t> source;
  bool ok = false;
  io::TriangleMesh m = weld_for_validators(enu, source, ok);
  if (valid) *valid = ok;
  std::vector<io::Rgba8> c;
  if (!colours.empty())
    for (const std::size_t t : source)
      c.push_back(t < colours.size() ? colours[t] : io::Rgba8{0, 0, 0, 0});
  return {std::move(m), std::move(c)};
}

std::pair<io::TriangleMesh, std::vector<io::Rgba8>> read_model(
    const std::string& file, const Vec3d& origin, const SceneGeoref& georef,
    const std::vector<io::Rgba8>& colours) {
  return welded_model(to_enu(read_scene_model(file, origin), georef), colours);
}

/// Memory budget of the models kept between reading and writing (KeptModel::ready).
class ModelCache {
 public:
  explicit ModelCache(std::size_t budget) : left_(budget) {}
  /// Claims room for `m`; false once the budget is spent.
  bool take(const io::TriangleMesh& m, std::size_t colours) {
    const std::size_t need = m.vertices.size() * sizeof(Vec3d) +
                             m.triangles.size() * sizeof(m.triangles[0]) +
                             colours * sizeof(io::Rgba8) + 256;
    std::size_t left = left_.load();
    while (left >= need)
      if (left_.compare_exchange_weak(left, left - need)) return true;
    return false;
  }

 private:
  std::atomic<std::size_t> left_;
};

/// The kept model for the glb writers: cached, or read again.
std::pair<io::TriangleMesh, std::vector<io::Rgba8>> kept_model(const KeptModel& km,
                                                               const Vec3d& origin,
                                                               const SceneGeoref& georef) {
  if (km.ready) return *km.ready;
  return read_model(km.file, origin, georef, km.colours);
}

/// Reads one building's report and models and chooses its kept chain.
Building load_building(const std::string& work, const ChunkRecord& rec, const AssembleParams& p,
                       const SceneGeoref& georef, ModelCache& cache) {
  Building b;
  b.id = rec.id;
  b.file_stem = safe_stem(rec.id);
  b.origin = rec.origin;
  b.attributes = rec.attributes;
  // the chain is chosen in the scene frame (as `citylod cityjson` chooses it)
  const BuildingModels bm = read_building_models(
      work, rec.id, [&](const std::string& f) { return read_scene_model(f, rec.origin); });
  const LodReport& rep = bm.report;
  const std::vector<io::TriangleMesh>& meshes = bm.meshes;
  b.models_read = meshes.size();
  const ModelChoice choice = choose_models(rep, meshes, p.min_change_m, p.hausdorff_tolerance_m);
  if (choice.kept.empty())
    throw io::IoError(bm.report_path, "building '" + rec.id + "': every model is empty");
  b.chain = choice;
  for (std::size_t i = 0; i < choice.kept.size(); ++i) {
    const std::size_t k = choice.kept[i];
    const io::TriangleMesh mesh = to_enu(meshes[k], georef);
    KeptModel km;
    const ModelRecord& mr = rep.models[k];
    km.file = bm.files[k];
    km.colours = mr.triangle_colours;
    if (km.colours.size() != mesh.triangles.size()) km.colours.clear();  // a PLY edited since
    km.kind = mr.kind;
    km.level = mr.level;
    km.step = mr.step;
    km.error_m = choice.error_m[i];
    km.hausdorff_m = choice.hausdorff_m[i];
    km.rmse_m = rep.rmse_m(k);
    for (const auto& t : mesh.triangles)
      for (auto v : t) km.bbox.add(mesh.vertices[v]);
    km.height_m = km.bbox.max[2] - km.bbox.min[2];
    const io::GlbMeshSize s =
        io::glb_mesh_size(mesh, p.quantize || p.compression == io::Compression::meshopt);
    km.triangles = s.triangles;
    km.bytes = s.bytes;
    km.plain_bytes = s.float_bytes;
    // as the tiles store it: its validity, and the model itself while the cache lasts
    auto welded = welded_model(mesh, km.colours, &km.valid);
    if (cache.take(mesh, km.colours.size()))
      km.ready = std::make_shared<const std::pair<io::TriangleMesh, std::vector<io::Rgba8>>>(
          std::move(welded));
    b.bbox.add(km.bbox);
    b.models.push_back(std::move(km));
  }
  const io::TriangleMesh finest = to_enu(meshes[choice.kept.back()], georef);
  b.footprint_area_m2 =
      rec.outline.size() >= 3 ? std::fabs(poly2::signed_area(rec.outline)) : projected_area(finest);
  const BBox3& fb = b.models.back().bbox;
  for (int k = 0; k < 3; ++k) b.centre[size_t(k)] = (fb.min[size_t(k)] + fb.max[size_t(k)]) / 2;
  double diag = 0;
  for (int k = 0; k < 3; ++k) diag += std::pow(b.bbox.max[size_t(k)] - b.bbox.min[size_t(k)], 2);
  b.error_none_m = std::max(std::sqrt(diag), b.models.front().error_m + 0.01);
  return b;
}

// ------------------------------------------------------------ tile tree
struct Item {
  std::uint32_t b;  // building
  std::uint32_t m;  // kept model
};

struct TileNode {
  std::string name;  // "r", "r_0", "r_0_3", ...
  std::vector<Item> items;
  double error = 0;
  std::size_t triangles = 0, bytes = 0;
  BBox3 content_box;  // padded, of the shown models
  BBox3 box;          // rounded, contains content and children
  std::vector<std::size_t> children;
};

class TreeBuilder {
 public:
  TreeBuilder(const std::vector<Building>& b, const AssembleParams& p) : bs_(b), p_(p) {}

  std::vector<TileNode> tiles;
  double tileset_error = 0;

  void build() {
    std::vector<Item> first;
    for (std::uint32_t i = 0; i < bs_.size(); ++i) {
      first.push_back({i, 0});
      tileset_error = std::max(tileset_error, bs_[i].error_none_m);
    }
    if (fits(first) && !separate_leaves(first)) {
      make_tile(first, "r");
      return;
    }
    // The coarsest models of all buildings exceed one glb, or enough buildings
    // have a single model (their finest, which a root with content would
    // repeat in its children) for leaves of their own: an empty root over
    // groups of them.
    tiles.emplace_back();
    tiles[0].name = "r";
    tiles[0].error = tileset_error;
    const std::vector<std::vector<Item>> groups = child_groups(first, tileset_error);
    for (std::size_t k = 0; k < groups.size(); ++k) {
      const std::size_t c = make_tile(groups[k], "r_" + std::to_string(k));
      tiles[0].children.push_back(c);
    }
    finish_box(0);
  }

 private:
  const KeptModel& model(const Item& it) const { return bs_[it.b].models[it.m]; }
  /// The item shows its building's finest model.
  bool finished(const Item& it) const { return it.m + 1 == bs_[it.b].models.size(); }

  /// Groups of `next` for the children of a tile of error `error`: buildings
  /// that reach their finest model go to leaf tiles of their own (error 0),
  /// the others to tiles that refine further, so no model is stored twice
  /// down a chain (REPLACE: the children together still show every building).
  /// ... when they total at least AssembleParams::min_leaf_bytes (else they stay
  /// with the refining ones).
  std::vector<std::vector<Item>> child_groups(const std::vector<Item>& next, double error) const {
    std::vector<std::vector<Item>> groups;
    if (!separate_leaves(next)) {
      partition(next, max_extent(error), groups);
      return groups;
    }
    std::vector<Item> refining, done;
    for (const auto& it : next) (finished(it) ? done : refining).push_back(it);
    partition(refining, max_extent(error), groups);
    partition(done, max_extent(error), groups);
    return groups;
  }
  /// `items` mixes refining buildings with enough finished ones for leaves of their own.
  bool separate_leaves(const std::vector<Item>& items) const {
    std::size_t done = 0, bytes = 0;
    for (const auto& it : items)
      if (finished(it)) {
        ++done;
        bytes += model(it).plain_bytes;  // the same tree with or without compression
      }
    return done > 0 && done < items.size() && bytes >= p_.min_leaf_bytes;
  }

  bool fits(const std::vector<Item>& items) const {
    std::size_t t = 0, by = 0;
    for (const auto& it : items) {
      t += model(it).triangles;
      by += model(it).bytes;
    }
    return t <= p_.max_tile_triangles && by <= p_.max_tile_bytes;
  }

  /// Splits by the midpoint of the building centres' xy extent (up to 4
  /// quadrants, SW SE NW NE order); one group when all centres coincide.
  std::vector<std::vector<Item>> quadrants(const std::vector<Item>& items) const {
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const auto& it : items) {
      const Vec3d& c = bs_[it.b].centre;
      x0 = std::min(x0, c[0]);
      x1 = std::max(x1, c[0]);
      y0 = std::min(y0, c[1]);
      y1 = std::max(y1, c[1]);
    }
    std::vector<std::vector<Item>> q(4);
    const double mx = (x0 + x1) / 2, my = (y0 + y1) / 2;
    for (const auto& it : items) {
      const Vec3d& c = bs_[it.b].centre;
      const int k = (x1 - x0 > 1e-6 && c[0] >= mx ? 1 : 0) + (y1 - y0 > 1e-6 && c[1] >= my ? 2 : 0);
      q[size_t(k)].push_back(it);
    }
    std::vector<std::vector<Item>> out;
    for (auto& g : q)
      if (!g.empty()) out.push_back(std::move(g));
    return out;
  }

  /// xy diagonal of the buildings' boxes (all their kept models).
  double extent(const std::vector<Item>& items) const {
    BBox3 b;
    for (const auto& it : items) b.add(bs_[it.b].bbox);
    return std::hypot(b.max[0] - b.min[0], b.max[1] - b.min[1]);
  }

  double max_extent(double error) const {
    return p_.tile_extent_factor > 0 ? std::max(p_.tile_extent_factor * error, p_.min_tile_extent_m)
                                     : std::numeric_limits<double>::infinity();
  }

  /// Groups of `items` for sibling tiles: quadrant splits (repeated) while a
  /// group is over the glb budget or wider than `max_extent`.
  void partition(const std::vector<Item>& items, double max_extent,
                 std::vector<std::vector<Item>>& out) const {
    if (items.empty()) return;
    if (items.size() <= 1 || (fits(items) && extent(items) <= max_extent)) {
      out.push_back(items);
      return;
    }
    std::vector<std::vector<Item>> q = quadrants(items);
    if (q.size() == 1) {
      if (fits(items)) {
        out.push_back(items);
        return;
      }
      // Coincident centres and over budget: halve in id order.
      const auto mid = items.begin() + long(items.size() / 2);
      q = {std::vector<Item>(items.begin(), mid), std::vector<Item>(mid, items.end())};
    }
    for (const auto& g : q) partition(g, max_extent, out);
  }

  std::size_t make_tile(const std::vector<Item>& items, const std::string& name) {
    const std::size_t id = tiles.size();
    tiles.emplace_back();
    {
      TileNode& t = tiles[id];
      t.name = name;
      t.items = items;
      BBox3 exact;
      for (const auto& it : items) {
        const KeptModel& m = model(it);
        t.error = std::max(t.error, m.error_m);
        t.triangles += m.triangles;
        t.bytes += m.bytes;
        exact.add(m.bbox);
      }
      // Room for float32 rounding of positions relative to the tile centre
      // (and for int16 quantization steps).
      double r = 0;
      for (int k = 0; k < 3; ++k) r = std::max(r, exact.max[size_t(k)] - exact.min[size_t(k)]);
      const double pad =
          1e-3 + r * 1e-6 +
          (p_.quantize || p_.compression == io::Compression::meshopt ? 2 * r / 32767 : 0);
      t.content_box = exact;
      for (int k = 0; k < 3; ++k) {
        t.content_box.min[size_t(k)] -= pad;
        t.content_box.max[size_t(k)] += pad;
      }
    }
    if (tiles[id].error > 0) {
      std::vector<Item> next = items;
      for (auto& it : next)
        if (!finished(it)) ++it.m;
      const std::vector<std::vector<Item>> groups = child_groups(next, tiles[id].error);
      for (std::size_t k = 0; k < groups.size(); ++k) {
        const std::size_t c = make_tile(groups[k], name + "_" + std::to_string(k));
        tiles[id].children.push_back(c);
      }
    }
    finish_box(id);
    return id;
  }

  void finish_box(std::size_t id) {
    TileNode& t = tiles[id];
    BBox3 b;
    if (!t.items.empty()) b.add(io::TileBox::from_bbox(t.content_box).to_bbox());
    for (std::size_t c : t.children) b.add(tiles[c].box);
    t.box = io::TileBox::from_bbox(b).to_bbox();
  }

  const std::vector<Building>& bs_;
  const AssembleParams& p_;
};

// ------------------------------------------------------------ output
io::GlbFeature feature_of(const Building& b, std::size_t m) {
  const KeptModel& km = b.models[m];
  io::GlbFeature f;
  f.building_id = b.id;
  f.kind = km.kind;
  f.level = km.level;
  f.step = km.step;
  f.model_index = int(m);
  f.model_count = int(b.models.size());
  f.height_m = km.height_m;
  f.footprint_area_m2 = b.footprint_area_m2;
  f.error_m = km.error_m;
  f.attributes = b.attributes;
  f.rmse_m = km.rmse_m;
  f.valid = km.valid;
  return f;
}

Vec3d rounded_centre(const BBox3& b) {
  Vec3d c;
  for (int k = 0; k < 3; ++k)
    c[size_t(k)] = std::round((b.min[size_t(k)] + b.max[size_t(k)]) / 2 * 100) / 100;
  return c;
}

bool inside(const BBox3& in, const BBox3& out) {
  for (int k = 0; k < 3; ++k)
    if (in.min[size_t(k)] < out.min[size_t(k)] || in.max[size_t(k)] > out.max[size_t(k)])
      return false;
  return true;
}

/// Writes the tile tree as tileset JSON files: the file of a subtree takes its
/// children's subtrees inline while they fit its budget of tiles
/// (`left`, AssembleParams::max_tiles_per_file); a larger one becomes an
/// external tileset, tiles/<name>.json (its own budget), referenced by a tile
/// with the same box and error. `prefix`: path from the file's directory to
/// tiles/ ("tiles/" from tileset.json, "" from an external file).
struct TilesetWriter {
  const std::vector<TileNode>& tiles;
  std::size_t max_tiles;
  std::vector<std::size_t> size;                              // tiles in the subtree of each tile
  std::vector<std::pair<std::string, io::Tileset>> external;  // tiles/<name>.json

  TilesetWriter(const std::vector<TileNode>& t, std::size_t max) : tiles(t), max_tiles(max) {
    size.assign(t.size(), 1);
    for (std::size_t id = t.size(); id-- > 0;)  // a child's id is larger than its parent's
      for (std::size_t c : t[id].children) size[id] += size[c];
  }

  io::Tile tile(std::size_t id, const std::string& prefix, std::size_t& left) {
    const TileNode& n = tiles[id];
    io::Tile t;
    t.box = io::TileBox::from_bbox(n.box);
    t.geometric_error = n.error;
    if (!n.items.empty()) {
      t.content_uri = prefix + n.name + ".glb";
      t.content_box = io::TileBox::from_bbox(n.content_box);
    }
    left = left > 0 ? left - 1 : 0;
    for (std::size_t c : n.children) {
      if (size[c] <= left) {
        t.children.push_back(tile(c, prefix, left));
        continue;
      }
      io::Tile ref;
      ref.box = io::TileBox::from_bbox(tiles[c].box);
      ref.geometric_error = tiles[c].error;
      ref.content_uri = prefix + tiles[c].name + ".json";
      left = left > 0 ? left - 1 : 0;
      std::size_t fresh = max_tiles;
      io::Tileset ext;
      ext.geometric_error = tiles[c].error;
      ext.root = tile(c, "", fresh);
      ext.root.refine = "REPLACE";
      external.emplace_back(tiles[c].name + ".json", std::move(ext));
      t.children.push_back(std::move(ref));
    }
    return t;
  }
};

int tree_depth(const std::vector<TileNode>& tiles, std::size_t id) {
  int d = 0;
  for (std::size_t c : tiles[id].children) d = std::max(d, 1 + tree_depth(tiles, c));
  return d;
}

/// Replaces `out` by the staged directory. Refuses to delete a directory that
/// is not a previous tileset unless `force`.
void check_output_dir(const fs::path& out, bool force) {
  if (fs::exists(tileset_json_path(out.string() + ".old")))
    io::recover_directory(out.string());  // killed mid-swap (file systems without exchange)
  if (!fs::exists(out)) return;
  if (!fs::is_directory(out)) throw io::IoError(out.string(), "exists and is not a directory");
  const bool empty = fs::directory_iterator(out) == fs::directory_iterator();
  if (!empty && !fs::exists(tileset_json_path(out.string())) && !force)
    throw io::IoError(out.string(), "exists and is not a tileset (no tileset.json); use " +
                                        option_name("force") + " to replace it");
}

// ------------------------------------------------------------ the stage's steps
/// Progress of the stage's parallel loops: one report at a time.
class Reporter {
 public:
  explicit Reporter(const ProgressFn& progress) : progress_(progress) {}
  void operator()(double f, const char* stage) const {
    notify_progress(progress_, "assemble", f, stage);
  }
  /// One more of `total` done, in a parallel loop: progress from + span * done / total.
  void step(std::atomic<std::size_t>& done, std::size_t total, double from, double span,
            const char* stage) {
    if (!progress_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    (*this)(from + span * double(++done) / double(total), stage);
  }

 private:
  const ProgressFn& progress_;
  std::mutex mutex_;
};

/// 1. The buildings to model, read in parallel (load_building); a building
/// that fails is an error, or skipped with a warning (skip_missing).
std::vector<Building> read_buildings(const std::string& work_dir, const Manifest& man,
                                     const AssembleParams& params, const SceneGeoref& georef,
                                     Reporter& report, AssembleStats& st) {
  const std::vector<const ChunkRecord*> recs = buildings_to_model(man, work_dir, &st.skipped);
  std::vector<Building> loaded(recs.size());
  std::vector<std::string> errors(recs.size());
  std::atomic<std::size_t> done{0};
  const int nthreads = resolve_threads(params.threads);
  ModelCache cache(kModelCacheBytes);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
  for (long i = 0; i < long(recs.size()); ++i) {
    try {
      loaded[size_t(i)] = load_building(work_dir, *recs[size_t(i)], params, georef, cache);
    } catch (const std::exception& e) {
      errors[size_t(i)] = e.what();
    }
    report.step(done, recs.size(), 0, 0.5, "reading models");
  }
  std::vector<Building> buildings;
  for (std::size_t i = 0; i < recs.size(); ++i) {
    if (!errors[i].empty()) {
      if (!params.skip_missing) throw std::runtime_error(errors[i]);
      st.warnings.push_back("skipped: " + errors[i]);
      ++st.skipped;
      continue;
    }
    st.models_read += loaded[i].models_read;
    st.models_kept += loaded[i].models.size();
    st.chains[loaded[i].id] = loaded[i].chain;
    buildings.push_back(std::move(loaded[i]));
  }
  if (buildings.empty())
    throw io::IoError(work_dir, "no building has LOD models (nothing to assemble)");
  st.buildings = buildings.size();
  return buildings;
}

/// The options of every glb of the tileset.
io::GlbOptions glb_options(const AssembleParams& params, const std::vector<Building>& buildings) {
  io::GlbOptions gopt;
  gopt.quantize = params.quantize;
  {  // footprint attributes: one typed schema for every glb of the tileset
    std::vector<const nlohmann::json*> attrs;
    for (const auto& b : buildings) attrs.push_back(&b.attributes);
    gopt.attributes = io::glb_attribute_schema(attrs);
  }
  gopt.compression = params.compression;
  // quantized models are checked as stored: one that int16 damages is snapped
  // (or kept float) so that every valid model stays a valid solid in the tiles
  gopt.snapped_is_valid = [](const io::TriangleMesh& m) { return check_for_validators(m).valid(); };
  gopt.snap_tolerance_m = lod::Tolerances().snap;
  // One schema for every glb (tiles/ and buildings/ are one level below it).
  gopt.schema_uri = "../schema.json";
  return gopt;
}

/// Runs `write(i)` for i in [0, n) in parallel; the first error (by index)
/// removes the stage and is thrown.
template <typename Write>
void write_in_parallel(std::size_t n, int nthreads, const fs::path& stage, Write write) {
  std::vector<std::string> errors(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
  for (long i = 0; i < long(n); ++i) {
    try {
      write(size_t(i));
    } catch (const std::exception& e) {
      errors[size_t(i)] = e.what();
    }
  }
  for (const auto& e : errors)
    if (!e.empty()) {
      fs::remove_all(stage);
      throw std::runtime_error(e);
    }
}

/// 3a. tiles/<name>.glb of every tile with content; their sizes, the budget
/// warnings.
void write_tiles(const fs::path& stage, const std::vector<TileNode>& tiles,
                 const std::vector<Building>& buildings, const io::GlbOptions& gopt,
                 const SceneGeoref& georef, const AssembleParams& params, Reporter& report,
                 AssembleStats& st) {
  std::vector<std::size_t> glb_size(tiles.size(), 0);
  std::atomic<std::size_t> done{0};
  write_in_parallel(tiles.size(), resolve_threads(params.threads), stage, [&](std::size_t i) {
    const TileNode& t = tiles[i];
    if (t.items.empty()) return;
    io::GlbBuilder g(rounded_centre(t.content_box), gopt);
    for (const auto& it : t.items) {
      const Building& b = buildings[it.b];
      const auto [mesh, colours] = kept_model(b.models[it.m], b.origin, georef);
      g.add_feature(feature_of(b, it.m), mesh, colours);
    }
    if (!inside(g.stored_bounds(), t.content_box))
      throw std::logic_error("tile " + t.name + ": stored positions leave the content box");
    const std::string bytes = g.glb();
    io::atomic_write_file((stage / "tiles" / (t.name + ".glb")).string(), bytes);
    glb_size[i] = bytes.size();
    report.step(done, tiles.size(), 0.5, 0.4, "writing tiles");
  });
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    st.glb_bytes += glb_size[i];
    st.max_glb_bytes = std::max(st.max_glb_bytes, glb_size[i]);
    st.max_tile_triangles = std::max(st.max_tile_triangles, tiles[i].triangles);
    if (!tiles[i].items.empty()) {
      ++st.content_tiles;
      if (tiles[i].triangles > params.max_tile_triangles || tiles[i].bytes > params.max_tile_bytes)
        st.warnings.push_back("tile " + tiles[i].name + " exceeds the tile budget (" +
                              std::to_string(tiles[i].triangles) +
                              " triangles): a single building is too large");
    }
  }
}

/// 3b. buildings/<stem>.glb: every kept model of a building as a node.
/// Returns their sizes.
std::vector<std::size_t> write_building_glbs(const fs::path& stage,
                                             const std::vector<Building>& buildings,
                                             const io::GlbOptions& gopt, const SceneGeoref& georef,
                                             const AssembleParams& params, Reporter& report) {
  std::vector<std::size_t> bsize(buildings.size(), 0);
  std::atomic<std::size_t> done{0};
  write_in_parallel(buildings.size(), resolve_threads(params.threads), stage, [&](std::size_t i) {
    const Building& b = buildings[i];
    io::GlbBuilder g(rounded_centre(b.bbox), gopt);
    for (std::size_t m = 0; m < b.models.size(); ++m) {
      g.begin_node("model_" + std::to_string(m));
      const auto [mesh, colours] = kept_model(b.models[m], b.origin, georef);
      g.add_feature(feature_of(b, m), mesh, colours);
    }
    const std::string bytes = g.glb();
    io::atomic_write_file((stage / "buildings" / (b.file_stem + ".glb")).string(), bytes);
    bsize[i] = bytes.size();
    report.step(done, buildings.size(), 0.9, 0.09, "writing building models");
  });
  return bsize;
}

/// 3c. buildings.json, the viewer's index: the scene's frame and, per
/// building, its glb (`bsize`: their sizes) and its kept models.
/// Per building, per kept model: the first tile (in tile order) whose glb
/// holds it, as a path under the tileset's root, or "" if no tile shows it.
std::vector<std::vector<std::string>> tiles_of_models(const std::vector<TileNode>& tiles,
                                                      const std::vector<Building>& buildings) {
  std::vector<std::vector<std::string>> where(buildings.size());
  for (std::size_t b = 0; b < buildings.size(); ++b) where[b].resize(buildings[b].models.size());
  for (const TileNode& t : tiles)
    for (const Item& it : t.items)
      if (where[it.b][it.m].empty()) where[it.b][it.m] = "tiles/" + t.name + ".glb";
  return where;
}

void write_buildings_index(const fs::path& stage, const std::vector<Building>& buildings,
                           const std::vector<TileNode>& tiles,
                           const std::vector<std::size_t>& bsize, const Manifest& man,
                           const std::array<double, 16>& root_transform,
                           const AssembleParams& params, AssembleStats& st) {
  const auto& sc = man.scene;
  nlohmann::ordered_json index;
  index["version"] = 1;
  index["root_transform"] = root_transform;
  index["origin"] = {
      {"longitude", sc.origin_lon}, {"latitude", sc.origin_lat}, {"height", sc.origin_h}};
  if (!sc.crs.empty()) index["crs"] = sc.crs;
  nlohmann::ordered_json blist = nlohmann::ordered_json::object();
  const std::vector<std::vector<std::string>> in_tile = tiles_of_models(tiles, buildings);
  for (std::size_t i = 0; i < buildings.size(); ++i) {
    const Building& b = buildings[i];
    st.building_glb_bytes += bsize[i];
    nlohmann::ordered_json e;
    if (params.building_models) e["glb"] = "buildings/" + b.file_stem + ".glb";
    e["centre"] = b.centre;
    e["footprint_area"] = b.footprint_area_m2;
    if (!b.attributes.empty()) e["attributes"] = b.attributes;
    nlohmann::ordered_json ms = nlohmann::ordered_json::array();
    for (std::size_t m = 0; m < b.models.size(); ++m) {
      const KeptModel& km = b.models[m];
      nlohmann::ordered_json me;
      // the model as streamed: the building's feature in that tile's glb
      me["tile"] = in_tile[i][m].empty() ? nlohmann::ordered_json(nullptr)
                                         : nlohmann::ordered_json(in_tile[i][m]);
      if (params.building_models) me["node"] = "model_" + std::to_string(m);
      me.update(nlohmann::ordered_json{
          {"kind", lod::to_string(km.kind)},
          {"level", km.level},
          {"step", km.step},
          {"error_m", km.error_m},
          {"hausdorff_m", km.hausdorff_m},
          {"rmse_m", km.rmse_m >= 0 ? nlohmann::ordered_json(km.rmse_m) : nullptr},
          {"valid", km.valid},
          {"height", km.height_m},
          {"triangles", km.triangles},
          {"file", fs::path(km.file).filename().string()}});
      ms.push_back(std::move(me));
    }
    e["models"] = ms;
    blist[b.id] = e;
  }
  index["buildings"] = blist;
  io::atomic_write_file(buildings_json_path(stage.string()),
                        index.dump() + "\n");  // compact (the viewer reads it)
}

/// 3d. tileset.json and the external tilesets (tiles/<name>.json), the last
/// files of the stage.
void write_tilesets(const fs::path& stage, const TreeBuilder& tree, const std::string& crs,
                    const std::array<double, 16>& root_transform, const AssembleParams& params,
                    AssembleStats& st) {
  const std::vector<TileNode>& tiles = tree.tiles;
  io::Tileset ts;
  TilesetWriter tw(tiles, params.max_tiles_per_file);
  std::size_t budget = params.max_tiles_per_file;
  ts.root = tw.tile(0, "tiles/", budget);
  for (const auto& [name, ext] : tw.external)
    io::write_tileset((stage / "tiles" / name).string(), ext);
  st.tileset_files = 1 + tw.external.size();
  ts.root.refine = "REPLACE";
  ts.root.transform = root_transform;
  ts.geometric_error = std::max(tree.tileset_error, tiles[0].error);
  const std::string index = fs::path(buildings_json_path(stage.string())).filename().string();
  ts.extras = {{"citylod", {{"buildings", index}, {"crs", crs}}}};
  io::write_tileset(tileset_json_path(stage.string()), ts);  // last file of the stage
  st.tiles = tiles.size();
  st.depth = tree_depth(tiles, 0);
  st.root_error_m = tiles[0].error;
}

}  // namespace

AssembleStats assemble(const std::string& work_dir, const std::string& out_dir,
                       const AssembleParams& params, const ProgressFn& progress) {
  params.validate();
  AssembleStats st;
  const auto t0 = Clock::now();
  Reporter report(progress);
  if (!fs::is_directory(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  fs::path out = fs::absolute(out_dir).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();  // "DIR/"
  if (out.filename().empty() || out == out.root_path())
    throw io::IoError(out_dir, "not a valid output directory");
  // One writer: of the work directory (no LOD stage changes it meanwhile) and of the output.
  const DirLock work_lock(work_dir), out_lock = DirLock::for_output(out.string());
  const Manifest man = read_manifest(work_dir);
  if (man.chunks.empty())
    throw io::IoError(manifest_path(work_dir),
                      "the manifest lists no buildings (nothing to assemble)");
  require_valid_origin(man, work_dir);
  const SceneGeoref georef(man, work_dir);
  const auto& sc = man.scene;
  check_output_dir(out, params.force);

  // ---- 1. buildings
  const std::vector<Building> buildings = read_buildings(work_dir, man, params, georef, report, st);
  st.seconds_read = seconds_since(t0);

  // ---- 2. tile tree
  TreeBuilder tree(buildings, params);
  tree.build();

  // ---- 3. files, staged next to the output
  const auto t1 = Clock::now();
  const fs::path stage = out.string() + ".partial";
  fs::remove_all(stage);
  fs::create_directories(stage / "tiles");
  if (params.building_models) fs::create_directories(stage / "buildings");
  // the stage's files are written in place and made durable at once by publish_directory
  const io::StagedDirectory staged(stage.string());
  const io::GlbOptions gopt = glb_options(params, buildings);
  io::atomic_write_file((stage / "schema.json").string(), io::glb_schema(gopt) + "\n");
  write_tiles(stage, tree.tiles, buildings, gopt, georef, params, report, st);
  // Per-building glbs (every kept model as a node) + index for the viewer.
  const std::vector<std::size_t> bsize =
      params.building_models ? write_building_glbs(stage, buildings, gopt, georef, params, report)
                             : std::vector<std::size_t>(buildings.size(), 0);
  const geo::LocalFrame frame(geo::LonLatH(sc.origin_lon, sc.origin_lat, sc.origin_h));
  const std::array<double, 16> root_transform = frame.enu_to_ecef_matrix();
  write_buildings_index(stage, buildings, tree.tiles, bsize, man, root_transform, params, st);
  write_tilesets(stage, tree, sc.crs, root_transform, params, st);

  // ---- 4. switch the staged directory in: fsync'd, then one atomic exchange
  // (the output is at every instant the previous or the new complete tileset)
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  io::publish_directory(stage.string(), out.string());
  st.seconds_write = seconds_since(t1);
  report(1.0, "done");
  notify_finished(progress, "assemble");
  return st;
}

}  // namespace citylod::tiler
