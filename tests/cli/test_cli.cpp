// Runs the real `citylod` binary: exit codes, stdout/stderr, real data.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

namespace {

struct Result {
  int code = -1;
  std::string out, err;
};

std::string slurp(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// Per process: ctest runs the tests of this file in parallel processes, which
// must not share stdout.txt / stderr.txt or the files they write.
std::string tmp_dir() {
  std::string d = std::string(CITYLOD_TEST_TMP) + "/cli-" + std::to_string(::getpid());
  std::filesystem::create_directories(d);
  return d;
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

Result run(const std::string& args) {
  const std::string d = tmp_dir();
  const std::string out = d + "/stdout.txt", err = d + "/stderr.txt";
  std::string cmd =
      quote(CITYLOD_BINARY) + " " + args + " >" + quote(out) + " 2>" + quote(err) + " </dev/null";
  int st = std::system(cmd.c_str());
  Result r;
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + (WIFSIGNALED(st) ? WTERMSIG(st) : 0);
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

std::string shared(const std::string& rel) {
  return std::string(CITYLOD_SHARED_DATA) + "/" + rel;
}

std::string write_tmp(const std::string& name, const std::string& bytes) {
  std::string p = tmp_dir() + "/" + name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

#define REQUIRE_SHARED(p) \
  if (!std::filesystem::exists(p)) GTEST_SKIP() << "shared data missing: " << (p)

}  // namespace

TEST(Cli, Version) {
  Result r = run("--version");
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out, "citylod 0.1.0\n");
}

TEST(Cli, HelpListsSubcommands) {
  Result r = run("--help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("usage: citylod"), std::string::npos);
  EXPECT_NE(r.out.find("  info"), std::string::npos);
  EXPECT_NE(r.out.find("--log-level"), std::string::npos);
  Result none = run("");
  EXPECT_EQ(none.code, 2);
  EXPECT_NE(none.err.find("commands:"), std::string::npos);
}

TEST(Cli, SubcommandHelp) {
  Result r = run("info --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("usage: citylod info [options] FILE..."), std::string::npos);
  EXPECT_NE(r.out.find("--json"), std::string::npos);
  EXPECT_NE(r.out.find("--quiet"), std::string::npos);
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST(Cli, UsageErrorsExit2) {
  Result r = run("info --bogus x.ply");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("unknown option '--bogus'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("see 'citylod info --help'"), std::string::npos) << r.err;
  Result u = run("frobnicate");
  EXPECT_EQ(u.code, 2);
  EXPECT_NE(u.err.find("unknown command 'frobnicate'"), std::string::npos);
  EXPECT_NE(u.err.find("see 'citylod --help'"), std::string::npos);
  Result m = run("info");
  EXPECT_EQ(m.code, 2);
  EXPECT_NE(m.err.find("missing argument FILE"), std::string::npos) << m.err;
  Result l = run("--log-level loud info x");
  EXPECT_EQ(l.code, 2);
  EXPECT_NE(l.err.find("invalid log level 'loud'"), std::string::npos) << l.err;
  Result g = run("--nope");
  EXPECT_EQ(g.code, 2);
}

TEST(Cli, GlobalOptionsBeforeAndAfterSubcommand) {
  std::string p = write_tmp("g.xyz", "1 2 3\n4 5 6\n");
  EXPECT_EQ(run("--log-level debug --quiet info " + quote(p)).code, 0);
  EXPECT_EQ(run("info --log-level=error -q " + quote(p)).code, 0);
  EXPECT_EQ(run("info -- " + quote(p)).code, 0);
}

TEST(Cli, InfoCgalBuilding) {
  const std::string p = shared("single_building/cgal_building.ply");
  REQUIRE_SHARED(p);
  Result r = run("info " + quote(p));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("points:         100000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("attributes:     normals"), std::string::npos) << r.out;
}

TEST(Cli, InfoAhn3Las) {
  const std::string p = shared("delft/ahn3_cropped_2.las");
  REQUIRE_SHARED(p);
  Result r = run("info " + quote(p));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("points:         208432"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("point format:   1 "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("      6 building"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("      2 ground"), std::string::npos) << r.out;

  Result j = run("info --json " + quote(p));
  ASSERT_EQ(j.code, 0) << j.err;
  auto doc = nlohmann::json::parse(j.out);
  EXPECT_EQ(doc["point_count"], 208432);
  EXPECT_EQ(doc["las"]["point_format"], 1);
  bool has6 = false;
  for (const auto& c : doc["classes"])
    if (c["code"] == 6 && c["count"].get<long>() > 0) has6 = true;
  EXPECT_TRUE(has6);
}

TEST(Cli, InfoAutzenCrsInFeet) {
  const std::string p = shared("las/autzen_trim.las");
  REQUIRE_SHARED(p);
  Result r = run("info " + quote(p));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("crs:            NAD_1983_HARN_Lambert_Conformal_Conic"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("linear unit:    foot"), std::string::npos) << r.out;
  Result j = run("info -j " + quote(p));
  auto doc = nlohmann::json::parse(j.out);
  EXPECT_EQ(doc["crs"]["linear_unit"], "foot");
  EXPECT_DOUBLE_EQ(doc["crs"]["linear_unit_m"].get<double>(), 0.3048);
}

TEST(Cli, InfoLaz) {
  const std::string p = shared("delft/ahn3_cropped_2.laz");
  REQUIRE_SHARED(p);
  Result r = run("info " + quote(p));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("compressed:     LASzip"), std::string::npos) << r.out;
}

TEST(Cli, InfoAllSharedFiles) {
  const std::string dir = CITYLOD_SHARED_DATA;
  REQUIRE_SHARED(dir);
  int n = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (ext != ".ply" && ext != ".off" && ext != ".obj" && ext != ".las" && ext != ".laz") continue;
    Result r = run("info --json " + quote(e.path().string()));
    EXPECT_EQ(r.code, 0) << e.path() << ": " << r.err;
    EXPECT_TRUE(nlohmann::json::accept(r.out)) << e.path();
    ++n;
  }
  EXPECT_GE(n, 11);
  // Several files at once: one JSON array.
  Result many = run("info --json " + quote(dir + "/las/sample_c.las") + " " +
                    quote(dir + "/las/autzen_trim.las"));
  EXPECT_EQ(many.code, 0);
  EXPECT_EQ(nlohmann::json::parse(many.out).size(), 2u);
}

TEST(Cli, InfoBadInputsFailWithOneLine) {
  struct Case {
    std::string path, reason;
  };
  std::string ply_hdr =
      "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  std::string truncated = write_tmp("truncated.ply", ply_hdr + std::string(12 * 40, '\0'));
  // A LAS 1.2 file whose header claims more points than it holds.
  std::string las;
  const std::string src = shared("las/sample_c.las");
  if (std::filesystem::exists(src)) {
    las = slurp(src);
    las.resize(las.size() / 2);
  }
  std::string lying = las.empty() ? std::string() : write_tmp("lying.las", las);
  std::string readme = std::string(CITYLOD_SOURCE_DIR) + "/README.md";
  if (!std::filesystem::exists(readme)) readme = write_tmp("README.md", "# title\n\ntext\n");
  std::vector<Case> cases = {
      {tmp_dir() + "/missing.ply", "no such file"},
      {readme, "not a point cloud or mesh file (unrecognised format)"},
      {truncated, "truncated: header declares 100 points but the file holds only 40"},
      {write_tmp("nan.xyz", "1 2 3\nnan 2 3\n"), "NaN coordinate at point #1"},
      {write_tmp("empty.ply", ""), "empty file"},
      {write_tmp("badface.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
       "face #0 references vertex 7"},
  };
  if (!lying.empty())
    cases.push_back({lying, "truncated: header declares 14408 points but the file holds only"});
  for (const auto& c : cases) {
    Result r = run("info " + quote(c.path));
    EXPECT_EQ(r.code, 1) << c.path << "\n" << r.err;
    EXPECT_EQ(count_lines(r.err), 1) << r.err;
    EXPECT_EQ(r.err.rfind("citylod: error: " + c.path + ": ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(c.reason), std::string::npos) << r.err;
  }
}

// A single building keeps a terrain sheet as a plinth (the model represents
// all of its input); a work directory's buildings (city runs: chunks without
// ground, with a footprint) cut it off and get walls along their footprint.
// `citylod lod --help` lists every LOD parameter from its one declaration: value,
// unit, rule, and the city value where a work directory's buildings differ.
TEST(Cli, LodHelpListsTheParameters) {
  const Result r = run("lod --help");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("LOD parameters (--set NAME=VALUE"), std::string::npos) << r.out;
  const auto at = r.out.find("  planes.epsilon = 0.15 m ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const auto eol = r.out.find('\n', at);
  EXPECT_NE(r.out.substr(at, eol - at).find("must be > 0"), std::string::npos);
  // its doc on the next line, indented under it
  const std::string doc = "      max point-to-plane distance of a plane's inliers\n";
  EXPECT_EQ(r.out.compare(eol + 1, doc.size(), doc), 0) << r.out;
  EXPECT_NE(r.out.find("  closure.terrain = plinth (city: cut) "), std::string::npos) << r.out;
  const Result t = run("tile --help");
  ASSERT_EQ(t.code, 0) << t.err;
  EXPECT_NE(t.out.find("  closure.terrain = cut "), std::string::npos) << t.out;
}

TEST(Cli, LodTerrainDefaultsDependOnTheInput) {
  const Result one = run("lod --print-params");
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_NE(one.out.find("closure.terrain = plinth\n"), std::string::npos) << one.out;
  EXPECT_NE(one.out.find("closure.footprint_walls = false\n"), std::string::npos) << one.out;
  const Result city = run("lod " + quote(tmp_dir()) + " --print-params");
  ASSERT_EQ(city.code, 0) << city.err;
  EXPECT_NE(city.out.find("closure.terrain = cut\n"), std::string::npos) << city.out;
  EXPECT_NE(city.out.find("closure.footprint_walls = true\n"), std::string::npos) << city.out;
  const Result over =
      run("lod " + quote(tmp_dir()) + " --print-params --set closure.terrain=plinth");
  ASSERT_EQ(over.code, 0) << over.err;
  EXPECT_NE(over.out.find("closure.terrain = plinth\n"), std::string::npos) << over.out;
}

// `citylod lod` ends with the finest model's figures (the acceptance numbers a
// user checks first): triangles, volume, e1, e2.
TEST(Cli, LodPrintsTheFinestModel) {
  const std::string in = shared("ahn3_building_lod2/AHN3_13856.ply");
  REQUIRE_SHARED(in);
  const Result r = run("lod " + quote(in) + " --out " + quote(tmp_dir() + "/lod_finest"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto at = r.err.find("lod: finest model: ");
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string line = r.err.substr(at, r.err.find('\n', at) - at);
  EXPECT_NE(line.find(" triangles, volume "), std::string::npos) << line;
  EXPECT_NE(line.find(" % of the bbox diagonal"), std::string::npos) << line;
  double e2 = -1;
  ASSERT_EQ(std::sscanf(line.c_str() + line.find("e2 ") + 3, "%lf", &e2), 1) << line;
  EXPECT_GT(e2, 0.0);
  EXPECT_LE(e2, 0.5);
}
