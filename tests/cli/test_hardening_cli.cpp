// Hostile work directories, concurrent runs, interrupted publications and
// special files through the real `citylod` binary (issue 13): a clear error
// line naming the file, a non-zero exit, nothing touched outside the output.
#include <gtest/gtest.h>

#include "support/cli_run.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace {

using namespace citylod::test;
namespace fs = std::filesystem;

/// A manifest with one chunk named `id` (a box of 1 m, no chunk file).
void write_manifest_with(const fs::path& work, const std::string& id) {
  fs::create_directories(work);
  nlohmann::json chunk{
      {"id", id},     {"origin", {0, 0, 0}}, {"bbox_min", {0, 0, 0}}, {"bbox_max", {1, 1, 1}},
      {"points", 10}, {"status", "pending"}};
  nlohmann::json m{{"version", 1},
                   {"scene",
                    {{"crs", ""},
                     {"origin_crs", {0, 0, 0}},
                     {"origin_lon", 4.36},
                     {"origin_lat", 52.0},
                     {"origin_h", 0}}},
                   {"chunks", {chunk}}};
  std::ofstream(work / "manifest.json") << m.dump(1);
}

/// outer/WORK and outer/sentinel/keep.txt; returns outer.
fs::path with_sentinel(const std::string& name) {
  const fs::path outer = tmp_dir("hardening_" + name) / "outer";
  fs::create_directories(outer / "sentinel");
  std::ofstream(outer / "sentinel" / "keep.txt") << "must survive\n";
  return outer;
}

TEST(HostileWorkDir, ChunkIdsLeadingOutsideAreRefusedAndNothingIsDeleted) {
  for (const std::string& id :
       std::vector<std::string>{"../..", "..", "../sentinel", "a/../../..", "/tmp", ".hidden",
                                std::string(300, 'a'), "", "x\\y"}) {
    SCOPED_TRACE(id);
    const fs::path outer = with_sentinel("ids");
    const fs::path work = outer / "WORK";
    write_manifest_with(work, id);
    for (const std::string& cmd : std::vector<std::string>{"lod", "assemble", "eval"}) {
      SCOPED_TRACE(cmd);
      const std::string args = cmd == "assemble"
                                   ? "assemble " + q(work) + " --out " + q(outer / "ts")
                                   : cmd + " " + q(work);
      const CliRun r = run(args);
      EXPECT_NE(r.code, 0) << r.out;
      EXPECT_NE(r.out.find("manifest.json"), std::string::npos) << r.out;
      EXPECT_NE(r.out.find("not a safe name"), std::string::npos) << r.out;
      ASSERT_TRUE(fs::exists(outer / "sentinel" / "keep.txt")) << r.out;
      ASSERT_TRUE(fs::exists(work / "manifest.json")) << r.out;
    }
  }
}

TEST(HostileWorkDir, ASymlinkedLodFolderIsRefused) {
  const fs::path outer = with_sentinel("symlink");
  const fs::path work = outer / "WORK";
  write_manifest_with(work, "fp-1");
  fs::create_directories(outer / "sentinel" / "fp-1");
  std::ofstream(outer / "sentinel" / "fp-1" / "keep.txt") << "must survive\n";
  fs::create_directory_symlink(outer / "sentinel", work / "lod");
  const CliRun r = run("lod " + q(work));
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("symbolic link"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(outer / "sentinel" / "fp-1" / "keep.txt")) << r.out;
}

