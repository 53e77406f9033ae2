// split_bench: out-of-core behaviour of `citylod split`.
//
//   split_bench [--input FILE.las] [--crs EPSG:28992] [--memory-limit 128M] [--copies 1,4,16]
//   [--tmp DIR]
//
// For each N, writes a LAS holding N shifted copies of the input (a sqrt(N) x sqrt(N)
// grid of tiles), then runs split_scene() on it in a fresh process (this program
// re-executed with --child) and reports the child's peak RSS (wait4 rusage), wall
// and CPU time and throughput. The claim checked: peak RSS grows < 1.5x from
// N = 1 to N = 16 under the same --memory-limit.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_scene.hpp"
#include "child_run.hpp"
#include "citylod/tiler/split.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

struct Args {
  std::string input = std::string(CITYLOD_SHARED_DATA) + "/delft/ahn3_cropped_2.las";
  std::string crs = "EPSG:28992";
  std::string memory = "128M";
  std::vector<int> copies{1, 4, 16};
  std::string tmp = (fs::temp_directory_path() / "citylod_split_bench").string();
};

int child(const std::string& las, const std::string& work, const std::string& crs,
          const std::string& mem) {
  tiler::SplitOptions o;
  o.inputs = {las};
  o.work_dir = work;
  o.crs = crs;
  o.memory_limit = tiler::parse_memory_size(mem);
  o.force = true;
  try {
    const tiler::SplitReport r = tiler::split_scene(o);
    std::printf("%llu %zu %zu %.3f %zu\n", static_cast<unsigned long long>(r.points), r.chunks,
                r.cells, r.seconds, r.max_region_points);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "split_bench child: %s\n", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 6 && std::string(argv[1]) == "--child")
    return child(argv[2], argv[3], argv[4], argv[5]);
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--input")
      a.input = v;
    else if (k == "--crs")
      a.crs = v;
    else if (k == "--memory-limit")
      a.memory = v;
    else if (k == "--tmp")
      a.tmp = v;
    else if (k == "--copies") {
      a.copies.clear();
      std::stringstream ss(v);
      std::string t;
      while (std::getline(ss, t, ',')) a.copies.push_back(std::stoi(t));
    } else {
      std::fprintf(stderr,
                   "usage: split_bench [--input LAS] [--crs CRS] [--memory-limit SIZE] [--copies "
                   "1,4,16] [--tmp DIR]\n");
      return 2;
    }
  }
  if (!fs::exists(a.input)) {
    std::fprintf(stderr, "split_bench: input %s not found\n", a.input.c_str());
    return 1;
  }
  fs::create_directories(a.tmp);
  std::printf("split_bench: input %s, --crs %s, --memory-limit %s, %u hardware threads\n",
              a.input.c_str(), a.crs.c_str(), a.memory.c_str(),
              std::thread::hardware_concurrency());
  std::printf("%4s %12s %10s %8s %8s %10s %10s %12s %7s %12s\n", "N", "points", "input MB",
              "chunks", "cells", "wall s", "cpu s", "points/s", "RSS MB", "max region");
  double rss1 = 0, rss_last = 0;
  for (int n : a.copies) {
    const std::string las = (fs::path(a.tmp) / ("tiled_" + std::to_string(n) + ".las")).string();
    const std::string work = (fs::path(a.tmp) / ("work_" + std::to_string(n))).string();
    const std::uint64_t pts = bench::write_tiled_las(a.input, las, n);
    const bench::ChildRun c = bench::run_child(argv[0], {las, work, a.crs, a.memory});
    if (!c.ok) {
      std::fprintf(stderr, "split_bench: split failed for N=%d\n", n);
      return 1;
    }
    unsigned long long points = 0;
    std::size_t chunks = 0, cells = 0, region = 0;
    double secs = 0;
    std::sscanf(c.out.c_str(), "%llu %zu %zu %lf %zu", &points, &chunks, &cells, &secs, &region);
    const double wall = c.wall_s, cpu = c.cpu_s, rss = c.rss_mb;
    if (rss1 == 0) rss1 = rss;
    rss_last = rss;
    std::printf("%4d %12llu %10.1f %8zu %8zu %10.2f %10.2f %12.0f %7.1f %12zu\n", n, points,
                double(fs::file_size(las)) / 1e6, chunks, cells, wall, cpu, double(pts) / wall, rss,
                region);
    std::fflush(stdout);
    fs::remove(las);
    fs::remove_all(work);
  }
  std::printf("peak RSS N=%d / N=%d: %.2fx (%s 1.5x)\n", a.copies.back(), a.copies.front(),
              rss_last / rss1, rss_last / rss1 < 1.5 ? "<" : ">=");
  return 0;
}
