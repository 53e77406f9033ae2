// citylod vs 3DBAG's roofer on the same airborne LiDAR + footprints.
//
//   roofer_bench WORK ROOFER.city.jsonl [--csv FILE] [--roofer-obj DIR]
//
// WORK is the work directory of a `citylod tile` run (manifest, chunks, LOD
// reports and models); ROOFER.city.jsonl roofer's CityJSONSeq output for the
// same LAS and footprints. Buildings are matched by footprint id (the chunk's
// source "footprint:<id>" = the roofer feature id). Every model is measured
// against the same points, the building's chunk (its LiDAR points as the split
// assigned them):
//   - rmse: RMSE of the points to the model surface (m),
//   - roof: vertical RMSE of the points more than 1 m inside the footprint to
//     the model's highest surface above or below them (m),
//   - triangles, and validity: closed, oriented, no pinched vertex, one shell,
//     no self-intersection (exact incidence, lod::check_mesh),
//   - overfill: share of those roof points more than 1 m under the model's top
//     surface (a lower roof part filled up; > 20 % counts the building).
// For citylod: the finest model (last anchor), the coarsest (first model) and
// at each roofer LoD's triangle count the best of our candidates with at most
// that many triangles. Prints one row per building and a summary with medians
// and win counts. Times: roofer's rf_t_run (ms per building) and citylod's
// LOD time per building (report.json timings).
#include "citylod/geo/crs.hpp"
#include "citylod/geo/georef.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/types.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/lod/lod.hpp"
#include "citylod/lod/polygon2d.hpp"
#include "citylod/tiler/scene_georef.hpp"
#include "citylod/tiler/workdir.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

using namespace citylod;
using json = nlohmann::json;

namespace {

struct Measure {
  bool present = false;
  std::size_t triangles = 0;
  double rmse = NAN, roof = NAN;
  double overfill = NAN;  ///< share of the roof points more than 1 m under the model's top
  bool valid = false;
  int pinched = 0, shells = 0;
};

struct Building {
  std::string id;
  std::size_t points = 0;
  Measure finest, coarsest;
  std::vector<Measure> ours;  // every candidate, coarse to fine
  Measure rf[3];              // roofer LoD1.2, 1.3, 2.2
  Measure budget[3];          // our best candidate within roofer's triangle count
  double t_ours_ms = NAN, t_roofer_ms = NAN;
  int roof_planes = 0;
  double roof_height = NAN;  ///< roofer's rf_h_roof_70p - rf_h_ground (m)
  std::string status;
};

const char* kLods[3] = {"1.2", "1.3", "2.2"};

/// The q-quantile (0..1) of the finite values, by linear interpolation.
double quantile(std::vector<double> v, double q) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double at = q * double(v.size() - 1);
  const std::size_t i = std::size_t(at);
  return i + 1 < v.size() ? v[i] + (at - double(i)) * (v[i + 1] - v[i]) : v[i];
}

double median(std::vector<double> v) {
  return quantile(std::move(v), 0.5);
}

