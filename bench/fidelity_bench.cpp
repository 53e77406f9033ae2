// Fidelity against size (issue 7: "fidelity and speed measured against peers").
//
// For each input, every candidate LOD model of citylod (build_lod_tree with
// the default LodParams) is compared, at the same triangle count, with
//   - meshopt:  meshoptimizer's meshopt_simplify (QEM edge collapse, the
//               simplifier of gltfpack) run on the input mesh as read;
//   - cgal_gh:  CGAL 5.5 Surface_mesh_simplification::edge_collapse with
//               GarlandHeckbert_plane_policies, run on the input made a valid
//               Surface_mesh first (fidelity_cgal.cpp);
//   - peer models given with --peer (e.g. City3D's LoD2 reconstruction), one
//               point each.
// QEM needs a mesh: for point inputs only our curve and the peers are shown.
// Everything is evaluated with lod::evaluate_model against the same input
// (e1 model->input, e2 input->model, RMSE in % of the input's bbox diagonal;
// closed / edge-manifold by exact edge incidence). Output is deterministic:
// markdown tables on stdout, one CSV per input with --out (timings go to
// stderr only).
//
//   fidelity_bench [--out DIR] [--samples N] [INPUT [--crop X0,Y0,Z0,X1,Y1,Z1[,DEG]] [--name NAME]
//                  [--peer LABEL=MODEL]]...
//
// INPUT options apply to the INPUT before them. --crop keeps the triangles
// (points) whose vertices all lie in the box, in the file's coordinates
// rotated by DEG degrees (default 0) about the z axis (see crop()).
// Without INPUT: easy3d_building.off, b9_mesh.off whole, b9_mesh.off cropped
// to its main building, AHN3_13856.ply with City3D's AHN3_13856.obj.
#include "citylod/tiler/bridge.hpp"
#include "fidelity_cgal.hpp"

#include "citylod/io/reader.hpp"
#include "citylod/lod/lod.hpp"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace citylod;

