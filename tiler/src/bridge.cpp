// io <-> lod conversions (bridge.hpp).
#include "citylod/tiler/bridge.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// One file's content, read once.
struct BuildingFile {
  bool is_mesh = false;
  io::TriangleMesh mesh;
  io::PointSet points;
};

BuildingFile read_building_file(const std::string& path) {
  BuildingFile f;
  f.is_mesh = io::read_header(path).has_faces;
  if (f.is_mesh)
    f.mesh = io::read_mesh(path);
  else
    f.points = io::read_points(path);
  return f;
}

/// Largest coordinate the engine takes, in its local frame (metres from the
/// building's centre): beyond, its exact predicates and grids misbehave.
constexpr double kMaxLocalCoordinate = 1e7;

/// What the engine cannot take is an input error, named here (not a crash inside it):
/// a coordinate that is not finite or too large, a mesh whose every face is degenerate.
void check_building_input(const lod::BuildingInput& in, const std::string& path) {
  for (std::size_t i = 0; i < in.points.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double v = in.points[i][k];
      if (!std::isfinite(v))
        throw io::IoError(path, "vertex/point " + std::to_string(i) +
                                    " has a coordinate that "
                                    "is not a finite number");
      if (std::fabs(v) > kMaxLocalCoordinate)
        throw io::IoError(path, "vertex/point " + std::to_string(i) +
                                    " lies more than 1e7 m from the centre of the data "
                                    "(coordinates of extreme magnitude; not one building)");
    }
  for (const auto& t : in.triangles)
    for (const int v : t)
      if (v < 0 || std::size_t(v) >= in.points.size())
        throw io::IoError(path, "a triangle refers to vertex " + std::to_string(v) + " of " +
                                    std::to_string(in.points.size()));
  if (!in.triangles.empty()) {
    const bool any_area =
        std::any_of(in.triangles.begin(), in.triangles.end(), [&](const std::array<int, 3>& t) {
          const Eigen::Vector3d &a = in.points[std::size_t(t[0])],
                                &b = in.points[std::size_t(t[1])],
                                &c = in.points[std::size_t(t[2])];
          return (b - a).cross(c - a).norm() > 1e-12;
        });
    if (!any_area)
      throw io::IoError(path, "all " + std::to_string(in.triangles.size()) +
                                  " triangles are degenerate (zero area); nothing to model");
  }
}

/// The conversion of a building file to the engine's input: local = file - origin.
lod::BuildingInput to_building_input(const BuildingFile& f, const io::Vec3d& o,
                                     const std::string& path) {
  lod::BuildingInput in;
  if (f.is_mesh) {
    for (const auto& v : f.mesh.vertices)
      in.points.emplace_back(v[0] - o[0], v[1] - o[1], v[2] - o[2]);
    for (const auto& t : f.mesh.triangles)
      in.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
    if (f.mesh.colors.size() == f.mesh.vertices.size()) in.colors = f.mesh.colors;
  } else {
    in.points.reserve(f.points.size());
    for (const auto& v : f.points.positions)
      in.points.emplace_back(v[0] - o[0], v[1] - o[1], v[2] - o[2]);
    if (f.points.has_normals())
      for (const auto& n : f.points.normals) in.normals.emplace_back(n[0], n[1], n[2]);
    if (f.points.has_colors()) in.colors = f.points.colors;
  }
  check_building_input(in, path);
  return in;
}

}  // namespace

LoadedBuilding load_building(const std::string& path) {
  const BuildingFile f = read_building_file(path);
  LoadedBuilding b;
  b.is_mesh = f.is_mesh;
  io::BBox3 box;
  for (const auto& v : f.is_mesh ? f.mesh.vertices : f.points.positions) {
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
      throw io::IoError(path, "a vertex/point has a coordinate that is not a finite number");
    box.add(v);
  }
  if (!f.is_mesh && box.empty()) throw io::IoError(path + ": no points");
  if (!box.empty())
    for (int k = 0; k < 3; ++k)
      b.origin[size_t(k)] = std::round((box.min[size_t(k)] + box.max[size_t(k)]) / 2);
  b.input = to_building_input(f, b.origin, path);
  b.input.name = fs::path(path).filename().string();
  return b;
}

lod::BuildingInput chunk_input(const std::string& work, const ChunkRecord& c) {
  const std::string path = chunk_path(work, c.id);
  lod::BuildingInput in = to_building_input(read_building_file(path), {0, 0, 0}, path);
  // on a micrometre grid relative to the chunk origin: the same footprint gives the same
  // outline wherever it lies (relative to a whole-metre origin the scene coordinates of
  // a copy differ in their last bits)
  const auto snap = [](double v) { return std::round(v * 1e6) / 1e6; };
  for (const auto& q : c.outline)
    in.footprint.emplace_back(snap(q[0] - c.origin[0]), snap(q[1] - c.origin[1]));
  in.ground_z = snap(c.ground_z - c.origin[2]);
  in.has_ground_z = true;
  in.name = c.id;
  return in;
}

