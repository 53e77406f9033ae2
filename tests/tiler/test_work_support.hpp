// Work directories of synthetic buildings (a manifest and lod/<id>/report.json
// with the models of test_assemble_support.hpp) for the tiler's tests.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "citylod/tiler/workdir.hpp"
#include "tiler/test_assemble_support.hpp"

namespace citylod::test {

inline tiler::Manifest synthetic_manifest(double lon = 4.3571, double lat = 52.0116,
                                          double h = 45.0) {
  tiler::Manifest m;
  m.scene.crs = "";
  m.scene.origin_lon = lon;
  m.scene.origin_lat = lat;
  m.scene.origin_h = h;
  return m;
}

/// Writes WORK/manifest.json and WORK/lod/<id>/{report.json, model_*.ply}.
inline void write_work(const std::string& work, tiler::Manifest man,
                       const std::vector<SynthBuilding>& bs) {
  fs::create_directories(work);
  man.chunks.clear();
  for (const auto& b : bs) {
    tiler::ChunkRecord r;
    r.id = b.id;
    r.origin = b.origin;
    io::BBox3 box;
    for (const auto& m : b.models)
      for (const auto& v : m.mesh.vertices)
        box.add(Vec3d{v[0] + b.origin[0], v[1] + b.origin[1], v[2] + b.origin[2]});
    if (!box.empty()) {
      r.bbox_min = box.min;
      r.bbox_max = box.max;
    }
    r.status = tiler::Status::ok;
    man.chunks.push_back(r);
    const std::string dir = tiler::lod_dir(work, b.id);
    fs::create_directories(dir);
    nlohmann::json models = nlohmann::json::array();
    for (const auto& m : b.models) {
      char name[64];
      std::snprintf(name, sizeof name, "model_%02d_%s_L%d.ply", m.step, m.kind.c_str(), m.level);
      io::write_ply((fs::path(dir) / name).string(), m.mesh);
      models.push_back({{"file", name},
                        {"kind", m.kind},
                        {"level", m.level},
                        {"step", m.step},
                        {"triangles", m.mesh.triangles.size()}});
    }
    if (b.write_report) {
      nlohmann::json rep{{"input", "synthetic"}, {"status", "ok"}, {"models", models}};
      io::atomic_write_file((fs::path(dir) / "report.json").string(), rep.dump(2));
    }
  }
  tiler::write_manifest(work, man);
}

// ------------------------------------------------------------ glb reading (independent of io/)

}  // namespace citylod::test
