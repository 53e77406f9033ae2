// mesh_city_bench: how well `citylod split` cuts the photogrammetry city mesh
// ../shared/data/mesh_city into buildings, against its per-triangle truth labels.
//
//   mesh_city_bench WORK [--data DIR] [--rmse]
//
// WORK is the work directory of a split (or DIR/work of `citylod tile`) of
// DIR/scene.ply with --crs "$(cat DIR/crs_local.wkt)". Every chunk triangle is
// matched to its scene triangle (scene vertices taken to the split's ENU frame with
// the manifest's CRS and origin; chunk centroid + chunk origin, nearest scene centroid
// within 1 cm). Prints, per footprint chunk (building of buildings.csv):
//   kept       share of the building's true roof + wall triangles inside its chunk
//   precision  share of the chunk's triangles that are the building's (the rest:
//              another building / terrain / tree)
// and their medians; for chunks without footprint, the true label holding most of
// each chunk's triangles (building rows merged into it, tree, terrain), the number
// of tree crowns that became chunks and of buildings on their own. With --rmse
// (and LOD output in WORK/lod) also the finest model's RMSE against truth/<id>.obj,
// model -> truth and truth -> model, in metres.
// MESH_CITY_BENCH_DUMP=1 also prints every lost face (scene index, kind, where it went,
// its vertices in the local frame) to stderr. MESH_CITY_BENCH_KEEP=1 keeps the finest
// models and truth lattices it measures (TMP/mesh_city_bench_[ref_]ID.ply, local frame).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "citylod/geo/crs.hpp"
#include "citylod/geo/georef.hpp"
#include "citylod/geo/vertical.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/tiler/eval.hpp"
#include "citylod/tiler/scene_georef.hpp"
#include "citylod/tiler/workdir.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Truth {
  std::vector<int> building;       ///< per scene triangle: buildings.csv index, -1, -2
  std::vector<std::uint8_t> kind;  ///< 0 terrain 1 roof 2 wall 3 crown 4 trunk
  std::vector<std::string> id;     ///< per buildings.csv index: gml id
};

Truth read_truth(const std::string& dir, std::size_t n) {
  Truth t;
  std::ifstream f(dir + "/scene_face_labels.bin", std::ios::binary);
  t.building.resize(n);
  t.kind.resize(n);
  std::vector<std::int32_t> b(n);
  f.read(reinterpret_cast<char*>(b.data()), std::streamsize(4 * n));
  f.read(reinterpret_cast<char*>(t.kind.data()), std::streamsize(n));
  if (!f) throw std::runtime_error(dir + "/scene_face_labels.bin: too short");
  for (std::size_t i = 0; i < n; ++i) t.building[i] = b[i];
  std::ifstream csv(dir + "/buildings.csv");
  std::string line;
  std::getline(csv, line);
  while (std::getline(csv, line)) {
    std::stringstream ss(line);
    std::string id, bag, idx;
    std::getline(ss, id, ',');
    std::getline(ss, bag, ',');
    std::getline(ss, idx, ',');
    const std::size_t k = std::stoul(idx);
    if (t.id.size() <= k) t.id.resize(k + 1);
    t.id[k] = id;
  }
  return t;
}

/// Scene triangle of each chunk triangle, by centroid (ENU), -1 when unmatched.
class CentroidIndex {
 public:
  explicit CentroidIndex(std::vector<Eigen::Vector3d> c) : c_(std::move(c)) {
    for (std::size_t i = 0; i < c_.size(); ++i) grid_[key(c_[i])].push_back(i);
  }
  long find(const Eigen::Vector3d& p) const {
    const auto k = key(p);
    long best = -1;
    double bd = 0.01;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          const auto it = grid_.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid_.end()) continue;
          for (std::size_t i : it->second) {
            const double d = (c_[i] - p).norm();
            if (d < bd) bd = d, best = long(i);
          }
        }
    return best;
  }

 private:
  using Key = std::array<long, 3>;
  static Key key(const Eigen::Vector3d& p) {
    return {long(std::floor(p[0] / 0.05)), long(std::floor(p[1] / 0.05)),
            long(std::floor(p[2] / 0.05))};
  }
  std::vector<Eigen::Vector3d> c_;
  std::map<Key, std::vector<std::size_t>> grid_;
};

}  // namespace