TEST(HostileWorkDir, AModelFileOutsideItsFolderIsRefused) {
  const fs::path outer = with_sentinel("model_file");
  const fs::path work = outer / "WORK";
  write_manifest_with(work, "fp-1");
  fs::create_directories(work / "lod" / "fp-1");
  for (const std::string& file :
       std::vector<std::string>{"../../../sentinel/keep.txt", "/etc/passwd", "..", ""}) {
    SCOPED_TRACE(file);
    nlohmann::json rep{{"status", "ok"}, {"models", {{{"file", file}, {"kind", "anchor"}}}}};
    std::ofstream(work / "lod" / "fp-1" / "report.json", std::ios::trunc) << rep.dump();
    const CliRun r = run("assemble " + q(work) + " --out " + q(outer / "ts"));
    EXPECT_NE(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("report.json"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("not a plain file name"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(outer / "ts")) << r.out;
  }
}

// ------------------------------------------------------------ one writer per directory

const fs::path kExample = fs::path(CITYLOD_SOURCE_DIR) / "examples" / "delft_small";

std::string example_args() {
  return q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
         q(kExample / "footprints.geojson");
}

/// Every content uri of DIR/tileset/tileset.json names an existing file.
void expect_complete_tileset(const fs::path& ts) {
  ASSERT_TRUE(fs::exists(ts / "tileset.json")) << ts;
  const nlohmann::json j = nlohmann::json::parse(slurp(ts / "tileset.json"));
  std::size_t n = 0;
  std::function<void(const nlohmann::json&)> walk = [&](const nlohmann::json& t) {
    if (t.contains("content")) {
      ++n;
      EXPECT_TRUE(fs::exists(ts / t["content"]["uri"].get<std::string>())) << t["content"]["uri"];
    }
    if (t.contains("children"))
      for (const auto& c : t["children"]) walk(c);
  };
  walk(j["root"]);
  EXPECT_GT(n, 0u);
}

TEST(OneWriter, TwoTileRunsIntoOneDirectoryNeverLeaveABrokenTileset) {
  const fs::path d = tmp_dir("hardening_two_tiles");
  for (const char* delay : {"0", "0.3", "1"}) {
    SCOPED_TRACE(delay);
    fs::remove_all(d / "out");
    const std::string cmd = std::string(CITYLOD_BINARY) + " tile " + example_args() +
                            " --threads 1 --out " + q(d / "out");
    const CliRun r = sh("(" + cmd + " > " + q(d / "a.log") + " 2>&1; echo $? > " + q(d / "a.rc") +
                        ") & sleep " + delay + "; " + cmd + " > " + q(d / "b.log") +
                        " 2>&1; echo $? > " + q(d / "b.rc") + "; wait");
    const int a = std::stoi(slurp(d / "a.rc")), b = std::stoi(slurp(d / "b.rc"));
    const std::string alog = slurp(d / "a.log"), blog = slurp(d / "b.log");
    EXPECT_TRUE(a == 0 || b == 0) << alog << blog;
    for (const auto& [rc, log] : {std::make_pair(a, alog), std::make_pair(b, blog)})
      if (rc != 0) {
        EXPECT_NE(log.find("in use by another citylod run (pid "), std::string::npos) << log;
        EXPECT_NE(log.find((d / "out").string()), std::string::npos) << log;
      }
    expect_complete_tileset(d / "out" / "tileset");
    EXPECT_FALSE(fs::exists(d / "out" / ".citylod.lock"));  // released and removed
  }
}

// ------------------------------------------------------------ crashes by signal

TEST(NoSignal, ALongEpsgCodeIsAClearError) {
  const fs::path d = tmp_dir("hardening_crs");
  const CliRun r = run("split " + q(kExample / "delft_small.las") +
                       " --crs EPSG:" + std::string(100000, '7') + " -o " + q(d / "w"));
  EXPECT_GT(r.code, 0) << r.out.substr(0, 500);  // an error, not a signal (-1)
  EXPECT_NE(r.out.find("EPSG:777"), std::string::npos) << r.out.substr(0, 500);
  EXPECT_LT(r.out.size(), 2000u);
}

TEST(NoSignal, InfoRefusesSpecialFilesAtOnce) {
  const fs::path d = tmp_dir("hardening_special");
  const fs::path fifo = d / "pipe.las";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& f : std::vector<std::string>{fifo.string(), std::string("/dev/zero"),
                                                       std::string("/dev/null")}) {
    const auto t0 = std::chrono::steady_clock::now();
    const CliRun r = sh("timeout 20 " + std::string(CITYLOD_BINARY) + " info " + q(f));
    EXPECT_EQ(r.code, 1) << f << ": " << r.out;
    EXPECT_NE(r.out.find(f + ": is not a regular file"), std::string::npos) << r.out;
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10);
  }
}

