// Hostile work directories, concurrent runs, interrupted publications and
// special files through the real `citylod` binary (issue 13): a clear error
// line naming the file, a non-zero exit, nothing touched outside the output.
#include <gtest/gtest.h>

#include "support/cli_run.hpp"
#include "support/las_write.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
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

/// "ulimit -v KB; " for the shell: the binary's memory is capped. Not under
/// AddressSanitizer, whose shadow memory reserves terabytes of address space
/// (the Release run checks the cap; the sanitizer run checks the rest).
std::string mem_cap(long kb) {
#if defined(__SANITIZE_ADDRESS__)
  (void)kb;
  return "";
#else
  return "ulimit -v " + std::to_string(kb) + "; ";
#endif
}

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
        // "(pid N)" follows when the holder had written it (not yet, at a simultaneous start)
        EXPECT_NE(log.find("in use by another citylod run"), std::string::npos) << log;
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

TEST(NoSignal, ALongEpsgCodeInALasCrsRecordIsAClearError) {
  const fs::path d = tmp_dir("hardening_las_crs");
  const fs::path las = d / "long_crs.las";
  {
    LasWriter w(las.string(), {0.01, 0.01, 0.01}, {0, 0, 0}, "EPSG:" + std::string(60000, '9'));
    for (int i = 0; i < 100; ++i) w.add(85000 + i % 10, 446000 + i / 10, 1);
    w.close();
  }
  const CliRun r = run("split " + q(las) + " -o " + q(d / "w"));
  EXPECT_GT(r.code, 0) << r.out.substr(0, 500);  // an error, not a signal (-1)
  EXPECT_NE(r.out.find("long_crs.las"), std::string::npos) << r.out.substr(0, 500);
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
  CliRun r = sh(mem_cap(2000000) + std::string(CITYLOD_BINARY) + " eval " + q(d / "deep.json"));
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
  r = sh(mem_cap(2000000) + "timeout 60 " + std::string(CITYLOD_BINARY) + " eval " +
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
  const CliRun r = sh(mem_cap(1500000) + std::string(CITYLOD_BINARY) + " eval " + q(d / "ts"));
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

// Issue 27 item 2: a GeoPackage with 8 pages overwritten (SQLite: "database
// disk image is malformed") was read as a short layer (40 of 160 features) and
// the split exited 0. A read error is now one line naming the file.
TEST(LowItems, ADamagedGeoPackageIsAnErrorNotAShortLayer) {
  const fs::path src = fs::path(CITYLOD_SHARED_DATA) / "delft" / "bgt_pand.gpkg";
  if (!fs::exists(src)) GTEST_SKIP() << "shared data missing: " << src;
  const fs::path d = tmp_dir("hardening_damaged_gpkg");
  std::string bytes = slurp(src);
  const std::size_t page = 4096, start = (bytes.size() / page) / 2;
  ASSERT_GT(bytes.size(), (start + 8) * page);
  for (std::size_t k = 0; k < 8 * page; ++k) bytes[start * page + k] = char(0xAB);
  std::ofstream(d / "damaged.gpkg", std::ios::binary) << bytes;
  const CliRun r =
      run("split " + q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
          q(d / "damaged.gpkg") + " -o " + q(d / "w"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("damaged.gpkg: reading stopped after feature 40"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("malformed"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "w" / "manifest.json"));
  // the intact file: the same 160 features read, 12 buildings
  const CliRun ok = run("split " + q(kExample / "delft_small.las") +
                        " --crs EPSG:28992 --footprints " + q(src) + " -o " + q(d / "ok"));
  EXPECT_EQ(ok.code, 0) << ok.out;
}

// Issue 27: footprints whose geometries are all empty ended in "(see the notes
// above)" with no notes above (they are printed on success only): the reason is
// now in the error line.
TEST(LowItems, FootprintsWithoutPolygonsSayWhy) {
  const fs::path d = tmp_dir("hardening_empty_footprints");
  std::ofstream(d / "empty.geojson")
      << R"({"type":"FeatureCollection","features":[)"
      << R"({"type":"Feature","properties":{"id":"a"},"geometry":null},)"
      << R"({"type":"Feature","properties":{"id":"b"},"geometry":{"type":"Polygon","coordinates":[]}}]})";
  const CliRun r =
      run("split " + q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
          q(d / "empty.geojson") + " -o " + q(d / "w"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("empty.geojson: none of its 2 features is a usable polygon ("),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("see the notes above"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
}

// Issue 27 item 1: a footprint cost its area, not the data under it. A 10 km
// square around the 72 m example tile (a park or an airport of a city's
// footprint layer) did not finish in 60 s; the region is now clipped to the
// data's reach: measured 0.26 s, one chunk with the tile's 13,605 building points.
TEST(LowItems, AFootprintCostsTheDataUnderItNotItsArea) {
  const fs::path d = tmp_dir("hardening_big_footprint");
  std::ofstream(d / "park.geojson")
      << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":)"
      << R"("urn:ogc:def:crs:EPSG::28992"}},"features":[{"type":"Feature","properties":)"
      << R"({"id":"park"},"geometry":{"type":"Polygon","coordinates":[[[80000,442500],)"
      << R"([90000,442500],[90000,452500],[80000,452500],[80000,442500]]]}}]})";
  const auto t0 = std::chrono::steady_clock::now();
  const CliRun r =
      run("split " + q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
          q(d / "park.geojson") + " -o " + q(d / "w"));
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_LT(s, 30.0) << "a 10 km footprint over a 72 m tile";
  EXPECT_NE(r.out.find("1 chunks"), std::string::npos) << r.out;
}

// Issue 27 item 4: a 100 km cell over the 1.6 MB example tile sized the
// region's grids from the cell, not the data: "out of memory" at once, with
// the whole argument list as the subject. Now the region is the data's reach.
TEST(LowItems, AHugeCellCostsTheDataInItNotItsArea) {
  const fs::path d = tmp_dir("hardening_huge_cell");
  const CliRun r =
      run("split " + q(kExample / "delft_small.las") +
          " --crs EPSG:28992 --memory-limit 1000000T --cell-size 100000 -o " + q(d / "w"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("-> 5 chunks"), std::string::npos) << r.out;
}

// Issue 27: 10,000 footprints of 6 cm on one building (a 10 cm grid over its
// roof) were blamed on "wrong CRS, or footprints of another area": they meet the
// data and hold its points, too few in each. The line now says so. (No buffer:
// with one, the grid's edge squares take the building points around the grid.)
TEST(LowItems, TinyFootprintsAreCalledTooSmallNotMisplaced) {
  const fs::path d = tmp_dir("hardening_tiny_footprints");
  {
    std::ofstream f(d / "tiny.geojson");
    f << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":)"
      << R"("urn:ogc:def:crs:EPSG::28992"}},"features":[)";
    char buf[256];
    for (int i = 0; i < 100; ++i)
      for (int j = 0; j < 100; ++j) {
        const double x = 85025.0 + 0.1 * i, y = 447460.0 + 0.1 * j, e = 0.06;
        std::snprintf(buf, sizeof buf,
                      R"(%s{"type":"Feature","properties":{"id":"t%d_%d"},"geometry":)"
                      R"({"type":"Polygon","coordinates":[[[%.3f,%.3f],[%.3f,%.3f],[%.3f,%.3f],)"
                      R"([%.3f,%.3f],[%.3f,%.3f]]]}})",
                      i + j ? "," : "", i, j, x, y, x + e, y, x + e, y + e, x, y + e, x, y);
        f << buf;
      }
    f << "]}";
  }
  const CliRun r =
      run("split " + q(kExample / "delft_small.las") + " --crs EPSG:28992 --footprints " +
          q(d / "tiny.geojson") + " --footprint-buffer 0 -o " + q(d / "w"));
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("tiny.geojson: none of its 10000 footprints"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("much smaller than the buildings"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("another area"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "w" / "manifest.json"));
}

// Issue 27: a CRS in nanometres (no area of use to test against) exited 0 with an empty
// manifest; the unit is now named, and nothing is written.
TEST(LowItems, ACrsInNanometresIsAnErrorNotAnEmptyScene) {
  const fs::path d = tmp_dir("hardening_nanometres");
  const CliRun r = run("split " + q(kExample / "delft_small.las") +
                       " --crs '+proj=tmerc +lon_0=4.37 +lat_0=52 +datum=WGS84 +to_meter=1e-9 "
                       "+type=crs' -o " +
                       q(d / "w"));
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("delft_small.las: the data spans"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("smaller than any building"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "w" / "manifest.json"));
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

// ------------------------------------------------------------ serve

struct Server {
  pid_t pid = -1;
  int port = 0;
  Server(const fs::path& ts, bool cors) {
    int fds[2];
    EXPECT_EQ(::pipe(fds), 0);
    pid = ::fork();
    if (pid == 0) {
      ::dup2(fds[1], 1);
      ::close(fds[0]);
      const std::string bin = CITYLOD_BINARY;
      if (cors)
        ::execl(bin.c_str(), bin.c_str(), "serve", "-q", ts.c_str(), "--port", "0", "--cors",
                (char*)nullptr);
      else
        ::execl(bin.c_str(), bin.c_str(), "serve", "-q", ts.c_str(), "--port", "0", (char*)nullptr);
      ::_exit(127);
    }
    ::close(fds[1]);
    std::string line;
    char c;
    while (line.find('\n') == std::string::npos && ::read(fds[0], &c, 1) == 1) line.push_back(c);
    ::close(fds[0]);
    const auto at = line.find("http://127.0.0.1:");
    EXPECT_NE(at, std::string::npos) << line;
    if (at != std::string::npos) port = std::stoi(line.substr(at + 17));
  }
  ~Server() {
    ::kill(pid, SIGTERM);
    int st = 0;
    ::waitpid(pid, &st, 0);
  }
  /// Peak resident memory of the server (kB).
  long peak_kb() const {
    std::ifstream f("/proc/" + std::to_string(pid) + "/status");
    std::string l;
    while (std::getline(f, l))
      if (l.rfind("VmHWM:", 0) == 0) return std::stol(l.substr(6));
    return -1;
  }
};

int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(std::uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

std::string get(int port, const std::string& path, const std::string& extra = "") {
  const int fd = connect_to(port);
  if (fd < 0) return "";
  const std::string req =
      "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\n" + extra + "Connection: close\r\n\r\n";
  (void)!::write(fd, req.data(), req.size());
  std::string resp;
  char buf[65536];
  ssize_t n;
  while ((n = ::read(fd, buf, sizeof buf)) > 0) resp.append(buf, std::size_t(n));
  ::close(fd);
  return resp;
}

std::string body_of(const std::string& resp) {
  const auto at = resp.find("\r\n\r\n");
  return at == std::string::npos ? "" : resp.substr(at + 4);
}

TEST(Serve, NothingOutsideTheTilesetIsServedThroughSymbolicLinks) {
  const fs::path d = tmp_dir("hardening_serve_links");
  fs::create_directories(d / "ts");
  fs::create_directories(d / "outside");
  std::ofstream(d / "ts" / "tileset.json") << R"({"asset": {"version": "1.1"}})";
  std::ofstream(d / "outside" / "secret.txt") << "TOP-SECRET\n";
  std::ofstream(d / "ts" / "inside.txt") << "fine\n";
  fs::create_symlink(d / "outside" / "secret.txt", d / "ts" / "secret.txt");
  fs::create_directory_symlink(d / "outside", d / "ts" / "up");
  fs::create_symlink("/etc/passwd", d / "ts" / "passwd");
  fs::create_symlink(d / "ts" / "inside.txt", d / "ts" / "alias.txt");  // inside: served
  Server s(d / "ts", false);
  ASSERT_GT(s.port, 0);
  for (const char* p : {"/tileset/secret.txt", "/tileset/up/secret.txt", "/tileset/passwd"}) {
    const std::string r = get(s.port, p);
    EXPECT_EQ(r.find("200 OK"), std::string::npos) << p << ": " << r;
    EXPECT_EQ(r.find("TOP-SECRET"), std::string::npos) << p;
    EXPECT_EQ(r.find("root:"), std::string::npos) << p;
  }
  EXPECT_EQ(body_of(get(s.port, "/tileset/alias.txt")), "fine\n");
  // CORS only when asked
  EXPECT_EQ(get(s.port, "/tileset/tileset.json").find("Access-Control-Allow-Origin"),
            std::string::npos);
  Server c(d / "ts", true);
  EXPECT_NE(get(c.port, "/tileset/tileset.json").find("Access-Control-Allow-Origin: *"),
            std::string::npos);
}

TEST(Serve, RangesStreamingAndSlowClients) {
  const fs::path d = tmp_dir("hardening_serve_range");
  fs::create_directories(d / "ts");
  std::ofstream(d / "ts" / "tileset.json") << R"({"asset": {"version": "1.1"}})";
  const std::size_t big = 96u << 20;
  {
    std::string chunk(1 << 20, '\0');
    for (std::size_t i = 0; i < chunk.size(); ++i) chunk[i] = char('a' + i % 26);
    std::ofstream o(d / "ts" / "big.bin", std::ios::binary);
    for (std::size_t k = 0; k < big / chunk.size(); ++k) o << chunk;
  }
  Server s(d / "ts", false);
  ASSERT_GT(s.port, 0);
  const long base_kb = s.peak_kb();  // the binary and its libraries, before any file is served
  std::string r = get(s.port, "/tileset/big.bin", "Range: bytes=10-19\r\n");
  EXPECT_NE(r.find("206 Partial Content"), std::string::npos) << r.substr(0, 300);
  EXPECT_NE(r.find("Content-Range: bytes 10-19/" + std::to_string(big)), std::string::npos);
  EXPECT_EQ(body_of(r), "klmnopqrst");
  r = get(s.port, "/tileset/big.bin", "Range: bytes=-3\r\n");
  EXPECT_EQ(body_of(r).size(), 3u);
  r = get(s.port, "/tileset/big.bin", "Range: bytes=" + std::to_string(big) + "-\r\n");
  EXPECT_NE(r.find("416"), std::string::npos) << r.substr(0, 300);
  // several ranges: multipart/byteranges with each part's Content-Range (issue 27)
  r = get(s.port, "/tileset/big.bin", "Range: bytes=0-1, 26-28\r\n");
  EXPECT_NE(r.find("206 Partial Content"), std::string::npos) << r.substr(0, 300);
  EXPECT_NE(r.find("Content-Type: multipart/byteranges; boundary="), std::string::npos);
  {
    const auto b = r.find("boundary="), e = r.find("\r\n", b);
    const std::string boundary = r.substr(b + 9, e - b - 9);
    const std::string tail = "/" + std::to_string(big) + "\r\n\r\n";
    const std::string want = "\r\n--" + boundary +
                             "\r\nContent-Type: application/octet-stream\r\n"
                             "Content-Range: bytes 0-1" +
                             tail + "ab\r\n--" + boundary +
                             "\r\nContent-Type: application/octet-stream\r\n"
                             "Content-Range: bytes 26-28" +
                             tail + "abc\r\n--" + boundary + "--\r\n";
    EXPECT_EQ(body_of(r), want);
    EXPECT_NE(r.find("Content-Length: " + std::to_string(want.size()) + "\r\n"), std::string::npos);
  }
  // overlapping ranges are coalesced into one; unsatisfiable ones among them dropped
  r = get(s.port, "/tileset/big.bin", "Range: bytes=2-5,4-7, " + std::to_string(big + 5) + "-\r\n");
  EXPECT_NE(r.find("Content-Range: bytes 2-7/"), std::string::npos) << r.substr(0, 300);
  EXPECT_EQ(body_of(r), "cdefgh");
  // a malformed range set is ignored: the whole file
  r = get(s.port, "/tileset/tileset.json", "Range: bytes=1-2,x\r\n");
  EXPECT_NE(r.find("200 OK"), std::string::npos) << r.substr(0, 300);
  // an oversized request line or header block gets its status, not a silent close
  EXPECT_NE(get(s.port, "/tileset/" + std::string(100000, 'a')).find("HTTP/1.1 414 "),
            std::string::npos);
  EXPECT_NE(get(s.port, "/tileset/tileset.json", "X-Big: " + std::string(100000, 'b') + "\r\n")
                .find("HTTP/1.1 431 "),
            std::string::npos);
  // 70 clients that send nothing do not stall the others
  std::vector<int> slow;
  for (int i = 0; i < 70; ++i) slow.push_back(connect_to(s.port));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(get(s.port, "/tileset/tileset.json").find("200 OK"), std::string::npos);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  for (int fd : slow) ::close(fd);
  // 6 parallel whole-file GETs of 96 MB: streamed, not held in memory
  std::vector<std::thread> ts;
  std::vector<std::size_t> got(6);
  for (int i = 0; i < 6; ++i)
    ts.emplace_back([&, i] { got[std::size_t(i)] = get(s.port, "/tileset/big.bin").size(); });
  for (auto& t : ts) t.join();
  for (auto g : got) EXPECT_GT(g, big);
  // whole-file reads would add 6 x 96 MB; streaming adds its buffers only
  EXPECT_LT(s.peak_kb() - base_kb, 48 * 1024) << "peak RSS of serve above its start";
}

// ------------------------------------------------------------ the LOD worker dies with its parent

/// Pids of the children of `pid`.
std::vector<pid_t> children_of(pid_t pid) {
  std::vector<pid_t> out;
  std::ifstream f("/proc/" + std::to_string(pid) + "/task/" + std::to_string(pid) + "/children");
  pid_t c;
  while (f >> c) out.push_back(c);
  return out;
}

bool alive(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string s;
  std::getline(f, s);
  const auto close = s.rfind(')');
  return !s.empty() && close != std::string::npos && s[close + 2] != 'Z';
}

TEST(Serve, TheLodWorkerDiesWithItsParent) {
  const fs::path d = tmp_dir("hardening_worker");
  ASSERT_EQ(run("split " + example_args() + " -o " + q(d / "w")).code, 0);
  for (const int sig : {SIGKILL, SIGTERM}) {
    SCOPED_TRACE(sig);
    fs::remove_all(d / "w" / "lod");
    const pid_t pid = ::fork();
    if (pid == 0) {
      const std::string bin = CITYLOD_BINARY, work = (d / "w").string();
      ::execl(bin.c_str(), bin.c_str(), "lod", "-q", work.c_str(), "--threads", "1",
              (char*)nullptr);
      ::_exit(127);
    }
    std::vector<pid_t> kids;
    for (int i = 0; i < 2000 && kids.empty(); ++i) {
      kids = children_of(pid);
      if (kids.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ASSERT_EQ(kids.size(), 1u) << "no worker seen";
    ::kill(pid, sig);
    int st = 0;
    ::waitpid(pid, &st, 0);
    EXPECT_TRUE(WIFSIGNALED(st) && WTERMSIG(st) == sig) << st;
    bool gone = false;
    for (int i = 0; i < 200 && !gone; ++i) {
      gone = !alive(kids[0]);
      if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_TRUE(gone) << "worker " << kids[0] << " outlived its parent";
    if (!gone) ::kill(kids[0], SIGKILL);
  }
}

}  // namespace