lod::TriangleMesh to_lod_mesh(const io::TriangleMesh& m, const io::Vec3d& o) {
  return to_lod_mesh(m, [&o](const io::Vec3d& v) {
    return io::Vec3d{v[0] - o[0], v[1] - o[1], v[2] - o[2]};
  });
}

lod::TriangleMesh to_lod_mesh(const io::TriangleMesh& m,
                              const std::function<io::Vec3d(const io::Vec3d&)>& f) {
  lod::TriangleMesh out;
  out.vertices.reserve(m.vertices.size());
  for (const auto& v : m.vertices) {
    const io::Vec3d p = f(v);
    out.vertices.emplace_back(p[0], p[1], p[2]);
  }
  for (const auto& t : m.triangles) out.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
  return out;
}

io::TriangleMesh to_io_mesh(const lod::TriangleMesh& m, const io::Vec3d& o) {
  io::TriangleMesh out;
  out.vertices.reserve(m.vertices.size());
  for (const auto& v : m.vertices)
    out.vertices.push_back({v.x() + o[0], v.y() + o[1], v.z() + o[2]});
  for (const auto& t : m.triangles)
    out.triangles.push_back({std::uint32_t(t[0]), std::uint32_t(t[1]), std::uint32_t(t[2])});
  return out;
}

io::PolygonMesh to_io_polygons(const lod::PolygonMesh& m, const io::Vec3d& o) {
  io::PolygonMesh out;
  for (const auto& v : m.vertices)
    out.vertices.push_back({v.x() + o[0], v.y() + o[1], v.z() + o[2]});
  for (const auto& f : m.faces) {
    std::vector<std::uint32_t> g;
    for (int i : f) g.push_back(std::uint32_t(i));
    out.faces.push_back(std::move(g));
  }
  return out;
}

std::string model_stem(const lod::LodModel& m) {
  std::ostringstream s;
  s << "model_" << std::setw(2) << std::setfill('0') << m.step << '_' << lod::to_string(m.kind)
    << "_L" << m.level;
  return s.str();
}

LodReport make_lod_report(const lod::LodResult& r, const lod::LodParams& p,
                          const std::string& input) {
  LodReport j;
  j.input = input;
  j.status = r.status;
  j.reason = r.reason;
  for (const auto& [k, v] : p.items()) j.parameters[k] = v;
  const auto& s = r.stats;
  j.counts = {{"input_points", s.input_points},   {"input_faces", s.input_faces},
              {"P", s.planes_detected},           {"S", s.planes_sorted},
              {"principal", s.principal},         {"add_ons", s.add_ons},
              {"cut_outs", s.cut_outs},           {"clusters", s.clusters},
              {"level_sets", s.level_sets},       {"ioview_cells", s.ioview_cells},
              {"bsp_nodes", s.bsp_nodes},         {"lod_nodes", s.lod_nodes},
              {"planes_turned", s.planes_turned}, {"models", std::int64_t(r.models.size())},
              {"planes_found", s.planes_found},   {"bsp_cap_hit", s.bsp_cap_hit ? 1 : 0}};
  j.lod_tree_vs_bsp_tree = {{"lod_tree_cuts_to_finest", s.lod_tree_cuts_to_finest},
                            {"bsp_tree_nodes", s.baseline_bsp_nodes},
                            {"bsp_tree_cuts_to_finest", s.baseline_cuts_to_finest}};
  j.bbox_diagonal_m = s.bbox_diagonal;
  j.normals_estimated = s.normals_estimated;
  j.walls_inferred = s.walls_inferred;
  j.timings_s = {{"samples", s.t_samples}, {"T1_ioview", s.t_ioview},
                 {"T2_tree", s.t_tree},    {"T3_traversal", s.t_traversal},
                 {"metrics", s.t_metrics}, {"colour", s.t_colour}};
  j.notes = s.notes;
  for (const auto& m : r.models) {
    ModelRecord e;
    e.file = model_stem(m) + ".ply";
    e.kind = m.kind;
    e.level = m.level;
    e.step = m.step;
    e.cuts = m.cuts;
    e.diff_sum = m.diff_sum;
    e.polygons = m.polygons.faces.size();
    e.triangles = m.mesh.triangles.size();
    e.volume = m.volume;
    e.e1 = m.e1;
    e.e2 = m.e2;
    e.hausdorff_m = m.hausdorff;
    e.roof_rmse_m = m.roof_rmse;
    e.polygon_colours = m.polygon_colours;
    e.triangle_colours = m.triangle_colours;
    j.models.push_back(e);
  }
  return j;
}

}  // namespace citylod::tiler
