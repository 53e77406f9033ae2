// `citylod cityjson`: a work directory -> CityJSON 2.0 text sequence (docs/cityjson.md).
// Reads top to bottom: the georeferencing, one building (its models as
// polygons, semantics, lod), its feature, the file.
#include "citylod/tiler/cityjson.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <stdexcept>

#include <omp.h>
#include <nlohmann/json.hpp>

#include "citylod/geo/crs.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/gltf.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/weld.hpp"
#include "citylod/lod/lod.hpp"
#include "citylod/lod/validity.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/scene_georef.hpp"
#include "citylod/tiler/threads.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using io::Vec3d;
using json = nlohmann::ordered_json;

void CityJsonOptions::validate() const {
  if (!(scale > 0) || !std::isfinite(scale) || scale > 1)
    throw std::invalid_argument("cityjson scale must be in (0, 1] (CRS units per integer step)");
  if (!(min_change_m >= 0) || !std::isfinite(min_change_m))
    throw std::invalid_argument("min_change_m must be >= 0");
  if (!(hausdorff_tolerance_m > 0) || !std::isfinite(hausdorff_tolerance_m))
    throw std::invalid_argument("hausdorff_tolerance_m must be > 0");
  if (threads < 0) throw std::invalid_argument("threads must be >= 0");
}

std::string cityjson_lod(bool fallback, bool finest, bool sloped_roof, std::size_t roof_heights) {
  if (fallback) return "1.2";
  if (finest) return "2.2";
  if (sloped_roof) return "2.1";
  return roof_heights <= 1 ? "1.2" : "1.3";
}

std::string cityjson_reference_system(const std::string& crs_spec) {
  if (crs_spec.empty()) return "";
  const geo::Crs crs = geo::Crs::parse(crs_spec);
  if (!crs.epsg()) return "";
  return "https://www.opengis.net/def/crs/EPSG/0/" + std::to_string(*crs.epsg());
}

namespace {

using Clock = std::chrono::steady_clock;

// ------------------------------------------------------------ thresholds (docs/cityjson.md)
/// A roof face is horizontal when its normal is within ~2.6 degrees of up.
constexpr double kHorizontalNz = 0.999;
/// Horizontal roof faces closer than this in height are one roof height.
constexpr double kRoofHeightTolerance = 0.1;
/// A downward face is GroundSurface when it lies within this of the model's
/// lowest point, else OuterCeilingSurface (the underside of an overhang).
constexpr double kGroundTolerance = 0.5;
/// Welding radii tried, in order, in multiples of the validator's snap
/// tolerance: a model is written after welding its vertices within r (more
/// than the snap tolerance: no two written vertices of a solid are within it).
constexpr double kWeldFactors[] = {1.1, 2.2, 4.4, 8.8};

enum Semantic : int { kRoof = 0, kWall = 1, kGround = 2, kCeiling = 3 };
/// The models of a chain that are not one of the Building's LoDs (1.2, 1.3,
/// 2.2): CityObjects of this Extension type in the Building's feature.
constexpr const char* kChainObjectType = "+LodTreeModel";
/// Its Extension (docs/extensions/lodtree.ext.json).
constexpr const char* kChainExtension = "LodTree";
constexpr const char* kChainExtensionUrl =
    "https://raw.githubusercontent.com/citylod/citylod/main/docs/extensions/lodtree.ext.json";
/// The appearance theme of the input's colours.
constexpr const char* kColourTheme = "rgb";
const char* const kSemanticType[] = {"RoofSurface", "WallSurface", "GroundSurface",
                                     "OuterCeilingSurface"};

// ------------------------------------------------------------ georeferencing
/// transform.translate: the manifest's origin_crs rounded to whole units (local
/// scenes: ENU metres, translate 0).
Vec3d translate_of(const Manifest& man) {
  Vec3d t{0, 0, 0};
  if (man.scene.crs.empty()) return t;
  for (int k = 0; k < 3; ++k) t[size_t(k)] = std::round(man.scene.origin_crs[size_t(k)]);
  return t;
}

// ------------------------------------------------------------ one model
Vec3d newell(const std::vector<Vec3d>& v, const std::vector<std::uint32_t>& f) {
  Vec3d n{0, 0, 0};
  for (std::size_t i = 0; i < f.size(); ++i) {
    const Vec3d &a = v[f[i]], &b = v[f[(i + 1) % f.size()]];
    n[0] += (a[1] - b[1]) * (a[2] + b[2]);
    n[1] += (a[2] - b[2]) * (a[0] + b[0]);
    n[2] += (a[0] - b[0]) * (a[1] + b[1]);
  }
  const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (l > 0)
    for (auto& c : n) c /= l;
  return n;
}

/// Signed volume and area of a triangulated surface (for the OBJ/PLY match).
std::pair<double, double> volume_area(const io::TriangleMesh& m) {
  double vol = 0, area = 0;
  const Vec3d& o = m.vertices.empty() ? Vec3d{0, 0, 0} : m.vertices[0];
  for (const auto& t : m.triangles) {
    Vec3d p[3];
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k)
        p[i][size_t(k)] = m.vertices[t[size_t(i)]][size_t(k)] - o[size_t(k)];
    const Vec3d u{p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const Vec3d w{p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    const Vec3d c{u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    area += std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) / 2;
    vol += (p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) -
            p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
            p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0])) /
           6;
  }
  return {vol, area};
}

std::set<Vec3d> used_positions(const std::vector<Vec3d>& v,
                               const std::vector<std::vector<std::uint32_t>>& faces) {
  std::set<Vec3d> s;
  for (const auto& f : faces)
    for (auto i : f) s.insert(v[i]);
  return s;
}

