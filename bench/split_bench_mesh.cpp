// split_bench_mesh: out-of-core behaviour of `citylod split` on a photogrammetry mesh.
//
//   split_bench_mesh [--dir ../shared/data/mesh_city] [--memory-limit 2G] [--copies 1,16]
//                    [--layout tiles|file] [--tmp DIR] [--vertex-budget MB]
//
// For each N, writes N shifted copies of DIR/scene.ply on a ceil(sqrt(N))-wide grid
// (copy c at column c % side, row c / side, 20 m apart) with N copies of
// DIR/footprints_bgt_local.geojson (ids suffixed "-c" after the first), either as N tile
// files in a folder (layout tiles, as photogrammetry software exports them) or as one
// PLY (layout file), then runs split_scene() (--crs "$(cat DIR/crs_local.wkt)",
// --footprints) in a fresh process (this program re-executed with --child) and reports
// its peak RSS (wait4 rusage), wall and CPU time. The claim checked (issue 15): peak RSS
// of N = 16 tiles <= 1.2x that of N = 1. --vertex-budget MB sets
// SplitOptions::mesh_vertex_budget (default: half the memory limit): a mesh file's vertices
// over it are paged from a file through a cache of that size.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "child_run.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/tiler/footprints.hpp"
#include "citylod/tiler/split.hpp"
#include "citylod/tiler/workdir.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

struct Args {
  std::string dir = std::string(CITYLOD_SHARED_DATA) + "/mesh_city";
  std::string memory = "2G";
  std::string vertex_budget_mb = "0";
  std::vector<int> copies{1, 16};
  std::string layout = "tiles";
  std::string tmp = (fs::temp_directory_path() / "citylod_split_bench_mesh").string();
};

std::string slurp(const std::string& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

int child(const std::string& input, const std::string& fp, const std::string& work,
          const std::string& crs_file, const std::string& mem, const std::string& vertex_mb) {
  tiler::SplitOptions o;
  o.inputs = {input};
  o.work_dir = work;
  o.crs = slurp(crs_file);
  o.footprints = fp;
  o.memory_limit = tiler::parse_memory_size(mem);
  o.force = true;
  o.mesh_vertex_budget = std::uint64_t(std::stod(vertex_mb) * 1048576.0);
  try {
    const tiler::SplitReport r = tiler::split_scene(o);
    std::printf("%llu %zu %zu %.3f %zu\n", static_cast<unsigned long long>(r.triangles), r.chunks,
                r.cells, r.seconds, r.max_region_points);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "split_bench_mesh child: %s\n", e.what());
    return 1;
  }
}