/// Vertical RMSE of the roof points (more than 1 m inside the outline) to the
/// model: the model surface nearest in z on the vertical through the point; a
/// point over no model surface counts with its height above the model's base.
struct RoofFit {
  double rmse = NAN;
  double overfill = NAN;
};
RoofFit roof_rmse(const lod::TriangleMesh& m, const std::vector<lod::Vec3>& pts,
                  const std::vector<lod::Vec2>& outline) {
  double zmin = std::numeric_limits<double>::infinity();
  for (const auto& v : m.vertices) zmin = std::min(zmin, v.z());
  // Non-vertical triangles with their xy boxes.
  struct T {
    lod::Vec3 a, b, c;
    double x0, x1, y0, y1;
  };
  std::vector<T> tris;
  for (const auto& t : m.triangles) {
    const lod::Vec3 &a = m.vertices[size_t(t[0])], &b = m.vertices[size_t(t[1])],
                    &c = m.vertices[size_t(t[2])];
    const double nz = (b - a).cross(c - a).z();
    if (std::abs(nz) < 1e-9) continue;
    tris.push_back({a, b, c, std::min({a.x(), b.x(), c.x()}), std::max({a.x(), b.x(), c.x()}),
                    std::min({a.y(), b.y(), c.y()}), std::max({a.y(), b.y(), c.y()})});
  }
  double sum = 0;
  std::size_t n = 0, over = 0;
  for (const auto& p : pts) {
    const lod::Vec2 q(p.x(), p.y());
    if (outline.size() < 3 || !poly2::point_in_ring(outline, q)) continue;
    if (poly2::distance_to_ring(outline, q) <= 1.0) continue;
    double best = std::numeric_limits<double>::infinity();
    double top = -std::numeric_limits<double>::infinity();
    for (const auto& t : tris) {
      if (q.x() < t.x0 || q.x() > t.x1 || q.y() < t.y0 || q.y() > t.y1) continue;
      // Barycentric in xy.
      const double d =
          (t.b.y() - t.c.y()) * (t.a.x() - t.c.x()) + (t.c.x() - t.b.x()) * (t.a.y() - t.c.y());
      const double l1 =
          ((t.b.y() - t.c.y()) * (q.x() - t.c.x()) + (t.c.x() - t.b.x()) * (q.y() - t.c.y())) / d;
      const double l2 =
          ((t.c.y() - t.a.y()) * (q.x() - t.c.x()) + (t.a.x() - t.c.x()) * (q.y() - t.c.y())) / d;
      const double l3 = 1 - l1 - l2;
      const double eps = -1e-9;
      if (l1 < eps || l2 < eps || l3 < eps) continue;
      const double z = l1 * t.a.z() + l2 * t.b.z() + l3 * t.c.z();
      if (z <= zmin + 1e-6) continue;  // the base
      top = std::max(top, z);
      if (std::abs(p.z() - z) < std::abs(best)) best = p.z() - z;
    }
    if (!std::isfinite(best)) best = p.z() - zmin;
    sum += best * best;
    over += top > p.z() + 1.0;
    ++n;
  }
  if (n == 0) return {};
  return {std::sqrt(sum / double(n)), double(over) / double(n)};
}

Measure measure(const lod::TriangleMesh& m, const lod::BuildingInput& ref,
                const std::vector<lod::Vec2>& outline) {
  Measure r;
  r.present = true;
  r.triangles = m.triangles.size();
  const lod::ModelEvaluation ev =
      lod::evaluate_model(m, ref, int(std::max<std::size_t>(20000, ref.points.size())));
  r.rmse = ev.e2 * ev.diagonal / 100.0;
  const RoofFit rf = roof_rmse(m, ref.points, outline);
  r.roof = rf.rmse;
  r.overfill = rf.overfill;
  r.valid = ev.check.valid();
  r.pinched = ev.check.pinched_vertices;
  r.shells = ev.check.shells;
  return r;
}

lod::TriangleMesh to_lod(const io::TriangleMesh& m) {
  lod::TriangleMesh out;
  out.vertices.reserve(m.vertices.size());
  for (const auto& v : m.vertices) out.vertices.emplace_back(v[0], v[1], v[2]);
  for (const auto& t : m.triangles) out.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
  return out;
}

/// roofer's features by id: the Solid of each LoD (in the scene frame), attributes.
struct RooferBuilding {
  io::PolygonMesh lod[3];
  double t_run_ms = NAN;
  int roof_planes = 0;
  double roof_height = NAN;  ///< roofer's rf_h_roof_70p - rf_h_ground (m)
};

