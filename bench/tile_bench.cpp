// tile_bench: scaling of the one-command city run `citylod tile`.
//
//   tile_bench --citylod PATH/citylod --out DIR [--scales 1,4,16] [--threads N]
//              [--input LAS] [--crs EPSG:28992] [--keep]
//
// For each scale N: writes DIR/scene_N.las = the Delft AHN3 tile
// (../shared/data/delft/ahn3_cropped_2.las, EPSG:28992) repeated N times side
// by side (bench_scene.hpp, as split_bench), then runs
//   citylod tile DIR/scene_N.las --crs CRS --threads N --out DIR/tile_N
// as a fresh child process (fork/exec, output in DIR/tile_N.log) and waits for
// it with wait4(). The rusage of wait4 covers the child and every descendant
// it reaped, so the peak RSS and CPU time include the LOD stage, which
// `citylod tile` runs in a forked, supervised child (Linux: ru_maxrss of wait4
// = max over the child and its reaped descendants). The run report's own
// figures (peak RSS of the main process and of the LOD child) are kept in the
// CSV as a cross-check. Stage times (split / lod / assemble) and the counts
// come from DIR/tile_N/run_report.json.
//
// Prints a markdown table (stdout; progress on stderr) and writes
// DIR/tile_scaling.csv. Every scale starts from an empty output directory
// (nothing is reused). Exit 1 when a run fails (its log is named).
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_scene.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

struct Args {
  std::string citylod, out;
  std::string input = std::string(CITYLOD_SHARED_DATA) + "/delft/ahn3_cropped_2.las";
  std::string crs = "EPSG:28992";
  std::vector<int> scales{1, 4, 16};
  int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  bool keep = false;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(
      stderr,
      "tile_bench: %s\n"
      "usage: tile_bench --citylod PATH --out DIR [--scales 1,4,16] [--threads N] [--input LAS]\n"
      "                  [--crs CRS] [--keep]\n",
      why);
  std::exit(2);
}

struct Run {
  int scale = 0;
  std::uint64_t points = 0;
  std::size_t buildings = 0, ok = 0, fallback = 0, failed = 0, tiles = 0;
  double split = 0, lod = 0, assemble = 0, report_total = 0;
  double wall = 0, cpu = 0, rss_mb = 0, rss_self_mb = 0, rss_lod_mb = 0;
};

double load_average() {
  double l[1] = {0};
  return getloadavg(l, 1) == 1 ? l[0] : -1;
}