/// The model's faces as polygons, in its file's frame (chunk-relative). The
/// merged polygons of the OBJ the LOD stage writes next to the PLY when it is
/// the same surface (same vertices, volume and area); else the PLY's triangles.
io::PolygonMesh model_polygons(const std::string& ply, const io::TriangleMesh& mesh,
                               bool& from_obj) {
  io::PolygonMesh tri;
  tri.vertices = mesh.vertices;
  for (const auto& t : mesh.triangles) tri.faces.push_back({t[0], t[1], t[2]});
  from_obj = false;
  const fs::path obj = fs::path(ply).replace_extension(".obj");
  if (obj == fs::path(ply) || !fs::exists(obj)) return tri;
  io::PolygonMesh pm;
  try {
    pm = io::read_polygon_mesh(obj.string());
  } catch (const io::IoError&) {
    return tri;  // not ours or damaged: the PLY is the model
  }
  if (used_positions(pm.vertices, pm.faces) != used_positions(tri.vertices, tri.faces)) return tri;
  const auto [v0, a0] = volume_area(mesh);
  const auto [v1, a1] = volume_area(io::triangulate_polygons(pm));
  const double tol = 1e-9 * std::max(1.0, a0);
  if (std::fabs(v0 - v1) > tol * std::max(1.0, std::cbrt(std::fabs(v0))) ||
      std::fabs(a0 - a1) > tol)
    return tri;
  from_obj = true;
  return pm;
}

struct Geometry {
  std::vector<std::vector<std::uint32_t>> faces;  // feature vertex indices
  std::vector<int> semantic;                      // per face
  std::vector<io::Rgba8> colour;                  // per face (a = 0: none)
  std::vector<int> shell;  // per face: 0 outer, > 0 a cavity; with `multi` the face's solid
  std::string lod;
  json attributes;  // its citylod_models entry
  bool valid = false, full_semantics = false, from_obj = false;
  bool fallback = false, sloped = false;
  bool multi = false;  // a MultiSolid: the model's pieces, one Solid each (separate_pieces)
  std::size_t roof_heights = 0;
  int step = 0;
  double snapped = 0;  // vertices within this were welded together to keep the solid valid
};

struct Feature {
  std::string id;
  std::string line;  // the JSON text, no newline
  std::size_t geometries = 0, invalid = 0, triangulated = 0, vertices = 0;
  std::size_t chain_objects = 0;  // +LodTreeModel objects
  std::size_t coloured = 0;       // geometries with a material
  bool full_semantics = false;
  io::BBox3 bbox;  // CRS
  std::vector<std::string> warnings;
  std::string error;  // the building cannot be written
  bool skipped = false;
};

std::string chain_object_id(const std::string& building, int step) {
  return building + "-lodtree-" + std::to_string(step);
}

double round_to(double x, double step) {
  return std::round(x / step) * step;
}

/// Quantized feature vertices, deduplicated.
class VertexPool {
 public:
  VertexPool(const Vec3d& translate, double scale) : t_(translate), s_(scale) {}
  std::uint32_t add(const Vec3d& crs) {
    std::array<long long, 3> q;
    for (int k = 0; k < 3; ++k) q[size_t(k)] = std::llround((crs[size_t(k)] - t_[size_t(k)]) / s_);
    const auto [it, fresh] = index_.emplace(q, std::uint32_t(list_.size()));
    if (fresh) list_.push_back(q);
    return it->second;
  }
  /// Back in CRS units relative to translate (small numbers for the checks).
  Vec3d relative(std::uint32_t i) const {
    return {double(list_[i][0]) * s_, double(list_[i][1]) * s_, double(list_[i][2]) * s_};
  }
  Vec3d absolute(std::uint32_t i) const {
    const Vec3d r = relative(i);
    return {r[0] + t_[0], r[1] + t_[1], r[2] + t_[2]};
  }
  const std::vector<std::array<long long, 3>>& list() const { return list_; }

 private:
  Vec3d t_;
  double s_;
  std::map<std::array<long long, 3>, std::uint32_t> index_;
  std::vector<std::array<long long, 3>> list_;
};

/// A validator's view of faces over feature vertices: the solid (vertices in
/// CRS units relative to translate) with its shells (lod::make_solid: the
/// outer one first, then cavities); `shell_of` receives each face's shell.
lod::PolygonSolid as_solid(const std::vector<std::vector<std::uint32_t>>& faces,
                           const VertexPool& pool, std::vector<int>* shell_of = nullptr) {
  std::vector<lod::Vec3> vertices;
  std::vector<std::vector<int>> rings;
  std::map<std::uint32_t, int> local;
  for (const auto& f : faces) {
    std::vector<int> ring;
    for (const std::uint32_t q : f) {
      const auto [it, fresh] = local.emplace(q, int(vertices.size()));
      if (fresh) {
        const Vec3d v = pool.relative(q);
        vertices.emplace_back(v[0], v[1], v[2]);
      }
      ring.push_back(it->second);
    }
    rings.push_back(std::move(ring));
  }
  return lod::make_solid(std::move(vertices), rings, shell_of);
}

/// Each face's error alone (lod::face_errors, 0: none) in the order of
/// `faces`, whichever shell it went to; empty for no face.
std::vector<int> errors_by_face(const std::vector<std::vector<std::uint32_t>>& faces,
                                const VertexPool& pool, const lod::Tolerances& tol) {
  std::vector<int> shell_of;
  const lod::PolygonSolid solid = as_solid(faces, pool, &shell_of);
  const std::vector<std::vector<int>> per_shell = lod::face_errors(solid, tol);
  std::vector<std::size_t> next(per_shell.size(), 0);  // faces keep their order in a shell
  std::vector<int> out(faces.size(), 0);
  for (std::size_t j = 0; j < faces.size(); ++j) {
    const auto sh = std::size_t(shell_of[j]);
    out[j] = per_shell[sh][next[sh]++];
  }
  return out;
}

/// The shells of `s` as one-shell solids, when it has more than one and each
/// encloses a positive volume: a model in pieces apart from each other (the
/// LOD stage keeps such an anchor, "a multi-solid"), which a validator reads
/// as outer shell and wrongly oriented cavities unless written as a
/// MultiSolid. Empty otherwise (one shell, or a true cavity).
std::vector<lod::PolygonSolid> separate_pieces(const lod::PolygonSolid& s) {
  std::vector<lod::PolygonSolid> pieces;
  if (s.shells.size() < 2) return pieces;
  for (const auto& shell : s.shells) {
    if (!(lod::signed_volume(s.vertices, shell) > 0)) return {};
    pieces.push_back(lod::PolygonSolid{s.vertices, {shell}});
  }
  return pieces;
}