std::map<std::string, RooferBuilding> read_roofer(const std::string& path,
                                                  const tiler::SceneGeoref& scene,
                                                  int& skipped_holes) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open");
  std::string line;
  if (!std::getline(f, line)) throw std::runtime_error(path + ": empty");
  const json meta = json::parse(line);
  const auto& sc = meta.at("transform").at("scale");
  const auto& tr = meta.at("transform").at("translate");
  std::map<std::string, RooferBuilding> out;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    const json feat = json::parse(line);
    const std::string id = feat.at("id");
    RooferBuilding b;
    std::vector<io::Vec3d> verts;
    for (const auto& v : feat.at("vertices")) {
      const Eigen::Vector3d crs(v[0].get<double>() * sc[0].get<double>() + tr[0].get<double>(),
                                v[1].get<double>() * sc[1].get<double>() + tr[1].get<double>(),
                                v[2].get<double>() * sc[2].get<double>() + tr[2].get<double>());
      Eigen::Matrix3Xd e = crs;
      scene.from_crs(e);  // to the chunks' frame
      verts.push_back({e(0, 0), e(1, 0), e(2, 0)});
    }
    bool any = false;
    for (const auto& [oid, obj] : feat.at("CityObjects").items()) {
      if (obj.contains("attributes")) {
        const auto& a = obj["attributes"];
        if (a.contains("rf_t_run") && a["rf_t_run"].is_number())
          b.t_run_ms = a["rf_t_run"].get<double>();
        if (a.contains("rf_roof_planes") && a["rf_roof_planes"].is_number())
          b.roof_planes = a["rf_roof_planes"].get<int>();
        if (a.contains("rf_h_roof_70p") && a["rf_h_roof_70p"].is_number() &&
            a.contains("rf_h_ground") && a["rf_h_ground"].is_number())
          b.roof_height = a["rf_h_roof_70p"].get<double>() - a["rf_h_ground"].get<double>();
      }
      if (!obj.contains("geometry")) continue;
      for (const auto& geom : obj["geometry"]) {
        if (geom.at("type") != "Solid") continue;
        const std::string lod =
            geom.at("lod").is_string() ? geom["lod"].get<std::string>() : geom["lod"].dump();
        int k = -1;
        for (int i = 0; i < 3; ++i)
          if (lod == kLods[i]) k = i;
        if (k < 0) continue;
        io::PolygonMesh& pm = b.lod[k];
        pm.vertices = verts;
        for (const auto& shell : geom.at("boundaries"))
          for (const auto& surface : shell) {
            if (surface.size() > 1) ++skipped_holes;  // inner rings are not triangulated
            std::vector<std::uint32_t> ring;
            for (const auto& vi : surface[0]) ring.push_back(vi.get<std::uint32_t>());
            pm.faces.push_back(std::move(ring));
          }
        any = true;
      }
    }
    if (any) out[id] = std::move(b);
  }
  return out;
}

/// Removes vertices no face uses and renumbers (roofer's vertex list is the
/// feature's, shared by all its LoDs).
io::PolygonMesh compact(const io::PolygonMesh& m) {
  io::PolygonMesh out;
  std::vector<std::int64_t> map(m.vertices.size(), -1);
  for (const auto& f : m.faces) {
    std::vector<std::uint32_t> nf;
    for (auto v : f) {
      if (map[v] < 0) {
        map[v] = std::int64_t(out.vertices.size());
        out.vertices.push_back(m.vertices[v]);
      }
      nf.push_back(std::uint32_t(map[v]));
    }
    out.faces.push_back(std::move(nf));
  }
  return out;
}

