// One building's LOD output folder: models as OBJ/PLY, report.json, params.json, planes.ply.
#include <filesystem>

#include "citylod/io/writers.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/lod_stage.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

/// Distinct colours per level set (level -1 = unused in grey).
io::Rgb8 level_colour(int level) {
  static const io::Rgb8 palette[] = {{31, 119, 180},  {214, 39, 40},   {44, 160, 44},
                                     {255, 127, 14},  {148, 103, 189}, {140, 86, 75},
                                     {227, 119, 194}, {188, 189, 34},  {23, 190, 207}};
  if (level < 0) return {128, 128, 128};
  return palette[size_t(level) % (sizeof(palette) / sizeof(palette[0]))];
}

}  // namespace

std::vector<std::string> write_lod_output(const std::string& dir, const lod::LodResult& r,
                                          const lod::LodParams& p, int threads,
                                          const std::string& input, const io::Vec3d& origin,
                                          bool dump_planes, const std::string& id,
                                          const std::string& key) {
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
  LodReport report = make_lod_report(r, p, input);
  report.threads = threads;
  write_params_record(dir, report.parameters, threads);
  files.push_back(params_file(dir));
  const std::string rpath = report_file(dir);
  report.id = id;
  report.key = key;
  write_lod_report(rpath, report);
  files.push_back(rpath);
  return files;
}

}  // namespace citylod::tiler