/// How a validator takes `s`: 1 a valid Solid, 2 valid as a MultiSolid (every
/// piece of separate_pieces a valid Solid), 0 invalid (`c` the Solid's error).
int solid_verdict(const lod::PolygonSolid& s, const lod::Tolerances& tol, lod::SolidCheck& c) {
  c = lod::check_solid(s, tol);
  if (c.valid()) return 1;
  const std::vector<lod::PolygonSolid> pieces = separate_pieces(s);
  if (pieces.empty()) return 0;
  for (const lod::PolygonSolid& p : pieces)
    if (!lod::check_solid(p, tol).valid()) return 0;
  return 2;
}

/// pool index -> the representative of its cluster: the vertices `used`
/// within r integer steps of each other per axis, transitively, are one, the
/// lowest pool index of the cluster (io/weld.hpp, the glb writer's rule).
/// Representatives are more than r steps apart on some axis.
std::map<std::uint32_t, std::uint32_t> weld_map(std::vector<std::uint32_t> used,
                                                const VertexPool& pool, std::uint32_t r) {
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::vector<std::array<std::int64_t, 3>> points;
  for (const auto v : used) {
    const auto& q = pool.list()[v];
    points.push_back({q[0], q[1], q[2]});
  }
  std::vector<std::uint32_t> rank(used.size());
  std::iota(rank.begin(), rank.end(), 0u);
  const std::vector<std::uint32_t> root = io::weld(io::near_pairs(points, r), r, rank);
  std::map<std::uint32_t, std::uint32_t> m;
  for (std::size_t i = 0; i < used.size(); ++i) m.emplace(used[i], used[root[i]]);
  return m;
}

/// The rings with every vertex welded (weld_map): repeated consecutive
/// vertices and spikes (a, b, a) removed, rings left with fewer than three
/// vertices dropped; from[i] = the input ring of output ring i.
std::vector<std::vector<std::uint32_t>> weld_rings(
    const std::vector<std::vector<std::uint32_t>>& rings,
    const std::map<std::uint32_t, std::uint32_t>& to, std::vector<std::size_t>& from) {
  std::vector<std::vector<std::uint32_t>> out;
  from.clear();
  for (std::size_t fi = 0; fi < rings.size(); ++fi) {
    std::vector<std::uint32_t> ring;
    for (const std::uint32_t q : rings[fi]) ring.push_back(to.at(q));
    for (bool changed = true; changed && ring.size() >= 3;) {
      changed = false;
      for (std::size_t i = 0; i < ring.size() && ring.size() >= 3; ++i) {
        const std::size_t n = ring.size(), j = (i + 1) % n, k = (i + 2) % n;
        if (ring[i] == ring[j]) {  // repeated vertex
          ring.erase(ring.begin() + long(j));
          changed = true;
        } else if (ring[i] == ring[k]) {  // spike i -> j -> i: drop j and the return
          const std::size_t hi = std::max(j, k), lo = std::min(j, k);
          ring.erase(ring.begin() + long(hi));
          ring.erase(ring.begin() + long(lo));
          changed = true;
        }
      }
    }
    if (ring.size() < 3) continue;
    out.push_back(std::move(ring));
    from.push_back(fi);
  }
  return out;
}

/// The pool's integer vertices, for io/weld.hpp.
std::vector<std::array<std::int64_t, 3>> integer_points(const VertexPool& pool) {
  std::vector<std::array<std::int64_t, 3>> p;
  p.reserve(pool.list().size());
  for (const auto& q : pool.list()) p.push_back({q[0], q[1], q[2]});
  return p;
}

/// io::remove_collinear_spikes with the faces' semantics and colours kept aligned.
void remove_collinear_spikes(std::vector<std::vector<std::uint32_t>>& faces, std::vector<int>& sem,
                             std::vector<io::Rgba8>& col, const VertexPool& pool) {
  const std::vector<std::size_t> kept = io::remove_collinear_spikes(faces, integer_points(pool));
  std::vector<int> s2;
  std::vector<io::Rgba8> c2;
  for (const std::size_t x : kept) {
    s2.push_back(sem[x]);
    c2.push_back(col[x]);
  }
  sem = std::move(s2);
  col = std::move(c2);
}

/// One building's models as read (report, files, meshes), the chain kept
/// (indices into them, coarse -> fine) and its errors.
struct Chain : BuildingModels {
  std::vector<std::size_t> kept;
  std::vector<double> error_m;  // per kept model; empty with all_models
};

/// The models of `rec` and the chain to write: every model (all_models), the
/// chain given (opt.chains), else the one choose_models keeps.
Chain read_chain(const std::string& work, const ChunkRecord& rec, const CityJsonOptions& opt) {
  // a chain given: only its models are read
  const auto given =
      opt.chains && !opt.all_models ? opt.chains->find(rec.id) : decltype(opt.chains->end()){};
  const bool have = opt.chains && !opt.all_models && given != opt.chains->end();
  Chain ch{
      read_building_models(work, rec.id, read_model_file, have ? &given->second.kept : nullptr),
      {},
      {}};
  const std::vector<ModelRecord>& models = ch.report.models;
  if (opt.all_models) {
    for (std::size_t i = 0; i < models.size(); ++i) ch.kept.push_back(i);
    std::sort(ch.kept.begin(), ch.kept.end(),
              [&](std::size_t a, std::size_t b) { return models[a].step < models[b].step; });
  } else {
    const bool reuse = have && std::all_of(given->second.kept.begin(), given->second.kept.end(),
                                           [&](std::size_t k) { return k < models.size(); });
    if (have && !reuse)  // the report changed since: every model, and the choice
      ch.meshes = read_building_models(work, rec.id, read_model_file).meshes;
    const ModelChoice c =
        reuse ? given->second
              : choose_models(ch.report, ch.meshes, opt.min_change_m, opt.hausdorff_tolerance_m);
    ch.kept = c.kept;
    ch.error_m = c.error_m;
  }
  if (ch.kept.empty())
    throw io::IoError(ch.report_path, "building '" + rec.id + "': every model is empty");
  return ch;
}