void print_measure(const Measure& m) {
  if (!m.present) {
    std::printf(" %5s %6s %6s %3s", "-", "-", "-", "-");
    return;
  }
  std::printf(" %5zu %6.3f %6.3f %3s", m.triangles, m.rmse, m.roof, m.valid ? "ok" : "BAD");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: roofer_bench WORK ROOFER.city.jsonl [--csv FILE] [--roofer-obj DIR]\n"
                 "  --roofer-obj DIR  also write roofer's LoD2.2 of each building as DIR/ID.obj "
                 "in its chunk's frame (the frame of citylod's models)\n");
    return 2;
  }
  const std::string work = argv[1], roofer_path = argv[2];
  std::string csv_path, obj_dir;
  for (int i = 3; i + 1 < argc; ++i) {
    if (std::string(argv[i]) == "--csv") csv_path = argv[i + 1];
    if (std::string(argv[i]) == "--roofer-obj") obj_dir = argv[i + 1];
  }
  try {
    const tiler::Manifest man = tiler::read_manifest(work);
    int holes = 0, no_chunk = 0;
    const tiler::SceneGeoref scene(man, work);
    const auto roofer = read_roofer(roofer_path, scene, holes);
    std::vector<Building> rows;
    for (const auto& c : man.chunks) {
      const std::string prefix = "footprint:";
      if (c.source.rfind(prefix, 0) != 0) continue;
      const std::string fid = c.source.substr(prefix.size());
      const auto rf = roofer.find(fid);
      if (rf == roofer.end()) continue;  // roofer made no model (too few points)
      if (c.skipped()) {  // no points of ours on this footprint: no chunk to measure against
        ++no_chunk;
        continue;
      }
      Building b;
      b.id = fid;
      b.t_roofer_ms = rf->second.t_run_ms;
      b.roof_planes = rf->second.roof_planes;
      b.roof_height = rf->second.roof_height;
      const lod::Vec3 o(c.origin[0], c.origin[1], c.origin[2]);
      lod::BuildingInput ref;
      for (const auto& p : io::read_points(tiler::chunk_path(work, c.id)).positions)
        ref.points.emplace_back(p[0], p[1], p[2]);
      if (ref.points.empty()) continue;
      b.points = ref.points.size();
      std::vector<lod::Vec2> outline;
      for (const auto& q : c.outline) outline.emplace_back(q[0] - o.x(), q[1] - o.y());
      // roofer's models in the chunk frame.
      for (int k = 0; k < 3; ++k) {
        if (rf->second.lod[k].faces.empty()) continue;
        io::PolygonMesh pm = compact(rf->second.lod[k]);
        for (auto& v : pm.vertices) v = {v[0] - o.x(), v[1] - o.y(), v[2] - o.z()};
        b.rf[k] = measure(to_lod(io::triangulate_polygons(pm)), ref, outline);
        if (k == 2 && !obj_dir.empty()) io::write_obj(obj_dir + "/" + fid + ".obj", pm);
      }
      // Ours (the work directory's typed report).
      const std::string dir = tiler::lod_dir(work, c.id);
      const auto rep = tiler::find_lod_report(work, c.id);
      if (!rep) {
        b.status = "no-lod";
        rows.push_back(std::move(b));
        continue;
      }
      b.status = lod::to_string(rep->status);
      double t = 0;
      for (const auto& [k, v] : rep->timings_s) t += v;
      b.t_ours_ms = 1000.0 * t;
      int finest = -1;
      const auto& models = rep->all_models();
      for (std::size_t i = 0; i < models.size(); ++i) {
        const auto& mr = models[i];
        const std::string file =
            mr.file.empty() || mr.file[0] == '/' ? mr.file : dir + "/" + mr.file;
        const lod::TriangleMesh m = to_lod(io::read_mesh(file));
        b.ours.push_back(measure(m, ref, outline));
        if (tiler::is_anchor(mr.kind)) finest = int(i);
      }
      if (!b.ours.empty()) {
        b.coarsest = b.ours.front();
        b.finest = b.ours[size_t(std::max(0, finest))];
      }
      for (int k = 0; k < 3; ++k) {
        if (!b.rf[k].present) continue;
        for (const auto& m : b.ours)
          if (m.triangles <= b.rf[k].triangles &&
              (!b.budget[k].present || m.rmse < b.budget[k].rmse))
            b.budget[k] = m;
      }
      rows.push_back(std::move(b));
    }
    std::sort(rows.begin(), rows.end(),
              [](const Building& a, const Building& b) { return a.id < b.id; });

    std::printf("%-40s %6s %3s | %-27s| %-27s| %-27s| %-27s| %-27s| %7s %7s\n",
                "building (footprint id)", "points", "rp", "citylod finest (tri rmse roof ok)",
                "citylod coarsest", "roofer LoD1.2", "roofer LoD1.3", "roofer LoD2.2", "ms ours",
                "ms rf");
    for (const auto& b : rows) {
      std::printf("%-40.40s %6zu %3d |", b.id.c_str(), b.points, b.roof_planes);
      print_measure(b.finest);
      std::printf(" |");
      print_measure(b.coarsest);
      for (int k = 0; k < 3; ++k) {
        std::printf(" |");
        print_measure(b.rf[k]);
      }
      std::printf(" | %7.1f %7.1f\n", b.t_ours_ms, b.t_roofer_ms);
    }
    auto col = [&](auto get) {
      std::vector<double> v;
      for (const auto& b : rows) v.push_back(get(b));
      return v;
    };
    std::printf(
        "\nbuildings compared: %zu (roofer inner rings skipped: %d; footprints roofer modelled "
        "that have no points in the split, not compared: %d)\n",
        rows.size(), holes, no_chunk);
    std::printf("%-22s %10s %10s %10s %10s %10s %12s\n", "model", "rmse med", "rmse p90",
                "roof med", "roof p90", "tri med", "valid");
    auto summary = [&](const char* name, auto get) {
      std::vector<double> r, h, t;
      int valid = 0, n = 0;
      for (const auto& b : rows) {
        const Measure& m = get(b);
        if (!m.present) continue;
        ++n;
        valid += m.valid;
        r.push_back(m.rmse);
        h.push_back(m.roof);
        t.push_back(double(m.triangles));
      }
      std::printf("%-22s %10.3f %10.3f %10.3f %10.3f %10.0f %6d/%-5d\n", name, median(r),
                  quantile(r, 0.9), median(h), quantile(h, 0.9), median(t), valid, n);
    };
    summary("citylod finest", [](const Building& b) -> const Measure& { return b.finest; });
    summary("citylod coarsest", [](const Building& b) -> const Measure& { return b.coarsest; });
    summary("roofer LoD1.2", [](const Building& b) -> const Measure& { return b.rf[0]; });
    summary("roofer LoD1.3", [](const Building& b) -> const Measure& { return b.rf[1]; });
    summary("roofer LoD2.2", [](const Building& b) -> const Measure& { return b.rf[2]; });
    {
      std::map<std::string, int> by_status;
      for (const auto& b : rows) ++by_status[b.status];
      std::printf("citylod status of the buildings roofer models:");
      for (const auto& [k, v] : by_status) std::printf(" %s %d", k.c_str(), v);
      std::printf("\n");
      // roofer's own roof height (70th percentile above its ground) under
      // 0.3 m: a patch at the ground's level for roofer too.
      int low = 0, fallbacks = 0;
      for (const auto& b : rows)
        if (b.status == "fallback") {
          ++fallbacks;
          low += b.roof_height < 0.3;
        }
      std::printf(
          "citylod fallbacks where roofer's roof lies under 0.3 m above its ground: %d of %d\n",
          low, fallbacks);
    }
    int all_models = 0, all_valid = 0, pinched = 0, multi = 0;
    for (const auto& b : rows)
      for (const auto& m : b.ours) {
        ++all_models;
        all_valid += m.valid;
        pinched += m.pinched > 0;
        multi += m.shells != 1;
      }
    std::printf("citylod, all models: %d/%d valid (%d with pinched vertices, %d not one shell)\n",
                all_valid, all_models, pinched, multi);
    auto wins = [&](const char* what, auto ours, auto theirs) {
      int w = 0, n = 0;
      for (const auto& b : rows) {
        const Measure& t = theirs(b);
        if (!t.present) continue;
        ++n;
        const Measure& o = ours(b);
        w += o.present && o.rmse < t.rmse;
      }
      std::printf("  %-52s %3d of %d\n", what, w, n);
    };
    std::printf("wins (lower points->model RMSE):\n");
    wins(
        "finest vs roofer LoD2.2", [](const Building& b) -> const Measure& { return b.finest; },
        [](const Building& b) -> const Measure& { return b.rf[2]; });
    wins(
        "coarsest vs roofer LoD1.2", [](const Building& b) -> const Measure& { return b.coarsest; },
        [](const Building& b) -> const Measure& { return b.rf[0]; });
    for (int k = 0; k < 3; ++k) {
      const std::string what =
          std::string("best candidate <= roofer LoD") + kLods[k] + "'s triangles";
      wins(
          what.c_str(), [k](const Building& b) -> const Measure& { return b.budget[k]; },
          [k](const Building& b) -> const Measure& { return b.rf[k]; });
    }
    {
      int w = 0, n = 0;
      for (const auto& b : rows)
        if (b.finest.present && b.rf[2].present && std::isfinite(b.rf[2].roof)) {
          ++n;
          w += b.finest.roof < b.rf[2].roof;
        }
      std::printf("  %-52s %3d of %d\n", "finest vs roofer LoD2.2 (roof height RMSE)", w, n);
    }
    {
      // Lower roof parts filled up: > 20 % of the roof points more than 1 m
      // under the model's top surface.
      int ours = 0, theirs = 0, n = 0;
      for (const auto& b : rows)
        if (b.finest.present && b.rf[2].present) {
          ++n;
          ours += b.finest.overfill > 0.2;
          theirs += b.rf[2].overfill > 0.2;
        }
      std::printf(
          "overfilled (> 20 %% of roof points > 1 m under the model): citylod finest %d, "
          "roofer LoD2.2 %d of %d\n",
          ours, theirs, n);
    }
    std::printf("LOD time per building, median: citylod %.1f ms, roofer %.1f ms\n",
                median(col([](const Building& b) { return b.t_ours_ms; })),
                median(col([](const Building& b) { return b.t_roofer_ms; })));
    std::printf(
        "ratios of medians: finest rmse / roofer LoD2.2 = %.3f, finest roof / roofer LoD2.2 = "
        "%.3f, "
        "coarsest rmse / roofer LoD1.2 = %.3f\n",
        median(col([](const Building& b) { return b.finest.rmse; })) /
            median(col([](const Building& b) { return b.rf[2].rmse; })),
        median(col([](const Building& b) { return b.finest.roof; })) /
            median(col([](const Building& b) { return b.rf[2].roof; })),
        median(col([](const Building& b) { return b.coarsest.rmse; })) /
            median(col([](const Building& b) { return b.rf[0].rmse; })));
    if (!csv_path.empty()) {
      std::ofstream csv(csv_path);
      csv << "id,points,finest_tri,finest_rmse,finest_roof,finest_valid,coarsest_tri,coarsest_rmse,"
             "coarsest_roof,finest_overfill";
      for (int k = 0; k < 3; ++k)
        csv << ",rf" << kLods[k] << "_tri,rf" << kLods[k] << "_rmse,rf" << kLods[k] << "_roof";
      csv << ",rf2.2_overfill,ms_ours,ms_roofer,status\n";
      for (const auto& b : rows) {
        csv << b.id << ',' << b.points << ',' << b.finest.triangles << ',' << b.finest.rmse << ','
            << b.finest.roof << ',' << b.finest.valid << ',' << b.coarsest.triangles << ','
            << b.coarsest.rmse << ',' << b.coarsest.roof << ',' << b.finest.overfill;
        for (int k = 0; k < 3; ++k)
          csv << ',' << b.rf[k].triangles << ',' << b.rf[k].rmse << ',' << b.rf[k].roof;
        csv << ',' << b.rf[2].overfill << ',' << b.t_ours_ms << ',' << b.t_roofer_ms << ','
            << b.status << '\n';
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "roofer_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
