// Benchmark of the LOD engine on real buildings: the paper's Table 1 columns
// (F, V, P, S, T1, T2, T3), end-to-end time and peak RSS (each input in its own
// child process), candidate counts, fidelity of the finest anchor, and the
// LOD-Tree vs plain BSP-Tree cut counts (paper Section 5.1).
//
//   lod_bench [--threads N] [FILE...]     (default: the three real inputs of ../shared/data)
#include "citylod/tiler/bridge.hpp"

#include "citylod/lod/lod.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

using namespace citylod;

namespace {

struct Row {
  int F = 0, V = 0, P = 0, S = 0, levels = 0, anchors = 0, interps = 0;
  double T1 = 0, T2 = 0, T3 = 0, total = 0, e1 = -1, e2 = -1, diag = 0;
  int lod_cuts = 0, bsp_nodes = 0, bsp_cuts = 0;
  bool fallback = false;
  char reason[160] = {0};
};

Row run_one(const std::string& path, int threads) {
  Row row;
  const auto b = tiler::load_building(path);
  lod::LodParams p;
  p.bsp.baseline = true;
  p.budget.time_budget_s = 0;
  const auto t0 = std::chrono::steady_clock::now();
  lod::LodExecution exec;
  exec.threads = threads;
  const lod::LodResult r = lod::build_lod_tree(b.input, p, exec);
  row.total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& s = r.stats;
  row.F = s.input_faces;
  row.V = s.input_points;
  row.P = s.planes_detected;
  row.S = s.planes_sorted;
  row.levels = s.level_sets;
  row.T1 = s.t_ioview;
  row.T2 = s.t_tree;
  row.T3 = s.t_traversal;
  row.diag = s.bbox_diagonal;
  row.lod_cuts = s.lod_tree_cuts_to_finest;
  row.bsp_nodes = s.baseline_bsp_nodes;
  row.bsp_cuts = s.baseline_cuts_to_finest;
  row.fallback = r.status != lod::Status::ok;
  std::snprintf(row.reason, sizeof row.reason, "%s", r.reason.c_str());
  for (const auto& m : r.models) {
    if (m.kind == lod::ModelKind::anchor) {
      ++row.anchors;
      row.e1 = m.e1;
      row.e2 = m.e2;
    }
    if (m.kind == lod::ModelKind::interpolation) ++row.interps;
  }
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int threads = 1;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--threads") && i + 1 < argc)
      threads = std::atoi(argv[++i]);
    else
      files.push_back(argv[i]);
  }
  if (files.empty()) {
    const std::string d = CITYLOD_SHARED_DATA;
    files = {d + "/single_building/cgal_building.ply", d + "/noisy_mesh/easy3d_building.off",
             d + "/ahn3_building_lod2/AHN3_13856.ply"};
  }
  std::printf("threads per building: %d\n\n", threads);
  std::printf(
      "| input | F | V | D (m) | P | S | N_l | T1 (s) | T2 (s) | T3 (s) | total (s) | CPU (s) | "
      "peak RSS (MB) | anchors | interp. | finest e1 %% | finest e2 %% | LOD-Tree cuts | BSP-Tree "
      "nodes | BSP-Tree cuts |\n");
  std::printf(
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& f : files) {
    int fds[2];
    if (pipe(fds) != 0) return 1;
    const pid_t pid = fork();
    if (pid == 0) {
      close(fds[0]);
      Row row;
      try {
        row = run_one(f, threads);
      } catch (const std::exception& e) {
        row.fallback = true;
        std::snprintf(row.reason, sizeof row.reason, "%s", e.what());
      }
      if (write(fds[1], &row, sizeof row) != ssize_t(sizeof row)) _exit(2);
      _exit(0);
    }
    close(fds[1]);
    Row row;
    const ssize_t got = read(fds[0], &row, sizeof row);
    close(fds[0]);
    int status = 0;
    struct rusage ru {};
    wait4(pid, &status, 0, &ru);
    const std::string name = f.substr(f.find_last_of('/') + 1);
    if (got != ssize_t(sizeof row)) {
      std::printf("| %s | crashed (status %d) |\n", name.c_str(), status);
      continue;
    }
    const double cpu = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
                       1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    std::printf(
        "| %s%s | %d | %d | %.1f | %d | %d | %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %d | "
        "%d | %.3f | %.3f | %d | %d | %d |\n",
        name.c_str(), row.fallback ? (std::string(" (FALLBACK: ") + row.reason + ")").c_str() : "",
        row.F, row.V, row.diag, row.P, row.S, row.levels, row.T1, row.T2, row.T3, row.total, cpu,
        ru.ru_maxrss / 1024.0, row.anchors, row.interps, row.e1, row.e2, row.lod_cuts,
        row.bsp_nodes, row.bsp_cuts);
    std::fflush(stdout);
  }
  return 0;
}