/// Runs argv as a child with stdout+stderr to `log`; returns the wait status and its rusage.
int run_child(const std::vector<std::string>& argv, const std::string& log, rusage& ru,
              double& wall) {
  std::vector<char*> cargv;
  for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
  cargv.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
      close(fd);
    }
    execv(cargv[0], cargv.data());
    std::fprintf(stderr, "tile_bench: cannot execute %s\n", cargv[0]);
    _exit(127);
  }
  int status = 0;
  if (wait4(pid, &status, 0, &ru) != pid) return -1;
  wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return status;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value for " + k).c_str());
      return argv[++i];
    };
    if (k == "--citylod")
      a.citylod = value();
    else if (k == "--out")
      a.out = value();
    else if (k == "--input")
      a.input = value();
    else if (k == "--crs")
      a.crs = value();
    else if (k == "--threads")
      a.threads = std::atoi(value().c_str());
    else if (k == "--keep")
      a.keep = true;
    else if (k == "--scales") {
      a.scales.clear();
      std::stringstream ss(value());
      std::string t;
      while (std::getline(ss, t, ',')) a.scales.push_back(std::atoi(t.c_str()));
    } else if (k == "--help" || k == "-h") {
      usage("scaling of 'citylod tile' on N copies of a real tile");
    } else {
      usage(("unknown argument " + k).c_str());
    }
  }
  if (a.citylod.empty() || a.out.empty()) usage("--citylod and --out are required");
  if (a.threads < 1) usage("--threads must be >= 1");
  for (int s : a.scales)
    if (s < 1) usage("--scales must be positive integers");
  if (a.scales.empty()) usage("--scales is empty");
  if (access(a.citylod.c_str(), X_OK) != 0) {
    std::fprintf(stderr, "tile_bench: %s: not an executable\n", a.citylod.c_str());
    return 1;
  }
  if (!fs::exists(a.input)) {
    std::fprintf(stderr, "tile_bench: %s: input not found\n", a.input.c_str());
    return 1;
  }
  a.citylod = fs::absolute(a.citylod).string();
  fs::create_directories(a.out);

  const double load0 = load_average();
  std::vector<Run> runs;
  for (int n : a.scales) {
    Run r;
    r.scale = n;
    const std::string las = (fs::path(a.out) / ("scene_" + std::to_string(n) + ".las")).string();
    const std::string dir = (fs::path(a.out) / ("tile_" + std::to_string(n))).string();
    const std::string log = dir + ".log";
    std::fprintf(stderr, "tile_bench: scale %d: writing %s\n", n, las.c_str());
    r.points = bench::write_tiled_las(a.input, las, n);
    fs::remove_all(dir);  // a fresh run: nothing to resume
    std::fprintf(stderr, "tile_bench: scale %d: %llu points, citylod tile --threads %d (log %s)\n",
                 n, static_cast<unsigned long long>(r.points), a.threads, log.c_str());
    rusage ru{};
    const int status = run_child({a.citylod, "tile", las, "--crs", a.crs, "--threads",
                                  std::to_string(a.threads), "--out", dir, "--quiet"},
                                 log, ru, r.wall);
    if (status < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      std::fprintf(stderr, "tile_bench: citylod tile failed at scale %d (%s); see %s\n", n,
                   status >= 0 && WIFSIGNALED(status) ? "killed by a signal" : "non-zero exit",
                   log.c_str());
      return 1;
    }
    r.cpu = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    r.rss_mb = double(ru.ru_maxrss) / 1024.0;  // KiB -> MiB
    nlohmann::json rep;
    try {
      std::ifstream f(fs::path(dir) / "run_report.json");
      f >> rep;
      const auto& st = rep.at("stages");
      r.split = st.at("split").at("seconds").get<double>();
      r.lod = st.at("lod").at("seconds").get<double>();
      r.assemble = st.at("assemble").at("seconds").get<double>();
      r.buildings = st.at("lod").at("buildings").get<std::size_t>();
      r.tiles = st.at("assemble").at("tiles").get<std::size_t>();
      r.ok = rep.at("summary").at("ok").get<std::size_t>();
      r.fallback = rep.at("summary").at("fallback").get<std::size_t>();
      r.failed = rep.at("summary").at("failed").get<std::size_t>();
      r.report_total = rep.at("seconds_total").get<double>();
      r.rss_self_mb = double(rep.at("peak_rss_bytes").at("self").get<std::uint64_t>()) / (1 << 20);
      r.rss_lod_mb =
          double(rep.at("peak_rss_bytes").at("children").get<std::uint64_t>()) / (1 << 20);
      if (st.at("split").at("points").get<std::uint64_t>() != r.points)
        std::fprintf(
            stderr, "tile_bench: warning: split read %llu points, the scene has %llu\n",
            static_cast<unsigned long long>(st.at("split").at("points").get<std::uint64_t>()),
            static_cast<unsigned long long>(r.points));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tile_bench: %s/run_report.json: %s\n", dir.c_str(), e.what());
      return 1;
    }
    if (r.buildings == 0) {
      std::fprintf(stderr, "tile_bench: scale %d: no buildings (see %s)\n", n, log.c_str());
      return 1;
    }
    std::fprintf(stderr,
                 "tile_bench: scale %d: %zu buildings, %.1f s wall, %.1f s CPU, %.0f MiB peak\n", n,
                 r.buildings, r.wall, r.cpu, r.rss_mb);
    runs.push_back(r);
    if (!a.keep) {
      fs::remove(las);
      fs::remove_all(dir);
    }
  }
  const double load1 = load_average();

  // ---- table + CSV
  const Run& base = runs.front();
  const double base_per_b = base.wall / double(base.buildings);
  std::ofstream csv(fs::path(a.out) / "tile_scaling.csv");
  csv << "scale,points,buildings,ok,fallback,failed,tiles,split_s,lod_s,assemble_s,report_total_s,"
         "wall_s,cpu_s,"
         "peak_rss_mib,rss_main_mib,rss_lod_child_mib,wall_per_building_s,lod_per_building_s,wall_"
         "ratio,"
         "per_building_ratio,threads\n";
  std::printf(
      "`citylod tile` scaling: %s repeated N times (%s), --threads %d, %u hardware threads, "
      "load average %.2f before / %.2f after\n\n",
      fs::path(a.input).filename().c_str(), a.crs.c_str(), a.threads,
      std::thread::hardware_concurrency(), load0, load1);
  std::printf(
      "| scale | points | buildings (ok / fallback / failed) | split (s) | lod (s) | assemble (s) "
      "| total wall (s) "
      "| CPU (s) | peak RSS (MiB) | wall per building (s) | total / %dx | per building / %dx |\n",
      base.scale, base.scale);
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : runs) {
    const double per_b = r.wall / double(r.buildings);
    std::printf(
        "| %dx | %llu | %zu (%zu / %zu / %zu) | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %.3f | "
        "%.2f | %.2f |\n",
        r.scale, static_cast<unsigned long long>(r.points), r.buildings, r.ok, r.fallback, r.failed,
        r.split, r.lod, r.assemble, r.wall, r.cpu, r.rss_mb, per_b, r.wall / base.wall,
        per_b / base_per_b);
    csv << r.scale << ',' << r.points << ',' << r.buildings << ',' << r.ok << ',' << r.fallback
        << ',' << r.failed << ',' << r.tiles << ',' << fmt("%.3f", r.split) << ','
        << fmt("%.3f", r.lod) << ',' << fmt("%.3f", r.assemble) << ','
        << fmt("%.3f", r.report_total) << ',' << fmt("%.3f", r.wall) << ',' << fmt("%.3f", r.cpu)
        << ',' << fmt("%.1f", r.rss_mb) << ',' << fmt("%.1f", r.rss_self_mb) << ','
        << fmt("%.1f", r.rss_lod_mb) << ',' << fmt("%.4f", per_b) << ','
        << fmt("%.4f", r.lod / double(r.buildings)) << ',' << fmt("%.3f", r.wall / base.wall) << ','
        << fmt("%.3f", per_b / base_per_b) << ',' << a.threads << '\n';
  }
  std::printf(
      "\nTotal wall = the child process from fork to exit (split + lod + assemble + writing the "
      "run report);\n"
      "CPU = user + system of it and its descendants (the forked LOD stage); peak RSS = largest\n"
      "resident set among them (wait4). Per-process peaks in %s/tile_scaling.csv.\n",
      a.out.c_str());
  csv.close();
  if (!csv) {
    std::fprintf(stderr, "tile_bench: cannot write %s/tile_scaling.csv\n", a.out.c_str());
    return 1;
  }
  return 0;
}
