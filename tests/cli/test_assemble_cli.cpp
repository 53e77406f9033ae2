// End-to-end tests of `citylod assemble` and `citylod serve` with the real
// binary: tileset invariants, the Khronos glTF validator (node), error
// messages, kill safety and the headless-browser viewer test (chromium).
//
// Node-based checks need tests/node/node_modules: scripts/install-node-tools.sh.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <proj.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "tiler/test_work_support.hpp"

namespace citylod::test {
namespace {

const std::string kBin = CITYLOD_BINARY;
const fs::path kNode = fs::path(CITYLOD_SOURCE_DIR) / "tests" / "node";

std::string tmp_dir(const std::string& name) {
  const fs::path p = fs::path(CITYLOD_TEST_TMP) / "assemble_cli" / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

struct Proc {
  int code = -1;
  std::string output;  // stdout + stderr
};

Proc run(const std::string& cmd) {
  Proc r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = pclose(p);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

std::string q(const std::string& s) {
  return "'" + s + "'";
}

bool node_tools_installed() {
  return fs::exists(kNode / "node_modules" / "gltf-validator") &&
         fs::exists(kNode / "node_modules" / "playwright-core") &&
         fs::exists(kNode / "node_modules" / "cesium" / "Build" / "Cesium" / "Cesium.js");
}
#define REQUIRE_NODE_TOOLS()                                                                 \
  if (!node_tools_installed())                                                               \
  GTEST_SKIP() << "tests/node/node_modules is absent: run scripts/install-node-tools.sh to " \
                  "enable the node-based "                                                   \
                  "checks"

/// A synthetic city (50 buildings x 3 models) assembled by the binary, in a
/// directory of the calling test's own (ctest runs the tests in parallel).
std::string city_tileset(const std::string& name) {
  const std::string work = tmp_dir(name);
  write_work(work, synthetic_manifest(), synthetic_city(50, 3));
  const std::string out = work + "/tileset";
  const Proc r = run(q(kBin) + " assemble " + q(work) + " --out " + q(out));
  EXPECT_EQ(r.code, 0) << r.output;
  std::printf("%s", r.output.c_str());
  return out;
}

TEST(AssembleCli, WritesAValidTileset) {
  const std::string out = city_tileset("valid");
  const TilesetCheck chk = check_tileset(out);
  for (const auto& p : chk.problems) ADD_FAILURE() << p;
  EXPECT_GE(chk.content_tiles, 5);
  for (const auto& u : chk.uris) EXPECT_TRUE(fs::exists(fs::path(out) / u)) << u;
}

TEST(AssembleCli, EveryGlbPassesTheKhronosValidator) {
  REQUIRE_NODE_TOOLS();
  const std::string out = city_tileset("validator");
  // Also the quantized variant.
  const std::string work = tmp_dir("quantized");
  write_work(work, synthetic_manifest(), synthetic_city(12, 4));
  const Proc a =
      run(q(kBin) + " assemble -q " + q(work) + " --out " + q(work + "/tileset") + " --quantize");
  ASSERT_EQ(a.code, 0) << a.output;
  for (const std::string& dir : {out, work + "/tileset"}) {
    const Proc r = run("node " + q((kNode / "validate-glb.mjs").string()) + " " + q(dir) +
                       " --report " + q(dir + "/../validator-report.json"));
    std::printf("%s", r.output.c_str());
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find(" 0 errors"), std::string::npos) << r.output;
  }
}

TEST(AssembleCli, BadInputGivesClearErrors) {
  const std::string dir = tmp_dir("bad");
  Proc r = run(q(kBin) + " assemble " + q(dir) + " --out " + q(dir + "/out"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("manifest.json"), std::string::npos) << r.output;

  r = run(q(kBin) + " assemble " + q(dir));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--out"), std::string::npos) << r.output;

  write_work(dir, synthetic_manifest(), {});
  r = run(q(kBin) + " assemble " + q(dir) + " --out " + q(dir + "/out"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("no buildings"), std::string::npos) << r.output;

  auto city = synthetic_city(3, 2);
  city[1].write_report = false;
  write_work(dir, synthetic_manifest(), city);
  r = run(q(kBin) + " assemble " + q(dir) + " --out " + q(dir + "/out"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("'b-0001' has no LOD models"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir + "/out"));
  r = run(q(kBin) + " assemble " + q(dir) + " --out " + q(dir + "/out") + " --skip-missing");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: skipped"), std::string::npos) << r.output;
}

TEST(AssembleCli, AKilledRunNeverLeavesAHalfTileset) {
  const std::string work = tmp_dir("kill");
  write_work(work, synthetic_manifest(), synthetic_city(300, 4));
  const std::string out = work + "/tileset";
  const auto t0 = std::chrono::steady_clock::now();
  const Proc first = run(q(kBin) + " assemble -q " + q(work) + " --out " + q(out));
  ASSERT_EQ(first.code, 0) << first.output;
  const double full = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ measure  ] 300 buildings x 4 models: %.2f s (citylod assemble, wall clock)\n",
              full);
  for (double frac : {0.2, 0.5, 0.8, 0.95}) {
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      const int devnull = ::open("/dev/null", 1);
      dup2(devnull, 2);
      execl(kBin.c_str(), kBin.c_str(), "assemble", "-q", work.c_str(), "--out", out.c_str(),
            (char*)nullptr);
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(full * frac));
    ::kill(pid, SIGKILL);
    int st = 0;
    waitpid(pid, &st, 0);
    // Whatever the moment: a complete tileset (the old or the new one).
    const TilesetCheck chk = check_tileset(fs::exists(out) ? out : out + ".old", false);
    EXPECT_TRUE(chk.problems.empty()) << "killed at " << frac << ": " << chk.problems.front();
  }
  // The next run cleans up and succeeds.
  const Proc again = run(q(kBin) + " assemble -q " + q(work) + " --out " + q(out));
  EXPECT_EQ(again.code, 0) << again.output;
  EXPECT_TRUE(check_tileset(out).problems.empty());
}

TEST(AssembleCli, RealDelftBlockSplitLodAssemble) {
  // The whole chain on real data: AHN3 LiDAR of a Delft block (EPSG:28992).
  const fs::path las = fs::path(CITYLOD_SHARED_DATA) / "delft" / "ahn3_cropped_2.las";
  if (!fs::exists(las)) GTEST_SKIP() << "shared data not found: " << las;
  const std::string dir = tmp_dir("delft");
  const std::string work = dir + "/work", out = dir + "/tileset";
  Proc r = run(q(kBin) + " split -q " + q(las.string()) + " --crs EPSG:28992 --out " + q(work));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(q(kBin) + " lod -q " + q(work) + " -t 2");
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(q(kBin) + " assemble " + q(work) + " --out " + q(out));
  std::printf("%s", r.output.c_str());
  ASSERT_EQ(r.code, 0) << r.output;
  const TilesetCheck chk = check_tileset(out);
  for (const auto& p : chk.problems) ADD_FAILURE() << p;
  EXPECT_GE(chk.content_tiles, 2);
  // The root transform puts the ENU origin where PROJ puts the manifest's
  // origin (RD x, y; ellipsoidal height).
  const auto man = nlohmann::json::parse(read_bytes(work + "/manifest.json"));
  const auto ts = nlohmann::json::parse(read_bytes(out + "/tileset.json"));
  const Eigen::Matrix4d T = matrix_of(ts["root"]["transform"]);
  const auto& o = man["scene"]["origin_crs"];
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* rd = proj_normalize_for_visualization(
      ctx, proj_create_crs_to_crs(ctx, "EPSG:28992", "EPSG:4326", nullptr));
  PJ* ec = proj_normalize_for_visualization(
      ctx, proj_create_crs_to_crs(ctx, "EPSG:4979", "EPSG:4978", nullptr));
  const PJ_COORD ll =
      proj_trans(rd, PJ_FWD, proj_coord(o[0].get<double>(), o[1].get<double>(), 0, 0));
  const PJ_COORD x = proj_trans(
      ec, PJ_FWD, proj_coord(ll.lp.lam, ll.lp.phi, man["scene"]["origin_h"].get<double>(), 0));
  proj_destroy(rd);
  proj_destroy(ec);
  proj_context_destroy(ctx);
  const double off = (T.block<3, 1>(0, 3) - Eigen::Vector3d(x.xyz.x, x.xyz.y, x.xyz.z)).norm();
  std::printf("[ measure  ] Delft block: root origin off PROJ by %.4f m\n", off);
  EXPECT_LT(off, 0.05);
  if (node_tools_installed()) {
    const Proc v = run("node " + q((kNode / "validate-glb.mjs").string()) + " " + q(out));
    EXPECT_EQ(v.code, 0) << v.output;
    std::printf("%s", v.output.c_str());
  }
}

// ------------------------------------------------------------ serve

std::string http_get(int port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(std::uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return "";
  }
  const std::string req =
      "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  (void)!::write(fd, req.data(), req.size());
  std::string resp;
  char buf[65536];
  ssize_t n;
  while ((n = ::read(fd, buf, sizeof buf)) > 0) resp.append(buf, std::size_t(n));
  ::close(fd);
  return resp;
}

TEST(ServeCli, ServesTilesetAndViewerOnLoopback) {
  const std::string out = city_tileset("serve");
  int pipefd[2];
  ASSERT_EQ(pipe(pipefd), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    dup2(pipefd[1], 1);
    ::close(pipefd[0]);
    execl(kBin.c_str(), kBin.c_str(), "serve", "-q", out.c_str(), "--port", "0", (char*)nullptr);
    _exit(127);
  }
  ::close(pipefd[1]);
  std::string line;
  char c;
  while (line.find('\n') == std::string::npos && ::read(pipefd[0], &c, 1) == 1) line.push_back(c);
  const auto at = line.find("http://127.0.0.1:");
  ASSERT_NE(at, std::string::npos) << line;
  const int port = std::stoi(line.substr(at + 17));
  const std::string ts = http_get(port, "/tileset/tileset.json");
  EXPECT_NE(ts.find("200 OK"), std::string::npos);
  EXPECT_NE(ts.find("\"version\":\"1.1\""), std::string::npos);
  EXPECT_NE(http_get(port, "/").find("citylod viewer"), std::string::npos);
  EXPECT_NE(http_get(port, "/tileset/tiles/r.glb").find("model/gltf-binary"), std::string::npos);
  EXPECT_NE(http_get(port, "/tileset/nope.json").find("404"), std::string::npos);
  EXPECT_NE(http_get(port, "/tileset/../../../../etc/passwd").find("400"), std::string::npos);
  EXPECT_NE(http_get(port, "/tileset/%2e%2e/%2e%2e/etc/passwd").find("400"), std::string::npos);
  ::kill(pid, SIGTERM);
  int st = 0;
  waitpid(pid, &st, 0);
  ::close(pipefd[0]);
}

// ------------------------------------------------------------ viewer in a headless browser

TEST(ViewerCli, HeadlessChromiumLoadsAndRefinesTiles) {
  REQUIRE_NODE_TOOLS();
  if (!fs::exists("/usr/bin/chromium"))
    GTEST_SKIP() << "chromium is not installed (/usr/bin/chromium; apt-get install chromium): "
                    "browser test skipped";
  const std::string out = city_tileset("viewer_city");
  const std::string shots = (fs::path(CITYLOD_TEST_TMP) / "assemble_cli" / "viewer").string();
  fs::remove_all(shots);
  const Proc r = run("node " + q((kNode / "viewer-test.mjs").string()) + " --citylod " + q(kBin) +
                     " --tileset " + q(out) + " --out " + q(shots) + " --timeout-ms 300000");
  std::printf("%s", r.output.c_str());
  ASSERT_NE(r.code, 77) << r.output;
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(shots + "/2-zoomed.png"));
  std::printf("screenshots: %s\n", shots.c_str());
}

// The second viewer: NASA-AMMOS 3DTilesRendererJS (three.js) with its meshopt
// decoder and EXT_mesh_features / EXT_structural_metadata plugins.
TEST(ViewerCli, ThreeDTilesRendererLoadsAndRefinesTiles) {
  REQUIRE_NODE_TOOLS();
  if (!fs::exists("/usr/bin/chromium"))
    GTEST_SKIP() << "chromium is not installed (/usr/bin/chromium; apt-get install chromium): "
                    "browser test skipped";
  const std::string out = city_tileset("renderer_city");
  const std::string shots = (fs::path(CITYLOD_TEST_TMP) / "assemble_cli" / "renderer").string();
  fs::remove_all(shots);
  const Proc r = run("node " + q((kNode / "renderer-test.mjs").string()) + " --tileset " + q(out) +
                     " --out " + q(shots) + " --timeout-ms 300000");
  std::printf("%s", r.output.c_str());
  if (r.code == 77) GTEST_SKIP() << r.output;
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(shots + "/r2-zoomed.png"));
}

}  // namespace
}  // namespace citylod::test