/// The semantic of each face of `pm` and the roof shape (g.sloped,
/// g.roof_heights), in the model's own (ENU) frame. Returns the model's
/// lowest point (z).
double classify_faces(const io::PolygonMesh& pm, Geometry& g, std::vector<int>& sem) {
  double zmin = std::numeric_limits<double>::infinity();
  for (const auto& f : pm.faces)
    for (auto i : f) zmin = std::min(zmin, pm.vertices[i][2]);
  std::vector<double> roof_z;
  for (const auto& f : pm.faces) {
    const Vec3d n = newell(pm.vertices, f);
    const io::SurfaceClass c = io::classify_normal(n);
    double fz_max = -std::numeric_limits<double>::infinity(), fz_sum = 0;
    for (auto i : f) {
      fz_max = std::max(fz_max, pm.vertices[i][2]);
      fz_sum += pm.vertices[i][2];
    }
    if (c == io::SurfaceClass::roof) {
      sem.push_back(kRoof);
      if (n[2] < kHorizontalNz)
        g.sloped = true;
      else
        roof_z.push_back(fz_sum / double(f.size()));
    } else if (c == io::SurfaceClass::base) {
      sem.push_back(fz_max <= zmin + kGroundTolerance ? kGround : kCeiling);
    } else {
      sem.push_back(kWall);
    }
  }
  std::sort(roof_z.begin(), roof_z.end());
  for (std::size_t i = 0; i < roof_z.size(); ++i)
    if (i == 0 || roof_z[i] - roof_z[i - 1] > kRoofHeightTolerance) ++g.roof_heights;
  if (g.sloped) g.roof_heights = 0;
  return zmin;
}

/// A model's faces over the feature's vertex pool (in the CRS, quantized).
struct PooledModel {
  std::vector<std::vector<std::uint32_t>> rings;                  // pool indices, per polygon
  std::vector<std::array<std::uint32_t, 3>> tris;                 // pool indices, per PLY triangle
  std::vector<std::uint32_t> used;                                // pool indices of both, repeated
  std::vector<std::pair<std::size_t, std::size_t>> tris_of_ring;  // [first, last)
};

/// The polygons `pm` and the model's own triangles `mesh` (the PLY: the same
/// surface as the polygons) to the CRS (scene ENU = chunk origin + file
/// coordinates), quantized into `pool`.
PooledModel to_pool(const io::PolygonMesh& pm, const io::TriangleMesh& mesh,
                    const std::string& file, const ChunkRecord& rec, const SceneGeoref& georef,
                    VertexPool& pool) {
  PooledModel out;
  std::vector<std::uint32_t> used;
  {
    std::vector<char> is_used(pm.vertices.size(), 0);
    for (const auto& f : pm.faces)
      for (auto i : f) is_used[i] = 1;
    for (std::uint32_t i = 0; i < pm.vertices.size(); ++i)
      if (is_used[i]) used.push_back(i);
  }
  Eigen::Matrix3Xd pts(3, long(used.size()));
  for (std::size_t j = 0; j < used.size(); ++j)
    for (int c = 0; c < 3; ++c)
      pts(c, long(j)) = pm.vertices[used[j]][size_t(c)] + rec.origin[size_t(c)];
  if (georef.has_crs()) georef.to_crs(pts);
  std::vector<std::uint32_t> to_pool(pm.vertices.size(), 0);
  for (std::size_t j = 0; j < used.size(); ++j)
    to_pool[used[j]] = pool.add({pts(0, long(j)), pts(1, long(j)), pts(2, long(j))});
  for (const auto& f : pm.faces) {
    out.rings.emplace_back();
    for (auto i : f) out.rings.back().push_back(to_pool[i]);
  }
  std::map<Vec3d, std::uint32_t> pool_of;
  for (auto i : used) pool_of.emplace(pm.vertices[i], to_pool[i]);
  for (const auto& t : mesh.triangles) {
    std::array<std::uint32_t, 3> q;
    for (int c = 0; c < 3; ++c) {
      const auto it = pool_of.find(mesh.vertices[t[size_t(c)]]);
      if (it == pool_of.end())
        throw std::logic_error(file + ": a triangle vertex is not on the polygons");
      q[size_t(c)] = it->second;
    }
    out.tris.push_back(q);
  }
  for (const auto& t : out.tris) out.used.insert(out.used.end(), t.begin(), t.end());
  for (const auto& r : out.rings) out.used.insert(out.used.end(), r.begin(), r.end());
  return out;
}

/// The triangles of each polygon: the PLY triangulates the OBJ's polygons
/// in order, n - 2 triangles each (checked: each uses its polygon's
/// vertices only; else none are known and a polygon is never split).
std::vector<std::pair<std::size_t, std::size_t>> triangles_of_rings(
    const std::vector<std::vector<std::uint32_t>>& rings,
    const std::vector<std::array<std::uint32_t, 3>>& tris) {
  std::vector<std::pair<std::size_t, std::size_t>> tris_of_ring;  // [first, last)
  std::size_t at = 0;
  for (const auto& ring : rings) {
    const std::size_t n = ring.size() >= 3 ? ring.size() - 2 : 0;
    bool ok = at + n <= tris.size();
    for (std::size_t t = at; ok && t < at + n; ++t)
      for (const std::uint32_t q : tris[t])
        ok = ok && std::find(ring.begin(), ring.end(), q) != ring.end();
    if (!ok) return {};
    tris_of_ring.emplace_back(at, at + n);
    at += n;
  }
  if (at != tris.size()) return {};
  return tris_of_ring;
}

/// Faces of a solid with their semantics and colours, aligned.
struct Faces {
  std::vector<std::vector<std::uint32_t>> faces;
  std::vector<int> sem;
  std::vector<io::Rgba8> col;
};