/// Writes the N-copy scene; returns the input path for split (folder or file).
std::string write_scene(const Args& a, int n, const std::string& fp_out) {
  const io::TriangleMesh m = io::read_mesh(a.dir + "/scene.ply");
  io::BBox3 bb;
  for (const auto& v : m.vertices) bb.add(v);
  const int side = static_cast<int>(std::ceil(std::sqrt(double(n))));
  const double dx = bb.max[0] - bb.min[0] + 20, dy = bb.max[1] - bb.min[1] + 20;
  const fs::path root = fs::path(a.tmp) / ("scene_" + a.layout + "_" + std::to_string(n));
  fs::remove_all(root);
  fs::create_directories(root);
  io::TriangleMesh all;
  for (int c = 0; c < n; ++c) {
    const double ox = (c % side) * dx, oy = (c / side) * dy;
    io::TriangleMesh t;
    t.triangles = m.triangles;
    for (const auto& v : m.vertices) t.vertices.push_back({v[0] + ox, v[1] + oy, v[2]});
    if (a.layout == "tiles") {
      char name[64];
      std::snprintf(name, sizeof name, "Tile_%+04d_%+04d", c % side, c / side);
      fs::create_directories(root / "Data" / name);
      io::write_ply((root / "Data" / name / (std::string(name) + ".ply")).string(), t);
    } else {
      const auto base = static_cast<std::uint32_t>(all.vertices.size());
      all.vertices.insert(all.vertices.end(), t.vertices.begin(), t.vertices.end());
      for (const auto& tr : t.triangles)
        all.triangles.push_back({tr[0] + base, tr[1] + base, tr[2] + base});
    }
  }
  if (a.layout != "tiles") io::write_ply((root / "scene.ply").string(), all);
  // footprints, shifted like their copy
  const tiler::FootprintSet fs0 =
      tiler::read_footprint_source(a.dir + "/footprints_bgt_local.geojson");
  std::ofstream g(fp_out);
  g.precision(12);
  g << "{\"type\":\"FeatureCollection\",\"features\":[";
  bool first = true;
  for (int c = 0; c < n; ++c) {
    const double ox = (c % side) * dx, oy = (c / side) * dy;
    for (const auto& f : fs0.footprints) {
      g << (first ? "" : ",") << "{\"type\":\"Feature\",\"properties\":{\"id\":\"" << f.id
        << (c ? "-" + std::to_string(c) : std::string()) << "\"},\"geometry\":{\"type\":"
        << "\"MultiPolygon\",\"coordinates\":[";
      first = false;
      for (std::size_t p = 0; p < f.polygons.size(); ++p) {
        g << (p ? "," : "") << "[";
        for (std::size_t r = 0; r < f.polygons[p].rings.size(); ++r) {
          g << (r ? "," : "") << "[";
          const auto& ring = f.polygons[p].rings[r];
          for (std::size_t k = 0; k <= ring.size(); ++k) {
            const auto& v = ring[k % ring.size()];
            g << (k ? "," : "") << "[" << v[0] + ox << "," << v[1] + oy << "]";
          }
          g << "]";
        }
        g << "]";
      }
      g << "]}}";
    }
  }
  g << "]}";
  return a.layout == "tiles" ? root.string() : (root / "scene.ply").string();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 8 && std::string(argv[1]) == "--child")
    return child(argv[2], argv[3], argv[4], argv[5], argv[6], argv[7]);
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--dir")
      a.dir = v;
    else if (k == "--memory-limit")
      a.memory = v;
    else if (k == "--layout")
      a.layout = v;
    else if (k == "--tmp")
      a.tmp = v;
    else if (k == "--vertex-budget")
      a.vertex_budget_mb = v;
    else if (k == "--copies") {
      a.copies.clear();
      std::stringstream ss(v);
      std::string t;
      while (std::getline(ss, t, ',')) a.copies.push_back(std::stoi(t));
    } else {
      std::fprintf(stderr,
                   "usage: split_bench_mesh [--dir MESH_CITY] [--memory-limit SIZE] [--copies "
                   "1,16] [--layout tiles|file] [--tmp DIR] [--vertex-budget MB]\n");
      return 2;
    }
  }
  if (!fs::exists(a.dir + "/scene.ply")) {
    std::fprintf(stderr, "split_bench_mesh: %s/scene.ply not found\n", a.dir.c_str());
    return 1;
  }
  fs::create_directories(a.tmp);
  std::printf(
      "split_bench_mesh: %s, layout %s, --memory-limit %s, vertex budget %s MB (0: half "
      "the limit), %u hardware threads\n",
      a.dir.c_str(), a.layout.c_str(), a.memory.c_str(), a.vertex_budget_mb.c_str(),
      std::thread::hardware_concurrency());
  std::printf("%4s %12s %8s %8s %10s %10s %7s %12s\n", "N", "triangles", "chunks", "cells",
              "wall s", "cpu s", "RSS MB", "max region");
  double rss1 = 0, rss_last = 0;
  for (int n : a.copies) {
    const std::string fp = (fs::path(a.tmp) / ("fp_" + std::to_string(n) + ".geojson")).string();
    const std::string input = write_scene(a, n, fp);
    const std::string work = (fs::path(a.tmp) / ("work_" + std::to_string(n))).string();
    const std::string crs = a.dir + "/crs_local.wkt";
    const bench::ChildRun c =
        bench::run_child(argv[0], {input, fp, work, crs, a.memory, a.vertex_budget_mb});
    if (!c.ok) {
      std::fprintf(stderr, "split_bench_mesh: split failed for N=%d\n", n);
      return 1;
    }
    unsigned long long tris = 0;
    std::size_t chunks = 0, cells = 0, region = 0;
    double secs = 0;
    std::sscanf(c.out.c_str(), "%llu %zu %zu %lf %zu", &tris, &chunks, &cells, &secs, &region);
    const double wall = c.wall_s, cpu = c.cpu_s, rss = c.rss_mb;
    if (rss1 == 0) rss1 = rss;
    rss_last = rss;
    std::printf("%4d %12llu %8zu %8zu %10.2f %10.2f %7.1f %12zu\n", n, tris, chunks, cells, wall,
                cpu, rss, region);
    std::fflush(stdout);
    if (!std::getenv("SPLIT_BENCH_KEEP")) {
      fs::remove_all(input);
      fs::remove_all(work);
    }
  }
  std::printf("peak RSS N=%d / N=%d: %.2fx (%s 1.2x)\n", a.copies.back(), a.copies.front(),
              rss_last / rss1, rss_last / rss1 <= 1.2 ? "<=" : ">");
  return 0;
}