namespace {

struct Peer {
  std::string label, path;
};

struct InputSpec {
  std::string path, name;
  bool crop = false;
  std::array<double, 7>
      box{};  ///< x0 y0 z0 x1 y1 z1 (file coordinates) and the box's rotation about z (degrees)
  std::vector<Peer> peers;
  std::string note;  ///< printed under the input's heading (why it is in the default list)
};

/// One evaluated model, as written to the CSV.
struct Row {
  std::string method;
  int model = -1;  ///< step of our model whose triangle count was the target (-1: peer model)
  std::string kind;
  lod::ModelEvaluation ev;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::array<double, 7> parse_box(const std::string& s) {
  std::array<double, 7> b{};
  std::stringstream in(s);
  std::string item;
  int k = 0;
  while (std::getline(in, item, ',')) {
    if (k >= 7) throw std::invalid_argument("--crop takes 6 or 7 numbers");
    b[std::size_t(k++)] = std::stod(item);
  }
  if (k < 6 || b[0] > b[3] || b[1] > b[4] || b[2] > b[5])
    throw std::invalid_argument("--crop takes X0,Y0,Z0,X1,Y1,Z1[,DEG] with X0<=X1, Y0<=Y1, Z0<=Z1");
  return b;
}

std::string stem(const std::string& path) {
  return fs::path(path).stem().string();
}

/// Keeps the triangles (or points) whose vertices all lie in the box; unused
/// vertices are dropped. The box is given in file coordinates (= local +
/// origin) rotated by b[6] degrees about the z axis: (x, y, z) is inside when
/// (x cos a - y sin a, x sin a + y cos a, z) is in [x0, x1] x [y0, y1] x [z0, z1].
lod::BuildingInput crop(const lod::BuildingInput& in, const io::Vec3d& o,
                        const std::array<double, 7>& b) {
  const double a = b[6] * 3.14159265358979323846 / 180.0, c = std::cos(a), s = std::sin(a);
  auto inside = [&](const lod::Vec3& p) {
    const double x = p.x() + o[0], y = p.y() + o[1], z = p.z() + o[2];
    const double r[3] = {x * c - y * s, x * s + y * c, z};
    for (std::size_t k = 0; k < 3; ++k)
      if (r[k] < b[k] || r[k] > b[k + 3]) return false;
    return true;
  };
  lod::BuildingInput out;
  out.name = in.name;
  std::vector<int> map(in.points.size(), -1);
  auto keep = [&](int i) {
    if (map[std::size_t(i)] < 0) {
      map[std::size_t(i)] = int(out.points.size());
      out.points.push_back(in.points[std::size_t(i)]);
      if (!in.normals.empty()) out.normals.push_back(in.normals[std::size_t(i)]);
    }
    return map[std::size_t(i)];
  };
  if (in.is_mesh()) {
    for (const auto& t : in.triangles)
      if (inside(in.points[std::size_t(t[0])]) && inside(in.points[std::size_t(t[1])]) &&
          inside(in.points[std::size_t(t[2])]))
        out.triangles.push_back({keep(t[0]), keep(t[1]), keep(t[2])});
  } else {
    for (std::size_t i = 0; i < in.points.size(); ++i)
      if (inside(in.points[i])) keep(int(i));
  }
  return out;
}

lod::TriangleMesh as_mesh(const lod::BuildingInput& in) {
  lod::TriangleMesh m;
  m.vertices = in.points;
  m.triangles = in.triangles;
  return m;
}

/// meshopt_simplify to about `target` triangles (error bound lifted: the count decides).
lod::TriangleMesh meshopt_qem(const lod::BuildingInput& in, std::size_t target) {
  std::vector<float> pos;
  pos.reserve(3 * in.points.size());
  for (const auto& p : in.points) {
    pos.push_back(float(p.x()));
    pos.push_back(float(p.y()));
    pos.push_back(float(p.z()));
  }
  std::vector<unsigned> idx;
  idx.reserve(3 * in.triangles.size());
  for (const auto& t : in.triangles)
    for (int v : t) idx.push_back(unsigned(v));
  std::vector<unsigned> out(idx.size());
  float err = 0;
  const std::size_t n =
      meshopt_simplify(out.data(), idx.data(), idx.size(), pos.data(), in.points.size(),
                       3 * sizeof(float), std::max<std::size_t>(3, 3 * target), 1e9f, 0, &err);
  lod::TriangleMesh m;
  m.vertices = in.points;
  for (std::size_t i = 0; i + 2 < n; i += 3)
    m.triangles.push_back({int(out[i]), int(out[i + 1]), int(out[i + 2])});
  return m;
}

/// Largest distance (m) by which a vertex of `m` lies outside the bbox of `in`.
double bbox_excursion(const lod::TriangleMesh& m, const lod::BuildingInput& in) {
  lod::Vec3 lo = in.points.front(), hi = lo;
  for (const auto& p : in.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  double worst = 0;
  for (const auto& v : m.vertices)
    for (int k = 0; k < 3; ++k) worst = std::max({worst, lo[k] - v[k], v[k] - hi[k]});
  return worst;
}

std::string validity(const lod::ModelEvaluation& e) {
  std::string s = e.check.closed ? "closed" : "open";
  if (!e.check.edge_manifold) s += ", non-manifold";
  return s;
}

void write_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << "method,model,kind,triangles,e1,e2,closed,manifold\n";
  char line[256];
  for (const auto& r : rows) {
    std::snprintf(line, sizeof line, "%s,%d,%s,%zu,%.4f,%.4f,%d,%d\n", r.method.c_str(), r.model,
                  r.kind.c_str(), r.ev.triangles, r.ev.e1, r.ev.e2, int(r.ev.check.closed),
                  int(r.ev.check.edge_manifold));
    f << line;
  }
  if (!f.flush()) throw std::runtime_error("cannot write " + path);
}

/// Counts, over our models that the peer could reach (at most 3 % more
/// triangles than ours), how often our e2 is lower; the others are below the
/// peer's floor (it stops when no edge can be collapsed any more).
void print_comparison(const char* label, const std::vector<const Row*>& ours,
                      const std::vector<const Row*>& peer) {
  int wins = 0, reached = 0;
  std::size_t floor = 0;
  double lo = 1e300, hi = 0;
  for (std::size_t i = 0; i < ours.size(); ++i) {
    if (double(peer[i]->ev.triangles) > 1.03 * double(ours[i]->ev.triangles)) {
      floor = floor ? std::min(floor, peer[i]->ev.triangles) : peer[i]->ev.triangles;
      continue;
    }
    ++reached;
    if (ours[i]->ev.e2 < peer[i]->ev.e2) ++wins;
    const double ratio = peer[i]->ev.e2 / std::max(1e-12, ours[i]->ev.e2);
    lo = std::min(lo, ratio);
    hi = std::max(hi, ratio);
  }
  std::printf("- vs %s: at equal triangle count (within 3 %%) our e2 is lower in %d of %d models",
              label, wins, reached);
  if (reached) std::printf(" (%s e2 / our e2 = %.2f .. %.2f)", label, lo, hi);
  if (reached < int(ours.size()))
    std::printf("; %zu of our models are below its floor of %zu triangles",
                ours.size() - std::size_t(reached), floor);
  std::printf("\n");
}

int run_input(const InputSpec& spec, int samples, const std::string& out_dir) {
  const auto t_load = std::chrono::steady_clock::now();
  const tiler::LoadedBuilding loaded = tiler::load_building(spec.path);
  lod::BuildingInput input = spec.crop ? crop(loaded.input, loaded.origin, spec.box) : loaded.input;
  if (input.points.empty()) throw std::runtime_error(spec.path + ": nothing left after --crop");
  const bool mesh = input.is_mesh();

  std::printf("\n### %s\n\n", spec.name.c_str());
  if (!spec.note.empty()) std::printf("- note: %s\n", spec.note.c_str());
  std::printf("- input: `%s`", spec.path.c_str());
  if (spec.crop)
    std::printf(
        ", cropped to the box x' [%g, %g], y' [%g, %g], z [%g, %g] with (x', y') = (x, y) of the "
        "file "
        "rotated by %g degrees about z",
        spec.box[0], spec.box[3], spec.box[1], spec.box[4], spec.box[2], spec.box[5], spec.box[6]);
  if (mesh)
    std::printf(": %zu triangles, %zu vertices (of %zu / %zu in the file)\n",
                input.triangles.size(), input.points.size(), loaded.input.triangles.size(),
                loaded.input.points.size());
  else
    std::printf(": %zu points%s (of %zu in the file)\n", input.points.size(),
                input.normals.empty() ? "" : " with normals", loaded.input.points.size());

  const auto t_lod = std::chrono::steady_clock::now();
  const lod::LodParams params;  // defaults (the paper's), including the 120 s time budget
  const lod::LodResult r = lod::build_lod_tree(input, params);
  const double s_lod = seconds_since(t_lod);
  std::printf(
      "- LOD engine (default parameters): status %s%s%s, %zu candidate models, bbox diagonal %.1f "
      "m\n",
      lod::to_string(r.status), r.reason.empty() ? "" : ": ", r.reason.c_str(), r.models.size(),
      r.stats.bbox_diagonal);
  for (const auto& n : r.stats.notes) std::printf("- engine note: %s\n", n.c_str());
  if (!r.models.empty()) {
    double worst = 0;
    for (const auto& m : r.models) worst = std::max(worst, bbox_excursion(m.mesh, input));
    std::printf("- our models reach at most %.2f m outside the input's bbox\n", worst);
  }

  std::vector<Row> rows;
  double s_meshopt = 0, s_cgal = 0, s_eval = 0;
  std::unique_ptr<bench::GhSimplifier> gh;
  if (mesh) {
    const auto t = std::chrono::steady_clock::now();
    gh = std::make_unique<bench::GhSimplifier>(as_mesh(input));
    s_cgal += seconds_since(t);
    const bench::GhRepairStats& g = gh->stats();
    std::printf(
        "- CGAL input repair: repair_polygon_soup %zu -> %zu triangles, %zu -> %zu points; "
        "orient_polygon_soup %s (%zu points after); Surface_mesh %zu faces, %zu vertices "
        "(%zu non-manifold vertices split): **%zu triangles lost**\n",
        g.input_triangles, g.soup_polygons, g.input_vertices, g.soup_points,
        g.oriented_without_duplication ? "without duplicating points" : "duplicated points",
        g.oriented_points, g.mesh_faces, g.mesh_vertices, g.nonmanifold_vertices_split,
        g.lost_triangles);
  }

  for (const auto& m : r.models) {
    const std::size_t target = m.mesh.triangles.size();
    const std::string kind = lod::to_string(m.kind);
    auto t = std::chrono::steady_clock::now();
    rows.push_back({"ours", m.step, kind, lod::evaluate_model(m.mesh, input, samples)});
    s_eval += seconds_since(t);
    if (!mesh) continue;
    t = std::chrono::steady_clock::now();
    const lod::TriangleMesh q = meshopt_qem(input, target);
    s_meshopt += seconds_since(t);
    t = std::chrono::steady_clock::now();
    rows.push_back({"meshopt", m.step, kind, lod::evaluate_model(q, input, samples)});
    s_eval += seconds_since(t);
    t = std::chrono::steady_clock::now();
    const lod::TriangleMesh c = gh->simplify(target);
    s_cgal += seconds_since(t);
    t = std::chrono::steady_clock::now();
    rows.push_back({"cgal_gh", m.step, kind, lod::evaluate_model(c, input, samples)});
    s_eval += seconds_since(t);
  }
  for (const auto& p : spec.peers) {
    const lod::TriangleMesh model = tiler::to_lod_mesh(io::read_mesh(p.path), loaded.origin);
    rows.push_back({p.label, -1, "peer", lod::evaluate_model(model, input, samples)});
    std::printf("- peer model %s: `%s`\n", p.label.c_str(), p.path.c_str());
  }

  // Markdown table: one line per candidate of ours, peers at the end.
  std::printf("\n");
  if (mesh) {
    std::printf(
        "| model | kind | triangles | ours e1 %% | ours e2 %% | ours | meshopt tris | meshopt e1 "
        "%% | "
        "meshopt e2 %% | meshopt | CGAL GH tris | CGAL GH e1 %% | CGAL GH e2 %% | CGAL GH |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  } else {
    std::printf(
        "| model | kind | triangles | e1 %% | e2 %% | validity |\n|---|---|---|---|---|---|\n");
  }
  std::vector<const Row*> ours, qem, cgal;
  for (const auto& row : rows) {
    if (row.method == "ours") ours.push_back(&row);
    if (row.method == "meshopt") qem.push_back(&row);
    if (row.method == "cgal_gh") cgal.push_back(&row);
  }
  for (std::size_t i = 0; i < ours.size(); ++i) {
    const Row& o = *ours[i];
    std::printf("| %d | %s | %zu | %.3f | %.3f | %s |", o.model, o.kind.c_str(), o.ev.triangles,
                o.ev.e1, o.ev.e2, validity(o.ev).c_str());
    if (mesh)
      for (const Row* p : {qem[i], cgal[i]})
        std::printf(" %zu | %.3f | %.3f | %s |", p->ev.triangles, p->ev.e1, p->ev.e2,
                    validity(p->ev).c_str());
    std::printf("\n");
  }
  for (const auto& row : rows) {
    if (row.model >= 0) continue;
    std::printf(
        "| %s | peer | %zu | %.3f | %.3f | %s |", row.method.c_str(), row.ev.triangles, row.ev.e1,
        row.ev.e2,
        (validity(row.ev) + (row.ev.check.self_intersecting ? ", self-intersecting" : "")).c_str());
    if (mesh) std::printf(" | | | | | | | |");
    std::printf("\n");
  }
  std::printf("\n");
  if (mesh && !ours.empty()) {
    print_comparison("meshopt", ours, qem);
    print_comparison("CGAL GH", ours, cgal);
  }
  for (const auto& row : rows) {
    if (row.model >= 0) continue;
    int better = 0;
    std::size_t fewest = 0;
    for (const Row* o : ours)
      if (o->ev.e2 <= row.ev.e2) {
        ++better;
        if (fewest == 0 || o->ev.triangles < fewest) fewest = o->ev.triangles;
      }
    std::printf(
        "- vs %s (%zu triangles, e2 %.3f %%): %d of our %zu models have an e2 as low or lower",
        row.method.c_str(), row.ev.triangles, row.ev.e2, better, ours.size());
    if (better) std::printf(", the smallest with %zu triangles", fewest);
    std::printf("\n");
  }
  std::fflush(stdout);

  if (!out_dir.empty()) write_csv((fs::path(out_dir) / (spec.name + ".csv")).string(), rows);
  std::fprintf(stderr,
               "fidelity_bench: %s: LOD engine %.2f s, meshopt %.2f s, CGAL repair + GH %.2f s, "
               "evaluation %.2f s, "
               "total %.2f s\n",
               spec.name.c_str(), s_lod, s_meshopt, s_cgal, s_eval, seconds_since(t_load));
  return 0;
}

[[noreturn]] void usage(const char* msg) {
  std::fprintf(stderr,
               "fidelity_bench: %s\nusage: fidelity_bench [--out DIR] [--samples N] [INPUT [--crop "
               "X0,Y0,Z0,X1,Y1,Z1[,DEG]] [--name NAME] [--peer LABEL=MODEL]]...\n",
               msg);
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir;
  int samples = 5000;
  std::vector<InputSpec> inputs;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) usage((a + " needs a value").c_str());
        return argv[++i];
      };
      auto last = [&]() -> InputSpec& {
        if (inputs.empty()) usage((a + " must follow an INPUT").c_str());
        return inputs.back();
      };
      if (a == "--out")
        out_dir = value();
      else if (a == "--samples")
        samples = std::stoi(value());
      else if (a == "--crop") {
        const std::string v = value();
        last().crop = true;
        last().box = parse_box(v);
      } else if (a == "--name") {
        const std::string v = value();
        last().name = v;
      } else if (a == "--peer") {
        const std::string v = value();
        const auto eq = v.find('=');
        if (eq == std::string::npos || eq == 0) usage("--peer takes LABEL=MODEL");
        last().peers.push_back({v.substr(0, eq), v.substr(eq + 1)});
      } else if (a == "--help" || a == "-h") {
        usage(
            "fidelity of our LOD models vs QEM (meshoptimizer, CGAL Garland-Heckbert) at equal "
            "triangle counts");
      } else if (!a.empty() && a[0] == '-') {
        usage(("unknown option " + a).c_str());
      } else {
        inputs.push_back({a, stem(a), false, {}, {}, {}});
      }
    }
  } catch (const std::invalid_argument& e) {
    usage(e.what());
  }
  if (samples < 1) usage("--samples must be >= 1");
  if (inputs.empty()) {
    const std::string d = CITYLOD_SHARED_DATA;
    inputs.push_back({d + "/noisy_mesh/easy3d_building.off",
                      "easy3d_building",
                      false,
                      {},
                      {},
                      "one building with a terrain sheet (~15 % of its area)"});
    inputs.push_back(
        {d + "/urban_block_b9/b9_mesh.off",
         "b9_mesh",
         false,
         {},
         {},
         "the whole urban block (terrain, several buildings, trees) as ONE input: the engine "
         "models "
         "one building, so it makes one solid of the block; see b9_mesh_crop for a building"});
    // The main (A-shaped) building of the block: its box in the frame of its
    // walls (rotated 22 degrees about z), above the ground and the lower walls
    // (ground at z -12..-8, roofs at 0..5).
    inputs.push_back(
        {d + "/urban_block_b9/b9_mesh.off",
         "b9_mesh_crop",
         true,
         {-28, -46, -3, 31, 45, 20, 22},
         {},
         "the block's main (A-shaped) building: its box in the frame of its walls, z >= -3 m "
         "(drops the ground at -12..-8 m, the neighbouring buildings and the lower walls; keeps "
         "the tree tops of its courtyard)"});
    inputs.push_back(
        {d + "/ahn3_building_lod2/AHN3_13856.ply",
         "AHN3_13856",
         false,
         {},
         {{"City3D", d + "/ahn3_building_lod2/AHN3_13856.obj"}},
         "airborne LiDAR points (no QEM on points); City3D's LoD2 model of the same building"});
  }
  if (!out_dir.empty()) fs::create_directories(out_dir);
  std::printf(
      "Fidelity against size: our candidate models (build_lod_tree, default LodParams) vs "
      "meshoptimizer "
      "meshopt_simplify and CGAL %s Garland-Heckbert edge collapse at the same triangle counts; "
      "lod::evaluate_model with %d samples per side, e1/e2 in %% of the input's bbox diagonal.\n",
      bench::cgal_version(), samples);
  int status = 0;
  for (const auto& in : inputs) {
    try {
      run_input(in, samples, out_dir);
    } catch (const std::exception& e) {
      std::printf("\n### %s\n\nFAILED: %s\n", in.name.c_str(), e.what());
      std::fprintf(stderr, "fidelity_bench: %s: %s\n", in.name.c_str(), e.what());
      status = 1;
    }
  }
  return status;
}