/// The welded polygons (`faces`) with the ones a validator rejects alone
/// (`errs`: a fold, a ring that touches itself) replaced by their welded
/// triangles; `from`: each face's polygon.
Faces polygons_and_triangles(const Faces& welded, const std::vector<int>& errs,
                             const std::vector<std::size_t>& from, const PooledModel& m,
                             const std::map<std::uint32_t, std::uint32_t>& to,
                             const VertexPool& pool) {
  Faces mixed;
  for (std::size_t j = 0; j < welded.faces.size(); ++j) {
    if (!errs[j]) {
      mixed.faces.push_back(welded.faces[j]);
      mixed.sem.push_back(welded.sem[j]);
      mixed.col.push_back(welded.col[j]);
      continue;
    }
    for (std::size_t t = m.tris_of_ring[from[j]].first; t < m.tris_of_ring[from[j]].second; ++t) {
      const std::array<std::uint32_t, 3> w{to.at(m.tris[t][0]), to.at(m.tris[t][1]),
                                           to.at(m.tris[t][2])};
      if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;  // collapsed
      mixed.faces.push_back({w[0], w[1], w[2]});
      mixed.sem.push_back(welded.sem[j]);
      mixed.col.push_back(welded.col[j]);
    }
  }
  remove_collinear_spikes(mixed.faces, mixed.sem, mixed.col, pool);
  return mixed;
}

/// The model's own triangles, welded (`to`), collapsed ones and fins dropped,
/// each with its semantic (below zmin + kGroundTolerance: ground) and colour.
Faces welded_triangles(const PooledModel& m, const io::TriangleMesh& mesh,
                       const std::vector<io::Rgba8>& triangle_colours, double zmin,
                       const std::map<std::uint32_t, std::uint32_t>& to, const VertexPool& pool) {
  const bool tri_coloured = triangle_colours.size() == mesh.triangles.size();
  std::vector<std::array<std::uint32_t, 3>> welded;
  for (const auto& t : m.tris) welded.push_back({to.at(t[0]), to.at(t[1]), to.at(t[2])});
  std::vector<std::size_t> from;
  const std::vector<std::array<std::uint32_t, 3>> surviving =
      io::drop_collapsed_and_fins(welded, from);
  Faces out;
  for (std::size_t i = 0; i < surviving.size(); ++i) {
    out.faces.push_back({surviving[i][0], surviving[i][1], surviving[i][2]});
    const auto& t = mesh.triangles[from[i]];
    const Vec3d n = newell(mesh.vertices, {t[0], t[1], t[2]});
    const io::SurfaceClass c3 = io::classify_normal(n);
    double fz = -std::numeric_limits<double>::infinity();
    for (auto v : t) fz = std::max(fz, mesh.vertices[v][2]);
    out.col.push_back(tri_coloured ? triangle_colours[from[i]] : io::Rgba8{0, 0, 0, 0});
    out.sem.push_back(c3 == io::SurfaceClass::roof    ? kRoof
                      : c3 == io::SurfaceClass::wall  ? kWall
                      : fz <= zmin + kGroundTolerance ? kGround
                                                      : kCeiling);
  }
  remove_collinear_spikes(out.faces, out.sem, out.col, pool);
  return out;
}

/// A solid the validator accepts at its tolerances (docs/cityjson.md,
/// "Validity"): vertices welded within r > the snap tolerance (no two are
/// then within it; spikes and collapsed faces go), written as the merged
/// polygons when every one is a planar simple ring; else with the
/// polygons a validator rejects alone (a fold, a ring that touches itself)
/// as their triangles; else as the model's triangles; r grows until one of
/// them is valid, else the model is left out (g.valid stays false). Returns
/// why the first tries failed.
std::string make_solid(Geometry& g, const PooledModel& m, const std::vector<int>& sem,
                       const std::vector<io::Rgba8>& face_colours, bool from_obj, double zmin,
                       const io::TriangleMesh& mesh, const std::vector<io::Rgba8>& tri_colours,
                       const VertexPool& pool, const CityJsonOptions& opt) {
  const lod::Tolerances tol;  // val3dity's defaults
  const bool coloured = face_colours.size() == sem.size();
  std::string why;
  auto take = [&](Faces&& f, bool polygons, double snapped, int verdict) {
    as_solid(f.faces, pool, &g.shell);
    g.multi = verdict == 2;
    g.faces = std::move(f.faces);
    g.semantic = std::move(f.sem);
    g.colour = std::move(f.col);
    g.from_obj = polygons;
    g.snapped = snapped;
    g.valid = true;
  };
  for (const double factor : kWeldFactors) {
    const auto r = std::uint32_t(std::ceil(factor * tol.snap / opt.scale));
    const std::map<std::uint32_t, std::uint32_t> to = weld_map(m.used, pool, r);
    const bool moved =
        std::any_of(to.begin(), to.end(), [](const auto& p) { return p.first != p.second; });
    const double snapped = moved ? double(r) * opt.scale : 0;
    std::vector<std::size_t> from;
    Faces welded;
    welded.faces = weld_rings(m.rings, to, from);
    {
      const std::vector<std::size_t> kept_faces =
          io::remove_collinear_spikes(welded.faces, integer_points(pool));
      std::vector<std::size_t> f2;
      for (const std::size_t x : kept_faces) f2.push_back(from[x]);
      from = std::move(f2);
    }
    for (const std::size_t fi : from) {
      welded.sem.push_back(sem[fi]);
      welded.col.push_back(coloured ? face_colours[fi] : io::Rgba8{0, 0, 0, 0});
    }
    if (welded.faces.empty()) {  // a sliver: every face collapsed within r
      if (why.empty())
        why = "no face is left welded within " + std::to_string(r * opt.scale) + " m";
      continue;
    }
    const lod::PolygonSolid solid = as_solid(welded.faces, pool);
    lod::SolidCheck c;
    int verdict = solid_verdict(solid, tol, c);
    if (verdict) {
      take(std::move(welded), from_obj, snapped, verdict);
      break;
    }
    if (why.empty()) why = "polygons: error " + std::to_string(c.error) + " (" + c.detail + ")";
    // the polygons rejected alone, as their (welded) triangles
    const std::vector<int> errs = errors_by_face(welded.faces, pool, tol);
    if (!m.tris_of_ring.empty() && std::any_of(errs.begin(), errs.end(), [](int e) { return e; })) {
      Faces mixed = polygons_and_triangles(welded, errs, from, m, to, pool);
      verdict = solid_verdict(as_solid(mixed.faces, pool), tol, c);
      if (verdict) {
        take(std::move(mixed), from_obj, snapped, verdict);
        break;
      }
    }
    // the model's triangles
    Faces tris = welded_triangles(m, mesh, tri_colours, zmin, to, pool);
    verdict = solid_verdict(as_solid(tris.faces, pool), tol, c);
    if (verdict) {
      take(std::move(tris), false, snapped, verdict);
      break;
    }
    if (why.find("triangles") == std::string::npos)
      why += ", triangles: error " + std::to_string(c.error) + " (" + c.detail + ")";
  }
  return why;
}

