// The one bridge between citylod::io (files, georeferenced magnitudes) and
// the LOD engine's local-frame value types. Every conversion io <-> lod of
// the pipeline, the app and the benchmarks goes through here.
#pragma once

#include <functional>
#include <string>

#include "citylod/io/types.hpp"
#include "citylod/lod/lod.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

/// A building read from one file, moved to a local frame: local = file - origin.
struct LoadedBuilding {
  lod::BuildingInput input;
  io::Vec3d origin{0, 0, 0};  ///< added back to write models in the input frame
  bool is_mesh = false;
};

/// Reads a point cloud (with normals if present) or a mesh (PLY/OBJ/OFF with
/// faces) and centres it on its bbox centre rounded to the metre (the frame
/// `citylod lod` and `eval` work in). Throws io::IoError (also for a point
/// cloud without points).
LoadedBuilding load_building(const std::string& path);

/// A chunk of a work directory as the LOD stage sees it: the chunk file's
/// coordinates as they are (the chunk origin is the frame), its footprint and
/// ground height moved to that frame, name = id. Throws io::IoError.
lod::BuildingInput chunk_input(const std::string& work_dir, const ChunkRecord& c);

/// io -> lod: local = v - origin (or f(v)).
lod::TriangleMesh to_lod_mesh(const io::TriangleMesh& m, const io::Vec3d& origin = {0, 0, 0});
lod::TriangleMesh to_lod_mesh(const io::TriangleMesh& m,
                              const std::function<io::Vec3d(const io::Vec3d&)>& f);
/// lod -> io: v + origin.
io::TriangleMesh to_io_mesh(const lod::TriangleMesh& m, const io::Vec3d& origin);
io::PolygonMesh to_io_polygons(const lod::PolygonMesh& m, const io::Vec3d& origin);

/// "model_<step>_<kind>_L<level>": the file stem of a model.
std::string model_stem(const lod::LodModel& m);
/// The report.json record of a building's LOD result (models listed as <stem>.ply).
LodReport make_lod_report(const lod::LodResult& r, const lod::LodParams& p,
                          const std::string& input);

}  // namespace citylod::tiler
