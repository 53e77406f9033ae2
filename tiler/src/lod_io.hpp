// Bridges between citylod::io data (files, georeferenced magnitudes) and the
// LOD engine's local-frame value types, and the writer of one building's LOD
// output folder (models as OBJ/PLY, report.json, params.json, planes.ply).
#pragma once

#include "citylod/io/types.hpp"
#include "citylod/lod/lod.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace citylod::tiler {

/// A building read from one file, moved to a local frame: local = file - origin.
struct LoadedBuilding {
  lod::BuildingInput input;
  io::Vec3d origin{0, 0, 0};  ///< added back to write models in the input frame
  bool is_mesh = false;
};

/// Reads a point cloud (with normals if present) or a mesh (PLY/OBJ/OFF with
/// faces) and centres it on its bbox centre (rounded to the metre). Throws
/// io::IoError.
LoadedBuilding load_building(const std::string& path);

/// Converts a model's triangle mesh / polygons back to the input frame.
io::TriangleMesh to_io_mesh(const lod::TriangleMesh& m, const io::Vec3d& origin);
io::PolygonMesh to_io_polygons(const lod::PolygonMesh& m, const io::Vec3d& origin);

/// JSON report of one building: parameters, counts, timings, models.
nlohmann::json lod_report(const lod::LodResult& r, const lod::LodParams& p, const std::string& input);

/// Writes DIR/model_<step>_<kind>_L<level>.{obj,ply}, DIR/report.json,
/// DIR/params.json and, when dump_planes, DIR/planes.ply (inliers coloured by
/// level set). All files atomically. Returns the list of files written.
/// `extra` fields are added to report.json (e.g. the resume key of a city run).
std::vector<std::string> write_lod_output(const std::string& dir, const lod::LodResult& r,
                                          const lod::LodParams& p, const std::string& input,
                                          const io::Vec3d& origin, bool dump_planes,
                                          const nlohmann::json& extra = nlohmann::json::object());

}  // namespace citylod::tiler