/// Model `gi` of the chain as a Geometry: polygons and semantics (chunk
/// frame), then the CRS, then the solid a validator accepts (welded,
/// repaired) or none (g.valid false, a warning).
Geometry model_geometry(const Chain& ch, std::size_t gi, const ChunkRecord& rec,
                        const SceneGeoref& georef, VertexPool& pool, const CityJsonOptions& opt,
                        std::vector<std::string>& warnings) {
  const std::size_t k = ch.kept[gi];
  const ModelRecord& mr = ch.report.models[k];
  const io::TriangleMesh& mesh = ch.meshes[k];
  Geometry g;
  g.step = mr.step;
  g.fallback = ch.report.models[k].kind == ModelKind::fallback;
  bool from_obj = false;
  io::PolygonMesh pm = model_polygons(ch.files[k], mesh, from_obj);
  std::vector<int> sem;
  const double zmin = classify_faces(pm, g, sem);
  PooledModel m = to_pool(pm, mesh, ch.files[k], rec, georef, pool);
  if (from_obj) m.tris_of_ring = triangles_of_rings(m.rings, m.tris);
  // the input's colours of these faces (report.json), when they match
  const std::vector<io::Rgba8>& face_colours = from_obj ? mr.polygon_colours : mr.triangle_colours;
  const std::string why =
      make_solid(g, m, sem, face_colours, from_obj, zmin, mesh, mr.triangle_colours, pool, opt);
  if (!g.valid)
    warnings.push_back(
        "cityjson: " + rec.id + " model step " + std::to_string(mr.step) +
        " left out: not a valid solid as written, even welded within " +
        std::to_string(kWeldFactors[std::size(kWeldFactors) - 1] * lod::Tolerances().snap) +
        " m (" + why + ")");
  const std::set<int> classes(g.semantic.begin(), g.semantic.end());
  g.full_semantics = classes.count(kRoof) && classes.count(kWall) && classes.count(kGround);

  json a;
  a["kind"] = lod::to_string(mr.kind);
  a["level"] = mr.level;
  a["step"] = mr.step;
  const double rmse = ch.report.rmse_m(k);
  a["rmse_m"] = rmse >= 0 ? json(round_to(rmse, 1e-4)) : json(nullptr);
  if (mr.roof_rmse_m >= 0) a["roof_rmse_m"] = round_to(mr.roof_rmse_m, 1e-4);
  if (!ch.error_m.empty()) a["error_m"] = round_to(ch.error_m[gi], 1e-4);
  a["triangles"] = mesh.triangles.size();
  a["polygons"] = g.faces.size();
  a["valid"] = g.valid;
  if (g.snapped > 0) a["snapped_m"] = g.snapped;
  g.attributes = std::move(a);
  return g;
}

/// The lod of each written model; one geometry per lod on the Building
/// (LoD1.2 the coarsest block, LoD1.3 the finest flat step model, LoD2.2 the
/// finest model), the rest of the chain as +LodTreeModel children.
void assign_lods(std::vector<Geometry>& geoms, std::vector<std::size_t>& on_building,
                 std::vector<std::size_t>& children) {
  std::size_t lod12 = geoms.size(), lod13 = geoms.size();
  for (std::size_t i = 0; i < geoms.size(); ++i) {
    Geometry& g = geoms[i];
    g.lod = cityjson_lod(g.fallback, i + 1 == geoms.size(), g.sloped, g.roof_heights);
    g.attributes["lod"] = g.lod;
    if (g.lod == "1.2" && lod12 == geoms.size()) lod12 = i;
    if (g.lod == "1.3") lod13 = i;
  }
  for (std::size_t i = 0; i < geoms.size(); ++i)
    if (i == lod12 || i == lod13 || i + 1 == geoms.size())
      on_building.push_back(i);
    else
      children.push_back(i);
}

/// The pool vertices a written face uses (those left by welding are not
/// written), in pool order; the faces renumbered to them.
std::vector<std::uint32_t> written_vertices(std::vector<Geometry>& geoms, const VertexPool& pool) {
  std::vector<std::uint32_t> renum(pool.list().size(), 0);
  std::vector<std::uint32_t> written;
  std::vector<char> used_v(pool.list().size(), 0);
  for (const Geometry& g : geoms)
    for (const auto& f : g.faces)
      for (auto i : f) used_v[i] = 1;
  for (std::uint32_t i = 0; i < used_v.size(); ++i)
    if (used_v[i]) {
      renum[i] = std::uint32_t(written.size());
      written.push_back(i);
    }
  for (Geometry& g : geoms)
    for (auto& f : g.faces)
      for (auto& i : f) i = renum[i];
  return written;
}