TEST(NoSignal, InfoRefusesInfiniteCoordinates) {
  const fs::path d = tmp_dir("hardening_inf");
  auto expect_refused = [](const fs::path& f) {
    const CliRun r = run("info " + q(f));
    EXPECT_EQ(r.code, 1) << f << ": " << r.out;
    EXPECT_NE(r.out.find(f.filename().string() + ": "), std::string::npos) << r.out;
    EXPECT_TRUE(r.out.find("not a finite number") != std::string::npos ||
                r.out.find("infinite") != std::string::npos ||
                r.out.find("NaN") != std::string::npos)
        << r.out;
  };
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nend_header\n0 0 0\n";
  for (const std::string& line : std::vector<std::string>{"1 2 inf", "1 nan 3", "1e999 2 3"}) {
    std::ofstream(d / "p.ply", std::ios::trunc) << head << line << "\n";
    expect_refused(d / "p.ply");
    std::ofstream(d / "p.obj", std::ios::trunc) << "v 0 0 0\nv " << line << "\n";
    expect_refused(d / "p.obj");
    std::ofstream(d / "p.off", std::ios::trunc) << "OFF\n2 0 0\n0 0 0\n" << line << "\n";
    expect_refused(d / "p.off");
  }
  // binary PLY: an IEEE infinity in the data
  {
    std::ofstream o(d / "b.ply", std::ios::binary | std::ios::trunc);
    o << "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\n"
         "property double y\nproperty double z\nend_header\n";
    const double v[6] = {0, 0, 0, 1, HUGE_VAL, 2};
    o.write(reinterpret_cast<const char*>(v), sizeof v);
  }
  expect_refused(d / "b.ply");
}

/// An ASCII PLY mesh.
void write_ply(const fs::path& p, const std::vector<std::array<double, 3>>& v,
               const std::vector<std::array<int, 3>>& f) {
  std::ofstream o(p);
  o << "ply\nformat ascii 1.0\nelement vertex " << v.size()
    << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << f.size()
    << "\nproperty list uchar int vertex_indices\nend_header\n";
  o.precision(17);
  for (const auto& x : v) o << x[0] << " " << x[1] << " " << x[2] << "\n";
  for (const auto& t : f) o << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
}

