// `citylod tile` / `citylod rebuild` end to end on the bundled real example
// (examples/delft_small): completion + run report, thread-count determinism,
// kill -9 and resume, per-building rebuild, bad input.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include "support/cli_run.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;

namespace {

using namespace citylod::test;

const fs::path kExample = fs::path(CITYLOD_SOURCE_DIR) / "examples" / "delft_small";

std::string example_args() {
  return q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
         q(kExample / "footprints.geojson");
}

void expect_same_tree(const fs::path& a, const fs::path& b) {
  const auto ta = tree(a), tb = tree(b);
  ASSERT_FALSE(ta.empty()) << a;
  std::vector<std::string> diff;
  for (const auto& [k, v] : ta)
    if (!tb.count(k) || tb.at(k) != v) diff.push_back(k);
  for (const auto& [k, v] : tb)
    if (!ta.count(k)) diff.push_back(k + " (only in " + b.string() + ")");
  EXPECT_TRUE(diff.empty()) << diff.size() << " files differ, first: " << diff.front();
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream f(p);
  nlohmann::json j;
  f >> j;
  return j;
}

/// Finished buildings: lod/<id>/report.json carrying a key.
std::map<std::string, std::string> finished_reports(const fs::path& work) {
  std::map<std::string, std::string> m;
  if (!fs::exists(work / "lod")) return m;
  for (const auto& e : fs::directory_iterator(work / "lod")) {
    const fs::path r = e.path() / "report.json";
    if (e.is_directory() && fs::exists(r) && slurp(r).find("\"key\"") != std::string::npos)
      m[e.path().filename().string()] = slurp(r);
  }
  return m;
}

/// "lod: N buildings (X computed, Y reused)" of a run's log.
bool lod_counts(const std::string& log, int& total, int& computed, int& reused) {
  std::smatch m;
  if (!std::regex_search(log, m,
                         std::regex(R"(lod: (\d+) buildings \((\d+) computed, (\d+) reused\))")))
    return false;
  total = std::stoi(m[1]);
  computed = std::stoi(m[2]);
  reused = std::stoi(m[3]);
  return true;
}

TEST(TileCli, ExampleCompletesAndThreadsDoNotChangeTheOutput) {
  const fs::path d = tmp_dir("tile_cli_threads");
  const CliRun a = run("tile " + example_args() + " --threads 1 --out " + q(d / "t1"));
  ASSERT_EQ(a.code, 0) << a.out;
  const CliRun b = run("tile " + example_args() + " --threads 2 --out " + q(d / "t2"));
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(a.out.find("tile: time split"), std::string::npos) << a.out;
  ASSERT_TRUE(fs::exists(d / "t1" / "tileset" / "tileset.json"));
  const nlohmann::json rep = read_json(d / "t1" / "run_report.json");
  ASSERT_TRUE(rep["buildings"].is_array());
  EXPECT_GT(rep["buildings"].size(), 0u);
  for (const auto& bld : rep["buildings"]) {
    const bool has_models = bld.value("models", 0) > 0;
    const bool has_reason = !bld.value("reason", std::string()).empty();
    EXPECT_TRUE(has_models || has_reason) << bld.dump();
  }
  for (const char* s : {"split", "lod", "assemble"}) EXPECT_TRUE(rep["stages"].contains(s)) << s;
  EXPECT_GT(rep["peak_rss_bytes"]["self"].get<double>(), 0);
  expect_same_tree(d / "t1" / "tileset", d / "t2" / "tileset");

  // Re-running the same command reuses everything.
  const CliRun c = run("tile " + example_args() + " --threads 2 --out " + q(d / "t2"));
  ASSERT_EQ(c.code, 0) << c.out;
  int total = 0, computed = -1, reused = -1;
  ASSERT_TRUE(lod_counts(c.out, total, computed, reused)) << c.out;
  EXPECT_EQ(computed, 0);
  EXPECT_EQ(reused, total);
  expect_same_tree(d / "t1" / "tileset", d / "t2" / "tileset");
}

TEST(TileCli, KilledRunResumesWithoutRecomputingFinishedBuildings) {
  const fs::path d = tmp_dir("tile_cli_kill");
  const CliRun ref = run("tile " + example_args() + " --threads 2 --out " + q(d / "ref"));
  ASSERT_EQ(ref.code, 0) << ref.out;

  const fs::path out = d / "run";
  const std::string cmd =
      std::string(CITYLOD_BINARY) + " -q tile " + example_args() + " --threads 2 --out " + q(out);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setsid();  // own process group: the kill reaches the supervised LOD child too
    execl("/bin/sh", "sh", "-c", ("exec " + cmd + " >/dev/null 2>&1").c_str(), (char*)nullptr);
    _exit(127);
  }
  // Kill it once at least one building is finished (about 1-2 s into the run).
  const auto t0 = std::chrono::steady_clock::now();
  bool running = true;
  int status = 0;
  while (finished_reports(out / "work").empty()) {
    if (waitpid(pid, &status, WNOHANG) == pid) {
      running = false;
      break;
    }
    if (std::chrono::steady_clock::now() - t0 > std::chrono::seconds(300)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(running) << "the run finished before it could be killed";
  kill(-pid, SIGKILL);
  waitpid(pid, &status, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the group's last members die
  const auto before = finished_reports(out / "work");
  ASSERT_FALSE(before.empty());

  const CliRun again = run("tile " + example_args() + " --threads 2 --out " + q(out));
  ASSERT_EQ(again.code, 0) << again.out;
  int total = 0, computed = -1, reused = -1;
  ASSERT_TRUE(lod_counts(again.out, total, computed, reused)) << again.out;
  EXPECT_EQ(reused, int(before.size())) << again.out;
  EXPECT_EQ(computed, total - int(before.size())) << again.out;
  const auto after = finished_reports(out / "work");
  for (const auto& [id, bytes] : before) EXPECT_EQ(after.at(id), bytes) << id << " was recomputed";
  expect_same_tree(d / "ref" / "tileset", out / "tileset");
}

TEST(TileCli, RebuildChangesOneBuildingAndReportsChangedFiles) {
  const fs::path d = tmp_dir("tile_cli_rebuild");
  const fs::path out = d / "run";
  const CliRun t = run("tile " + example_args() + " --threads 2 --out " + q(out));
  ASSERT_EQ(t.code, 0) << t.out;
  std::string id;
  const nlohmann::json run_report = read_json(out / "run_report.json");
  for (const auto& b : run_report["buildings"])
    if (b["status"] == "ok") {
      id = b["id"];
      break;
    }
  ASSERT_FALSE(id.empty());
  const auto before = finished_reports(out / "work");

  // A zero-ish time budget forces this building's fallback: its models certainly change.
  const CliRun r =
      run("rebuild " + q(out) + " --building " + id + " --set budget.time_budget_s=1e-9");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("changed tiles/"), std::string::npos) << r.out;
  const auto after = finished_reports(out / "work");
  ASSERT_EQ(after.size(), before.size());
  for (const auto& [bid, bytes] : before) {
    if (bid == id)
      EXPECT_NE(after.at(bid), bytes) << bid;
    else
      EXPECT_EQ(after.at(bid), bytes) << bid << " changed but was not rebuilt";
  }
  const nlohmann::json ov = read_json(out / "work" / "overrides.json");
  EXPECT_EQ(ov["buildings"][id]["set"]["budget.time_budget_s"], "1e-9") << ov.dump();

  // The tileset equals a fresh assemble of the work dir.
  const CliRun a = run("assemble " + q(out / "work") + " --out " + q(d / "fresh"));
  ASSERT_EQ(a.code, 0) << a.out;
  expect_same_tree(d / "fresh", out / "tileset");

  // A later tile run keeps the override: nothing is recomputed.
  const CliRun again = run("tile " + example_args() + " --threads 2 --out " + q(out));
  ASSERT_EQ(again.code, 0) << again.out;
  int total = 0, computed = -1, reused = -1;
  ASSERT_TRUE(lod_counts(again.out, total, computed, reused)) << again.out;
  EXPECT_EQ(computed, 0) << again.out;
  EXPECT_EQ(finished_reports(out / "work").at(id), after.at(id));

  // --select pins models (the fallback's only model: step of the first model).
  const nlohmann::json rep = read_json(out / "work" / "lod" / id / "report.json");
  const int step = rep["models"][0].value("step", 0);
  const CliRun s =
      run("rebuild " + q(out) + " --building " + id + " --select " + std::to_string(step));
  ASSERT_EQ(s.code, 0) << s.out;
  EXPECT_EQ(read_json(out / "work" / "overrides.json")["buildings"][id]["select"][0], step);
  const CliRun bad = run("rebuild " + q(out) + " --building " + id + " --select 999");
  EXPECT_EQ(bad.code, 1) << bad.out;
}

TEST(TileCli, BadInputIsOneErrorLine) {
  const fs::path d = tmp_dir("tile_cli_bad");
  const CliRun r = run("tile " + q(d / "missing.las") + " --crs EPSG:28992 --out " + q(d / "out"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_NE(r.out.find("citylod: error:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("missing.las"), std::string::npos) << r.out;
  const CliRun nb = run("rebuild " + q(d) + " --building x");
  EXPECT_EQ(nb.code, 1) << nb.out;
}

}  // namespace