/// The input's colours: one X3D material per distinct colour (first use
/// order), theme "rgb" (docs/cityjson.md); `material_of` its index.
json colour_materials(const std::vector<Geometry>& geoms, std::map<io::Rgba8, int>& material_of) {
  json materials = json::array();
  for (const Geometry& g : geoms)
    for (const io::Rgba8& c : g.colour)
      if (c[3] && material_of.emplace(c, int(materials.size())).second) {
        char name[16];
        std::snprintf(name, sizeof name, "rgb_%02x%02x%02x", c[0], c[1], c[2]);
        materials.push_back({{"name", name},
                             {"diffuseColor",
                              {round_to(c[0] / 255.0, 1e-4), round_to(c[1] / 255.0, 1e-4),
                               round_to(c[2] / 255.0, 1e-4)}}});
      }
  return materials;
}

/// A geometry as a CityJSON Solid (or MultiSolid), counted in `out`.
json solid_json(const Geometry& g, const std::map<io::Rgba8, int>& material_of, Feature& out) {
  // the shells (outer first, then cavities; with g.multi one per solid), each face one ring
  json boundaries = json::array(), values = json::array(), colour_values = json::array();
  for (std::size_t f = 0; f < g.faces.size(); ++f) {
    const std::size_t sh = std::size_t(g.shell[f]);
    while (boundaries.size() <= sh) {
      boundaries.push_back(json::array());
      values.push_back(json::array());
      colour_values.push_back(json::array());
    }
    boundaries[sh].push_back(json::array({g.faces[f]}));
    values[sh].push_back(g.semantic[f]);
    colour_values[sh].push_back(g.colour[f][3] ? json(material_of.at(g.colour[f])) : json(nullptr));
  }
  std::set<int> present(g.semantic.begin(), g.semantic.end());
  // surfaces: one object per class present, values index into them
  json surfaces = json::array();
  std::map<int, int> slot;
  for (int c : present) {
    slot[c] = int(surfaces.size());
    surfaces.push_back({{"type", kSemanticType[c]}});
  }
  for (auto& sv : values)
    for (auto& v : sv) v = slot[v.get<int>()];
  if (g.multi) {  // each shell the one shell of its own Solid
    for (json* a : {&boundaries, &values, &colour_values})
      for (json& shell : *a) shell = json::array({std::move(shell)});
  }
  json geo;
  geo["type"] = g.multi ? "MultiSolid" : "Solid";
  geo["lod"] = g.lod;
  geo["boundaries"] = boundaries;
  geo["semantics"] = {{"surfaces", surfaces}, {"values", values}};
  if (std::any_of(g.colour.begin(), g.colour.end(), [](const io::Rgba8& c) { return c[3]; })) {
    geo["material"] = {{kColourTheme, {{"values", colour_values}}}};
    ++out.coloured;
  }
  ++out.geometries;
  out.triangulated += !g.from_obj;
  out.full_semantics = out.full_semantics && g.full_semantics;
  return geo;
}

/// The CityJSONFeature's text (out.line) and counts: the Building with its
/// footprint's attributes and the geometries `on_building`, the `children`
/// as +LodTreeModel objects, the vertices.
void write_feature(Feature& out, std::vector<Geometry>& geoms,
                   const std::vector<std::size_t>& on_building,
                   const std::vector<std::size_t>& children, const ChunkRecord& rec,
                   const LodReport& rep, const VertexPool& pool) {
  const std::string& object_id = out.id;
  const std::vector<std::uint32_t> written = written_vertices(geoms, pool);
  std::map<io::Rgba8, int> material_of;
  const json materials = colour_materials(geoms, material_of);
  out.full_semantics = true;
  json objects = json::object();
  json obj;
  obj["type"] = "Building";
  json attrs = json::object();
  // the footprint's own attributes (typed as read from its source), then ours
  for (const auto& [key, v] : rec.attributes.items()) attrs[key] = v;
  attrs["citylod_id"] = rec.id;
  if (!rec.source.empty()) attrs["citylod_source"] = rec.source;
  attrs["citylod_status"] = to_string(rep.status);
  if (!rep.reason.empty()) attrs["citylod_reason"] = rep.reason;
  json models = json::array(), geometry = json::array();
  for (const std::size_t i : on_building) {
    models.push_back(geoms[i].attributes);
    geometry.push_back(solid_json(geoms[i], material_of, out));
  }
  attrs["citylod_models"] = models;
  obj["attributes"] = attrs;
  obj["geometry"] = geometry;
  objects[object_id] = obj;
  for (const std::size_t i : children) {
    json child;
    child["type"] = kChainObjectType;
    json ca = geoms[i].attributes;
    // not a child of the Building: validators (val3dity) read a Building's
    // children as BuildingParts, which must not overlap
    child["attributes"] = {{"citylod_building", object_id}, {"citylod_model", ca}};
    child["geometry"] = json::array({solid_json(geoms[i], material_of, out)});
    objects[chain_object_id(object_id, geoms[i].step)] = child;
    ++out.chain_objects;
  }
  json verts = json::array();
  for (const std::uint32_t i : written) {
    verts.push_back(pool.list()[i]);
    out.bbox.add(pool.absolute(i));
  }
  out.vertices = written.size();
  json feat;
  feat["type"] = "CityJSONFeature";
  feat["id"] = object_id;
  feat["CityObjects"] = objects;
  feat["vertices"] = verts;
  if (!materials.empty()) feat["appearance"] = {{"materials", materials}};
  out.line = feat.dump();
}

/// One building -> its CityJSONFeature.
Feature make_feature(const std::string& work, const ChunkRecord& rec, const std::string& object_id,
                     const SceneGeoref& georef, const Vec3d& translate,
                     const CityJsonOptions& opt) {
  Feature out;
  out.id = object_id;
  const Chain ch = read_chain(work, rec, opt);

  // ---- per model: its Geometry (the feature's vertices, in the CRS)
  VertexPool pool(translate, opt.scale);
  std::vector<Geometry> geoms;
  for (std::size_t gi = 0; gi < ch.kept.size(); ++gi) {
    Geometry g = model_geometry(ch, gi, rec, georef, pool, opt, out.warnings);
    out.invalid += !g.valid;
    geoms.push_back(std::move(g));
  }

  // ---- the written models: their lods, which go on the Building
  geoms.erase(
      std::remove_if(geoms.begin(), geoms.end(), [](const Geometry& g) { return !g.valid; }),
      geoms.end());
  std::vector<std::size_t> on_building, children;
  assign_lods(geoms, on_building, children);
  if (geoms.empty())
    out.warnings.push_back("cityjson: " + rec.id +
                           " has no model that is a valid solid as written: its Building "
                           "is written without geometry");

  // ---- the feature
  write_feature(out, geoms, on_building, children, rec, ch.report, pool);
  return out;
}