TEST(NoSignal, LodRefusesDegenerateMeshesAndExtremeCoordinatesAtLoad) {
  const fs::path d = tmp_dir("hardening_lod");
  // every face degenerate: collinear or repeated vertices
  write_ply(d / "flat.ply", {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}},
            {{0, 1, 2}, {1, 2, 3}, {0, 0, 1}, {3, 3, 3}});
  CliRun r = run("lod " + q(d / "flat.ply") + " -o " + q(d / "o1"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("flat.ply: all 4 triangles are degenerate"), std::string::npos) << r.out;
  // a cube with one vertex 1e12 m away
  std::vector<std::array<double, 3>> v;
  for (int i = 0; i < 8; ++i) v.push_back({double(i & 1), double((i >> 1) & 1), double(i >> 2)});
  v.push_back({1e12, 0, 0});
  write_ply(d / "far.ply", v,
            {{0, 2, 3},
             {0, 3, 1},
             {4, 5, 7},
             {4, 7, 6},
             {0, 1, 5},
             {0, 5, 4},
             {2, 6, 7},
             {2, 7, 3},
             {0, 4, 6},
             {0, 6, 2},
             {1, 3, 7},
             {1, 7, 5},
             {8, 1, 5}});
  r = run("lod " + q(d / "far.ply") + " -o " + q(d / "o2"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("far.ply: vertex/point"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("extreme magnitude"), std::string::npos) << r.out;
}

/// A tileset whose root holds `depth` nested children.
void write_deep_tileset(const fs::path& p, int depth) {
  std::string s = R"({"asset": {"version": "1.1"}, "geometricError": 1, "root": )";
  for (int i = 0; i < depth; ++i) s += R"({"geometricError": 1, "children": [)";
  s += R"({"geometricError": 0})";
  for (int i = 0; i < depth; ++i) s += "]}";
  s += "}";
  std::ofstream(p) << s;
}

TEST(NoSignal, EvalBoundsNestingAndFanOutOfTilesets) {
  const fs::path d = tmp_dir("hardening_eval");
  write_deep_tileset(d / "deep.json", 200000);
  CliRun r =
      sh("ulimit -v 2000000; " + std::string(CITYLOD_BINARY) + " eval " + q(d / "deep.json"));
  EXPECT_EQ(r.code, 1) << r.out.substr(0, 400);
  EXPECT_NE(r.out.find("deep.json: tiles nested deeper than"), std::string::npos)
      << r.out.substr(0, 400);
  // fan-out: each level names the next level 12 times (12^8 visits without the bound)
  for (int level = 0; level < 8; ++level) {
    nlohmann::json children = nlohmann::json::array();
    for (int k = 0; k < 12; ++k)
      children.push_back({{"geometricError", 1},
                          {"content", {{"uri", "level" + std::to_string(level + 1) + ".json"}}}});
    nlohmann::json ts{{"asset", {{"version", "1.1"}}},
                      {"geometricError", 1},
                      {"root", {{"geometricError", 1}, {"children", children}}}};
    std::ofstream(d / ("level" + std::to_string(level) + ".json")) << ts.dump();
  }
  write_deep_tileset(d / "level8.json", 1);
  const auto t0 = std::chrono::steady_clock::now();
  r = sh("ulimit -v 2000000; timeout 60 " + std::string(CITYLOD_BINARY) + " eval " +
         q(d / "level0.json"));
  EXPECT_EQ(r.code, 1) << r.out.substr(0, 400);
  EXPECT_NE(r.out.find("referenced more than once"), std::string::npos) << r.out.substr(0, 400);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10);
}

TEST(NoSignal, AGlbDeclaringMoreThanItHoldsIsRefusedBeforeAllocating) {
  const fs::path d = tmp_dir("hardening_glb");
  // glTF JSON: one triangle whose position accessor claims 200 million vertices without data
  const std::string json =
      R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"scene":0,"nodes":[{"mesh":0}],)"
      R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
      R"("accessors":[{"componentType":5126,"count":200000000,"type":"VEC3"}]})";
  std::string chunk = json;
  while (chunk.size() % 4) chunk += ' ';
  std::string glb = "glTF";
  auto u32 = [&](std::uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  u32(std::uint32_t(12 + 8 + chunk.size()));
  u32(std::uint32_t(chunk.size()));
  u32(0x4E4F534A);
  glb += chunk;
  fs::create_directories(d / "ts");
  std::ofstream(d / "ts" / "t.glb", std::ios::binary) << glb;
  std::ofstream(d / "ts" / "tileset.json")
      << R"({"asset": {"version": "1.1"}, "geometricError": 1,)"
         R"( "root": {"geometricError": 0, "content": {"uri": "t.glb"}}})";
  const CliRun r = sh("ulimit -v 1500000; " + std::string(CITYLOD_BINARY) + " eval " + q(d / "ts"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("t.glb: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("without data"), std::string::npos) << r.out;
}

// ------------------------------------------------------------ low items

TEST(LowItems, CellSizeHasALowerBound) {
  const fs::path d = tmp_dir("hardening_cell");
  for (const char* c : {"0.000001", "1", "9.9"}) {
    const CliRun r = run("split " + q(kExample / "delft_small.las") +
                         " --crs EPSG:28992 --cell-size " + c + " -o " + q(d / "w"));
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("--cell-size must be at least 10 m"), std::string::npos) << r.out;
  }
}

TEST(LowItems, SplitNeverReplacesAForeignChunksFolder) {
  const fs::path d = tmp_dir("hardening_foreign");
  fs::create_directories(d / "w" / "chunks");
  std::ofstream(d / "w" / "chunks" / "precious.txt") << "mine\n";
  const CliRun r = run("split " + example_args() + " -o " + q(d / "w"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("chunks: exists and is not empty"), std::string::npos) << r.out;
  EXPECT_EQ(slurp(d / "w" / "chunks" / "precious.txt"), "mine\n");
}

TEST(LowItems, ATruncatedChunkIsNoticedOnResume) {
  const fs::path d = tmp_dir("hardening_truncated");
  const fs::path work = d / "w";
  ASSERT_EQ(run("split " + example_args() + " -o " + q(work)).code, 0);
  const nlohmann::json m = nlohmann::json::parse(slurp(work / "manifest.json"));
  const std::string id = m["chunks"][0]["id"];
  const fs::path chunk = work / "chunks" / (id + ".ply");
  const std::string good = slurp(chunk);
  fs::resize_file(chunk, good.size() / 2);
  // lod WORK: that building fails with a clear reason, naming the chunk
  CliRun r = run("lod " + q(work) + " --building " + id);
  EXPECT_NE(r.out.find(id + ".ply: missing, truncated or changed since split"), std::string::npos)
      << r.out;
  // split again (up to date by its inputs): notices and rewrites it
  r = run("split " + example_args() + " -o " + q(work));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("truncated or changed since split; splitting again"), std::string::npos)
      << r.out;
  EXPECT_EQ(slurp(chunk), good);
}

}  // namespace