int main(int argc, char** argv) {
  std::string work, data = std::string(CITYLOD_SHARED_DATA) + "/mesh_city";
  bool rmse = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--data" && i + 1 < argc)
      data = argv[++i];
    else if (a == "--rmse")
      rmse = true;
    else if (work.empty())
      work = a;
    else {
      std::fprintf(stderr, "usage: mesh_city_bench WORK [--data DIR] [--rmse]\n");
      return 2;
    }
  }
  if (work.empty()) {
    std::fprintf(stderr, "usage: mesh_city_bench WORK [--data DIR] [--rmse]\n");
    return 2;
  }
  try {
    const tiler::Manifest m = tiler::read_manifest(work);
    const tiler::SceneGeoref georef(m, work);
    io::TriangleMesh scene = io::read_mesh(data + "/scene.ply");
    const std::vector<io::Vec3d> scene_crs = scene.vertices;
    Eigen::Map<Eigen::Matrix3Xd> v(scene.vertices[0].data(), 3,
                                   Eigen::Index(scene.vertices.size()));
    georef.from_crs(v);  // to the chunks' frame
    const std::size_t n = scene.triangles.size();
    const Truth truth = read_truth(data, n);
    std::vector<Eigen::Vector3d> cen(n);
    for (std::size_t t = 0; t < n; ++t) {
      Eigen::Vector3d s(0, 0, 0);
      for (int k = 0; k < 3; ++k)
        s += Eigen::Map<const Eigen::Vector3d>(scene.vertices[scene.triangles[t][k]].data());
      cen[t] = s / 3;
    }
    const CentroidIndex index(cen);
    std::map<std::string, int> building_of_id;
    for (std::size_t b = 0; b < truth.id.size(); ++b) building_of_id["fp-" + truth.id[b]] = int(b);
    std::vector<std::size_t> true_count(truth.id.size(), 0);
    for (std::size_t t = 0; t < n; ++t)
      if (truth.building[t] >= 0 && (truth.kind[t] == 1 || truth.kind[t] == 2))
        ++true_count[std::size_t(truth.building[t])];

    std::vector<double> kept_all, prec_all, e1_all, e2_all;
    std::vector<int> chunk_of(n, -1);  // index in m.chunks
    int chunk_index = -1;
    std::size_t unmatched = 0, tree_chunks = 0;
    std::set<int> trees_seen;
    std::map<int, std::size_t> alone;  // building -> chunks where it is > 50 % and >= 50 % kept
    std::printf("%-46s %7s %7s %7s %7s %7s %7s\n", "chunk", "tris", "kept%", "prec%", "other",
                "terrain", "tree");
    for (const auto& c : m.chunks) {
      ++chunk_index;
      if (c.skipped()) continue;
      const io::TriangleMesh cm = io::read_mesh(tiler::chunk_path(work, c.id));
      std::map<int, std::size_t> by_building;  // -1 terrain, -2 tree
      std::size_t tree_crown = 0;
      for (const auto& tri : cm.triangles) {
        Eigen::Vector3d s(0, 0, 0);
        for (int k = 0; k < 3; ++k)
          s += Eigen::Map<const Eigen::Vector3d>(cm.vertices[tri[k]].data());
        s = s / 3 + Eigen::Vector3d(c.origin[0], c.origin[1], c.origin[2]);
        const long t = index.find(s);
        if (t < 0) {
          ++unmatched;
          continue;
        }
        const int b = truth.building[std::size_t(t)];
        const int k = truth.kind[std::size_t(t)];
        chunk_of[std::size_t(t)] = chunk_index;
        ++by_building[k == 1 || k == 2 ? b : (k == 0 ? -1 : -2)];
        tree_crown += k == 3;
      }
      const double total = double(cm.triangles.size());
      const auto it = building_of_id.find(c.id);
      if (it != building_of_id.end()) {
        const int b = it->second;
        const double mine = double(by_building[b]);
        const double kept = 100.0 * mine / double(true_count[std::size_t(b)]);
        const double prec = 100.0 * mine / total;
        kept_all.push_back(kept);
        prec_all.push_back(prec);
        std::size_t other = 0;
        for (const auto& [bb, k] : by_building)
          if (bb >= 0 && bb != b) other += k;
        std::printf("%-46s %7zu %7.1f %7.1f %7zu %7zu %7zu", c.id.c_str(), cm.triangles.size(),
                    kept, prec, other, by_building[-1], by_building[-2]);
        if (rmse) {
          const auto rep = tiler::read_lod_report(tiler::lod_report_path(work, c.id));
          const tiler::ModelRecord* fin = nullptr;
          for (const auto& mr : rep.models)
            if (tiler::is_anchor(mr.kind)) fin = &mr;
          if (!fin && !rep.models.empty()) fin = &rep.models.back();
          if (fin) {
            const fs::path mp = fs::path(tiler::lod_dir(work, c.id)) / fin->file;
            io::TriangleMesh model = io::read_mesh(mp.string());
            for (auto& p : model.vertices)
              for (int k = 0; k < 3; ++k) p[std::size_t(k)] += c.origin[std::size_t(k)];
            if (!model.vertices.empty())
              georef.to_crs(Eigen::Map<Eigen::Matrix3Xd>(model.vertices[0].data(), 3,
                                                         Eigen::Index(model.vertices.size())));
            const fs::path tmp = fs::temp_directory_path() / ("mesh_city_bench_" + c.id + ".ply");
            io::write_ply(tmp.string(), model);
            // The truth as a dense point set (5 cm lattice on every face): the distances
            // are then to its surface, not to its few vertices.
            const io::TriangleMesh tm =
                io::read_mesh(data + "/truth/" + truth.id[std::size_t(b)] + ".obj");
            io::PointSet ref;
            for (const auto& tri : tm.triangles) {
              const Eigen::Vector3d a(tm.vertices[tri[0]].data());
              const Eigen::Vector3d ab = Eigen::Vector3d(tm.vertices[tri[1]].data()) - a;
              const Eigen::Vector3d ac = Eigen::Vector3d(tm.vertices[tri[2]].data()) - a;
              const int steps = 1 + int(std::max(ab.norm(), ac.norm()) / 0.05);
              for (int i = 0; i <= steps; ++i)
                for (int j = 0; i + j <= steps; ++j) {
                  const Eigen::Vector3d q = a + ab * (double(i) / steps) + ac * (double(j) / steps);
                  ref.positions.push_back({q[0], q[1], q[2]});
                }
            }
            const fs::path tref =
                fs::temp_directory_path() / ("mesh_city_bench_ref_" + c.id + ".ply");
            io::write_ply(tref.string(), ref);
            const auto ev = tiler::evaluate_models({tmp.string()}, tref.string(), 20000);
            if (!std::getenv("MESH_CITY_BENCH_KEEP")) {
              fs::remove(tmp);
              fs::remove(tref);
            }
            const double e1 = ev[0].e.e1 * ev[0].e.diagonal / 100;
            const double e2 = ev[0].e.e2 * ev[0].e.diagonal / 100;
            e1_all.push_back(e1);
            e2_all.push_back(e2);
            std::printf("  model->truth %.3f m  truth->model %.3f m  closed %d", e1, e2,
                        int(ev[0].e.check.closed));
          }
        }
        std::printf("\n");
      } else {
        int major = -1;
        std::size_t best = 0;
        for (const auto& [bb, k] : by_building)
          if (k > best) best = k, major = bb;
        if (major == -2) {
          ++tree_chunks;
        } else if (major >= 0) {
          const double kept = 100.0 * double(best) / double(true_count[std::size_t(major)]);
          std::size_t others = 0;
          for (const auto& [bb, k] : by_building)
            if (bb >= 0 && bb != major &&
                100.0 * double(k) / double(true_count[std::size_t(bb)]) > 10)
              ++others;
          if (others == 0 && kept >= 50) ++alone[major];
        }
        std::printf("%-46s %7zu  majority %s (%zu), buildings:", c.id.c_str(), cm.triangles.size(),
                    major == -2   ? "tree"
                    : major == -1 ? "terrain"
                                  : truth.id[std::size_t(major)].c_str(),
                    best);
        for (const auto& [bb, k] : by_building)
          if (bb >= 0) std::printf(" %d:%zu", bb, k);
        std::printf(" terrain:%zu tree:%zu\n", by_building[-1], by_building[-2]);
        (void)tree_crown;
      }
    }
    // Where each building's lost faces went: no chunk, or another chunk.
    std::printf("%-46s %9s %9s %9s %9s\n", "lost faces of", "roof:none", "roof:other", "wall:none",
                "wall:other");
    for (std::size_t b = 0; b < truth.id.size(); ++b) {
      std::size_t lost[2][2] = {{0, 0}, {0, 0}};
      int own = -1;
      for (std::size_t ci = 0; ci < m.chunks.size(); ++ci)
        if (m.chunks[ci].id == "fp-" + truth.id[b]) own = int(ci);
      if (own < 0) continue;
      for (std::size_t t = 0; t < n; ++t) {
        if (truth.building[t] != int(b) || (truth.kind[t] != 1 && truth.kind[t] != 2)) continue;
        if (chunk_of[t] == own) continue;
        ++lost[truth.kind[t] - 1][chunk_of[t] < 0 ? 0 : 1];
        if (std::getenv("MESH_CITY_BENCH_DUMP")) {
          const auto& tri = scene.triangles[t];
          const auto& a = scene_crs[tri[0]];
          const auto& bb = scene_crs[tri[1]];
          const auto& cc = scene_crs[tri[2]];
          std::fprintf(
              stderr,
              "lost %zu kind %d tri %zu -> %s : %.2f %.2f %.2f | %.2f %.2f %.2f | %.2f %.2f %.2f\n",
              b, int(truth.kind[t]), t,
              chunk_of[t] < 0 ? "none" : m.chunks[std::size_t(chunk_of[t])].id.c_str(), a[0], a[1],
              a[2], bb[0], bb[1], bb[2], cc[0], cc[1], cc[2]);
        }
      }
      std::printf("%-46s %9zu %9zu %9zu %9zu\n", truth.id[b].c_str(), lost[0][0], lost[0][1],
                  lost[1][0], lost[1][1]);
    }
    if (!kept_all.empty())
      std::printf(
          "footprint chunks %zu: kept median %.1f %% (min %.1f), precision median %.1f %% "
          "(min %.1f)\n",
          kept_all.size(), median(kept_all), *std::min_element(kept_all.begin(), kept_all.end()),
          median(prec_all), *std::min_element(prec_all.begin(), prec_all.end()));
    if (!e1_all.empty())
      std::printf(
          "finest models %zu: model->truth RMSE median %.3f m (max %.3f), truth->model "
          "median %.3f m (max %.3f)\n",
          e1_all.size(), median(e1_all), *std::max_element(e1_all.begin(), e1_all.end()),
          median(e2_all), *std::max_element(e2_all.begin(), e2_all.end()));
    std::size_t nfp = 0;
    for (const auto& c : m.chunks) nfp += !c.skipped() && building_of_id.count(c.id) == 0;
    if (nfp)
      std::printf("chunks without footprint %zu: %zu tree chunks, %zu buildings on their own\n",
                  nfp, tree_chunks, alone.size());
    std::printf("unmatched chunk triangles: %zu\n", unmatched);
    return unmatched == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mesh_city_bench: %s\n", e.what());
    return 1;
  }
}