/// CityObject id: the footprint's own id for footprint chunks (the id a GIS
/// team joins on), the chunk id otherwise or when footprint ids repeat.
std::vector<std::string> object_ids(const std::vector<const ChunkRecord*>& recs) {
  std::vector<std::string> ids;
  const std::string prefix = "footprint:";
  for (const auto* r : recs)
    ids.push_back(r->source.rfind(prefix, 0) == 0 && r->source.size() > prefix.size()
                      ? r->source.substr(prefix.size())
                      : r->id);
  std::map<std::string, int> count;
  for (const auto& i : ids) ++count[i];
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (count[ids[i]] > 1 || (ids[i] != recs[i]->id && count.count(recs[i]->id)))
      ids[i] = recs[i]->id;
  return ids;
}

}  // namespace

CityJsonStats write_cityjson(const std::string& work_dir, const std::string& out_path,
                             const CityJsonOptions& opt, const ProgressFn& progress) {
  opt.validate();
  const auto t0 = Clock::now();
  CityJsonStats st;
  if (!fs::is_directory(work_dir)) throw io::IoError(work_dir, "work directory does not exist");
  const Manifest man = read_manifest(work_dir);
  if (man.chunks.empty())
    throw io::IoError(manifest_path(work_dir),
                      "the manifest lists no buildings (nothing to write)");
  const SceneGeoref georef(man, work_dir);
  const Vec3d translate = translate_of(man);
  st.reference_system = cityjson_reference_system(man.scene.crs);
  const fs::path out = fs::absolute(out_path).lexically_normal();
  if (out.filename().empty() || fs::is_directory(out))
    throw io::IoError(out_path, "not a file path for the CityJSONSeq output");

  const std::vector<const ChunkRecord*> recs = buildings_to_model(man, work_dir, &st.skipped);
  const std::vector<std::string> ids = object_ids(recs);

  // Features in batches (bounded memory), written in id order to a side file;
  // the header (which needs the extent) goes first in the final file.
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  const fs::path body = out.string() + ".partial.body";
  const fs::path stage = out.string() + ".partial";
  std::ofstream bf(body, std::ios::binary | std::ios::trunc);
  if (!bf) throw io::IoError(body.string(), "cannot write");
  const int nthreads = resolve_threads(opt.threads);
  io::BBox3 extent;
  const std::size_t batch = std::size_t(16 * nthreads);
  auto fail = [&](const std::string& msg) {
    bf.close();
    fs::remove(body);
    throw std::runtime_error(msg);
  };
  for (std::size_t b0 = 0; b0 < recs.size(); b0 += batch) {
    const std::size_t b1 = std::min(recs.size(), b0 + batch);
    std::vector<Feature> feats(b1 - b0);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (long i = long(b0); i < long(b1); ++i) {
      Feature& f = feats[size_t(i) - b0];
      try {
        f = make_feature(work_dir, *recs[size_t(i)], ids[size_t(i)], georef, translate, opt);
      } catch (const std::exception& e) {
        f.error = e.what();
      }
    }
    for (Feature& f : feats) {
      if (!f.error.empty()) {
        if (!opt.skip_missing) fail(f.error);
        st.warnings.push_back("skipped: " + f.error);
        ++st.skipped;
        continue;
      }
      bf << f.line << '\n';
      ++st.buildings;
      st.geometries += f.geometries;
      st.invalid += f.invalid;
      st.triangulated += f.triangulated;
      st.chain_objects += f.chain_objects;
      st.coloured += f.coloured;
      st.vertices += f.vertices;
      st.multi_lod += f.geometries >= 2;
      st.full_semantics += f.full_semantics;
      extent.add(f.bbox);
      for (auto& w : f.warnings) st.warnings.push_back(std::move(w));
    }
    notify_progress(progress, "cityjson", 0.95 * double(b1) / double(recs.size()), "buildings");
  }
  bf.close();
  if (!bf) fail(body.string() + ": write failed");
  if (st.buildings == 0) fail(work_dir + ": no building has LOD models (nothing to write)");

  // ---- header + body -> stage -> out
  json head;
  head["type"] = "CityJSON";
  head["version"] = "2.0";
  head["transform"] = {{"scale", {opt.scale, opt.scale, opt.scale}},
                       {"translate", {translate[0], translate[1], translate[2]}}};
  json meta;
  if (!st.reference_system.empty()) meta["referenceSystem"] = st.reference_system;
  meta["geographicalExtent"] = {extent.min[0], extent.min[1], extent.min[2],
                                extent.max[0], extent.max[1], extent.max[2]};
  meta["title"] = "citylod LOD chains of " + std::to_string(st.buildings) + " buildings";
  head["metadata"] = meta;
  if (st.chain_objects > 0)
    head["extensions"] = {{kChainExtension, {{"url", kChainExtensionUrl}, {"version", "1.0"}}}};
  head["CityObjects"] = json::object();
  head["vertices"] = json::array();
  {
    std::ofstream sf(stage, std::ios::binary | std::ios::trunc);
    std::ifstream in(body, std::ios::binary);
    sf << head.dump() << '\n' << in.rdbuf();
    sf.flush();
    if (!sf) {
      fs::remove(stage);
      fail(stage.string() + ": write failed");
    }
  }
  fs::remove(body);
  fs::rename(stage, out);
  st.bytes = fs::file_size(out);
  st.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  notify_finished(progress, "cityjson");
  return st;
}

}  // namespace citylod::tiler
