#include "lod_io.hpp"

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>

namespace citylod::tiler {

namespace fs = std::filesystem;

LoadedBuilding load_building(const std::string& path) {
  LoadedBuilding b;
  const io::FileInfo info = io::read_header(path);
  b.is_mesh = info.has_faces;
  io::BBox3 box;
  if (b.is_mesh) {
    const io::TriangleMesh m = io::read_mesh(path);
    for (const auto& v : m.vertices) box.add(v);
    for (int k = 0; k < 3; ++k) b.origin[size_t(k)] = std::round((box.min[size_t(k)] + box.max[size_t(k)]) / 2);
    for (const auto& v : m.vertices)
      b.input.points.emplace_back(v[0] - b.origin[0], v[1] - b.origin[1], v[2] - b.origin[2]);
    for (const auto& t : m.triangles) b.input.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
  } else {
    const io::PointSet p = io::read_points(path);
    for (const auto& v : p.positions) box.add(v);
    if (box.empty()) throw io::IoError(path + ": no points");
    for (int k = 0; k < 3; ++k) b.origin[size_t(k)] = std::round((box.min[size_t(k)] + box.max[size_t(k)]) / 2);
    b.input.points.reserve(p.size());
    for (const auto& v : p.positions)
      b.input.points.emplace_back(v[0] - b.origin[0], v[1] - b.origin[1], v[2] - b.origin[2]);
    if (p.has_normals())
      for (const auto& n : p.normals) b.input.normals.emplace_back(n[0], n[1], n[2]);
  }
  b.input.name = fs::path(path).filename().string();
  return b;
}

io::TriangleMesh to_io_mesh(const lod::TriangleMesh& m, const io::Vec3d& o) {
  io::TriangleMesh out;
  out.vertices.reserve(m.vertices.size());
  for (const auto& v : m.vertices) out.vertices.push_back({v.x() + o[0], v.y() + o[1], v.z() + o[2]});
  for (const auto& t : m.triangles)
    out.triangles.push_back({std::uint32_t(t[0]), std::uint32_t(t[1]), std::uint32_t(t[2])});
  return out;
}

io::PolygonMesh to_io_polygons(const lod::PolygonMesh& m, const io::Vec3d& o) {
  io::PolygonMesh out;
  for (const auto& v : m.vertices) out.vertices.push_back({v.x() + o[0], v.y() + o[1], v.z() + o[2]});
  for (const auto& f : m.faces) {
    std::vector<std::uint32_t> g;
    for (int i : f) g.push_back(std::uint32_t(i));
    out.faces.push_back(std::move(g));
  }
  return out;
}

namespace {

std::string model_stem(const lod::LodModel& m) {
  std::ostringstream s;
  s << "model_" << std::setw(2) << std::setfill('0') << m.step << '_' << lod::to_string(m.kind) << "_L"
    << m.level;
  return s.str();
}

/// Distinct colours per level set (level -1 = unused in grey).
io::Rgb8 level_colour(int level) {
  static const io::Rgb8 palette[] = {{31, 119, 180}, {214, 39, 40},  {44, 160, 44},  {255, 127, 14},
                                     {148, 103, 189}, {140, 86, 75}, {227, 119, 194}, {188, 189, 34},
                                     {23, 190, 207}};
  if (level < 0) return {128, 128, 128};
  return palette[size_t(level) % (sizeof(palette) / sizeof(palette[0]))];
}

}  // namespace

nlohmann::json lod_report(const lod::LodResult& r, const lod::LodParams& p, const std::string& input) {
  using nlohmann::json;
  json j;
  j["input"] = input;
  j["status"] = r.status;
  if (!r.reason.empty()) j["reason"] = r.reason;
  json params = json::object();
  for (const auto& [k, v] : p.items()) params[k] = v;
  j["parameters"] = params;
  const auto& s = r.stats;
  j["counts"] = {{"input_points", s.input_points},   {"input_faces", s.input_faces},
                 {"P", s.planes_detected},           {"S", s.planes_sorted},
                 {"principal", s.principal},         {"add_ons", s.add_ons},
                 {"cut_outs", s.cut_outs},           {"clusters", s.clusters},
                 {"level_sets", s.level_sets},       {"ioview_cells", s.ioview_cells},
                 {"bsp_nodes", s.bsp_nodes},         {"lod_nodes", s.lod_nodes},
                 {"planes_turned", s.planes_turned},
                 {"models", r.models.size()}};
  j["lod_tree_vs_bsp_tree"] = {{"lod_tree_cuts_to_finest", s.lod_tree_cuts_to_finest},
                               {"bsp_tree_nodes", s.baseline_bsp_nodes},
                               {"bsp_tree_cuts_to_finest", s.baseline_cuts_to_finest}};
  j["bbox_diagonal_m"] = s.bbox_diagonal;
  j["normals_estimated"] = s.normals_estimated;
  j["walls_inferred"] = s.walls_inferred;
  j["timings_s"] = {{"T1_ioview", s.t_ioview}, {"T2_tree", s.t_tree}, {"T3_traversal", s.t_traversal},
                    {"metrics", s.t_metrics}};
  j["notes"] = s.notes;
  json models = json::array();
  for (const auto& m : r.models) {
    models.push_back({{"file", model_stem(m) + ".ply"},
                      {"kind", lod::to_string(m.kind)},
                      {"level", m.level},
                      {"step", m.step},
                      {"cuts", m.cuts},
                      {"diff_sum", m.diff_sum},
                      {"polygons", m.polygons.faces.size()},
                      {"triangles", m.mesh.triangles.size()},
                      {"volume", m.volume},
                      {"e1", m.e1},
                      {"e2", m.e2},
                      {"hausdorff_m", m.hausdorff}});
  }
  j["models"] = models;
  return j;
}

std::vector<std::string> write_lod_output(const std::string& dir, const lod::LodResult& r,
                                          const lod::LodParams& p, const std::string& input,
                                          const io::Vec3d& origin, bool dump_planes,
                                          const nlohmann::json& extra) {
  fs::create_directories(dir);
  std::vector<std::string> files;
  for (const auto& m : r.models) {
    const std::string stem = (fs::path(dir) / model_stem(m)).string();
    io::write_obj(stem + ".obj", to_io_polygons(m.polygons, origin));
    io::write_ply(stem + ".ply", to_io_mesh(m.mesh, origin));
    files.push_back(stem + ".obj");
    files.push_back(stem + ".ply");
  }
  if (dump_planes) {
    io::PointSet pts;
    for (const auto& pl : r.planes)
      for (const auto& x : pl.inlier_points) {
        pts.positions.push_back({x.x() + origin[0], x.y() + origin[1], x.z() + origin[2]});
        pts.colors.push_back(level_colour(pl.level));
      }
    const std::string path = (fs::path(dir) / "planes.ply").string();
    io::write_ply(path, pts);
    files.push_back(path);
  }
  nlohmann::json params = nlohmann::json::object();
  for (const auto& [k, v] : p.items()) params[k] = v;
  const std::string ppath = (fs::path(dir) / "params.json").string();
  io::atomic_write_file(ppath, params.dump(2) + "\n");
  files.push_back(ppath);
  const std::string rpath = (fs::path(dir) / "report.json").string();
  nlohmann::json report = lod_report(r, p, input);
  report.update(extra);
  io::atomic_write_file(rpath, report.dump(2) + "\n");
  files.push_back(rpath);
  return files;
}

}  // namespace citylod::tiler
